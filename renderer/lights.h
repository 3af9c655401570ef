// The scene's emitters, sampled for next-event estimation: point and directional (delta) lights, an
// environment (constant, or an envmap sampled by luminance), and area lights on meshes and disks
// (uniform by area) and spheres (uniform in the cone of directions that meets them, seen from
// outside); they emit from the front side of their shape.
#pragma once

#include <array>
#include <memory>
#include <optional>
#include <vector>

#include "embree_scene.h"
#include "environment_map.h"
#include "light_rings.h"

namespace phongfit {

struct LightSample {
    Vec3d wi;         // unit, from the shading point towards the light
    double distance;  // to the light point; infinity for directional and environment
    Color3 radiance;  // arriving radiance (delta lights: irradiance-equivalent, I / d^2 or E)
    double pdf;       // solid-angle density; 1 for delta lights
    bool delta;
};

class LightSet {
public:
    LightSet(const Scene& scene, const EmbreeScene& geometry);

    int size() const { return int(lights_.size()); }

    // A sample of light `index` as seen from p, from a point of the unit square (each light warps
    // it as a whole, so that stratified points give stratified light samples).
    std::optional<LightSample> sample(int index, const Vec3d& p, const Vec2d& u) const;

    // Light index emitting from `shape` (area light), or -1.
    int lightOfShape(int shape) const { return shapeLight_[shape]; }
    // Index of the environment (constant or envmap), or -1.
    int environment() const { return environment_; }
    // The environment's radiance arriving from the unit direction `dir`, and the solid-angle
    // density with which its sampling picks `dir` (uniform on the sphere for a constant one).
    EnvironmentMap::Lookup environmentLookup(const Vec3d& dir) const;

    // Solid-angle density with which light `index` samples the direction from p to `hit` on it.
    double pdfArea(int index, const Vec3d& p, const Hit& hit) const;

    // Emitted radiance leaving `hit` towards -dir (front side only).
    Color3 emitted(const Hit& hit, const Vec3d& dir) const;

    // The directions from p that meet area light `index`: a sphere seen from outside, or a
    // parallelogram seen from its front. None for other lights, which are sampled instead.
    std::optional<LightCone> cone(int index, const Vec3d& p) const;
    // Whether light `index` has a cone at all (a sphere or a parallelogram): what rings integrate.
    bool hasCone(int index) const {
        return lights_[index].type == Light::Type::Sphere ||
               lights_[index].type == Light::Type::Parallelogram;
    }
    // Distance from p along the unit wi (a direction in the light's cone) to area light `index`.
    double distanceTo(int index, const Vec3d& p, const Vec3d& wi) const;
    // The radiance an area light emits (uniform over its front).
    const Color3& radiance(int index) const { return lights_[index].value; }

private:
    struct Light {
        enum class Type { Point, Directional, Environment, Mesh, Parallelogram, Sphere, Disk };
        Type type = Type::Point;
        Color3 value = Color3::Zero();  // intensity, irradiance or radiance
        Vec3d position = Vec3d::Zero(), direction = Vec3d::UnitZ();
        int shape = -1;
        // Parallelogram (a rectangle): `position` is a corner and `edges` go from it. Parallelogram
        // and disk: the unit front normal.
        std::array<Vec3d, 2> edges{Vec3d::Zero(), Vec3d::Zero()};
        Vec3d normal = Vec3d::UnitZ();
        // Mesh: per triangle, cumulative area, a vertex, two edges and the unit front normal.
        std::vector<double> triangleCdf;
        std::vector<std::array<Vec3d, 4>> triangles;
        double area = 0;
    };

    const Scene& scene_;
    std::vector<Light> lights_;
    std::vector<int> shapeLight_;
    int environment_ = -1;
    Color3 envRadiance_ = Color3::Zero();
    std::unique_ptr<const EnvironmentMap> envMap_;  // null for a constant environment
};

}  // namespace phongfit
