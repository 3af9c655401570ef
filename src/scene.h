// The scene description: what a Mitsuba 0.6 XML file (the supported subset, DESIGN.md) says, in
// world space, validated, with the source location of everything a later error may need to name.
// Nothing here knows about Embree or Ceres.
#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "math.h"
#include "phong_brdf.h"
#include "pixel_sampler.h"

namespace phongfit {

struct Image;

struct SourceLocation {
    std::string file;
    int line = 0;
    std::string str() const { return file + ":" + std::to_string(line); }
};

// Every supported BSDF is a Modified Phong material: `diffuse` is kd = reflectance, ks = 0.
struct BsdfDesc {
    std::string id;    // empty for an anonymous nested bsdf
    std::string type;  // "diffuse" or "phong", as written in the file
    PhongMaterial params;
    SourceLocation loc;
};

// Triangles in world space (after toWorld). Normals per vertex, or empty for flat shading.
// Triangles wind counter-clockwise seen from the front: cross(p1 - p0, p2 - p0) points outward
// (cube, obj) or along the emitting side (rectangle: toWorld's image of +z), mirrors included.
struct TriangleMesh {
    std::vector<Vec3f> positions;
    std::vector<Vec3f> normals;
    std::vector<std::uint32_t> indices;  // 3 per triangle
};

struct ShapeDesc {
    enum class Type { Sphere, Rectangle, Cube, Disk, Obj };
    Type type = Type::Sphere;
    // Sphere: world-space center and radius (toWorld applied; a non-uniform scale is an error).
    Vec3d center = Vec3d::Zero();
    double radius = 1;
    // Disk: toWorld of the unit disk in the z = 0 plane, normal +z.
    Eigen::Affine3d toWorld = Eigen::Affine3d::Identity();
    // Rectangle, cube and obj: world-space triangles (exact: these shapes are flat-faced).
    TriangleMesh mesh;
    int bsdf = -1;                       // index into Scene::bsdfs
    std::optional<Color3> areaRadiance;  // nested area emitter: emits from the front side
    SourceLocation loc;
};

struct EmitterDesc {
    enum class Type { Point, Directional, Constant, EnvMap };
    Type type = Type::Point;
    Vec3d position = Vec3d::Zero();    // point
    Vec3d direction = Vec3d(0, 0, 1);  // directional: unit direction of travel
    // Point: intensity (W/sr); directional: irradiance on a surface facing the light;
    // constant: radiance; envmap: the scale on the map's radiance.
    Color3 value = Color3::Ones();
    // Envmap: the lat-long map (finite, nonnegative, twice as wide as high) and the rotation from
    // the map's frame (+y up) to the world.
    std::shared_ptr<const Image> map;
    Eigen::Matrix3d toWorld = Eigen::Matrix3d::Identity();
    SourceLocation loc;
};

struct SensorDesc {
    double fovDegrees = 45;
    enum class FovAxis { X, Y, Smaller, Larger };
    FovAxis fovAxis = FovAxis::X;
    // Camera to world. Camera space as in Mitsuba: looks along +z, +y up, +x to the viewer's left
    // (so the image's +x is the viewer's right).
    Eigen::Affine3d toWorld = Eigen::Affine3d::Identity();
    int width = 768, height = 576;
    int sampleCount = 4;
    PixelSamplerType pixelSampler = PixelSamplerType::Sobol;  // <sampler type>: Sobol unless named
    enum class Filter { Box, Gaussian, Tent };
    Filter filter = Filter::Box;
    // The Gaussian's stddev or the tent's radius (1 - |x| / radius along each axis), pixels; the
    // box takes none. A parsed film has its filter's default (kPixelFilters).
    double filterWidth = 0.5;
    // The film names its <rfilter>. Where it does not, Mitsuba 0.6 filters with a Gaussian and
    // phongfit with a box: an image from Mitsuba then misstates its scene.
    bool filterNamed = false;
};

// The <rfilter> types as the scene format and `render`'s sidecar name them, with the width each
// takes and its default: the Gaussian's is Mitsuba 0.6's default filter; the tent of radius 1 is
// Tungsten's default and Mitsuba's tent.
struct PixelFilterName {
    SensorDesc::Filter filter;
    const char* type;
    const char* width;  // nullptr for the box
    double defaultWidth;
};
inline constexpr PixelFilterName kPixelFilters[] = {
    {SensorDesc::Filter::Box, "box", nullptr, 0},
    {SensorDesc::Filter::Gaussian, "gaussian", "stddev", 0.5},
    {SensorDesc::Filter::Tent, "tent", "radius", 1}};

inline const PixelFilterName& pixelFilterName(SensorDesc::Filter filter) {
    for (const PixelFilterName& f : kPixelFilters)
        if (f.filter == filter) return f;
    return kPixelFilters[0];
}

// A pixel filter's stddev or radius: its samples land this many pixels from the pixel at most
// (a Gaussian's within a few stddevs), which keeps film positions and camera rays finite.
inline constexpr double kMaxFilterWidth = 64;
inline bool filterWidthAllowed(double width) { return width > 0 && width <= kMaxFilterWidth; }

// A pixel filter and its width (SensorDesc::filterWidth; the box takes none): a render's in place
// of the film's (RenderOptions::pixelFilter), the one an image's edges show (EdgeCheck).
struct PixelFilter {
    SensorDesc::Filter filter = SensorDesc::Filter::Box;
    double width = 0;
    bool operator==(const PixelFilter&) const = default;
};
inline PixelFilter pixelFilterOf(const SensorDesc& film) {
    return {film.filter, pixelFilterName(film.filter).width != nullptr ? film.filterWidth : 0};
}
inline void setPixelFilter(SensorDesc& film, const PixelFilter& f) {
    film.filter = f.filter;
    film.filterWidth = f.width;
}

struct IntegratorDesc {
    std::string type = "path";  // "path" or "direct"
    int maxDepth = -1;          // Mitsuba's count: 1 = emitters seen directly; -1 = unbounded
    int rrDepth = 5;
};

struct Scene {
    std::string file;  // the file it came from (absolute or as given)
    IntegratorDesc integrator;
    SensorDesc sensor;
    std::vector<BsdfDesc> bsdfs;
    std::vector<ShapeDesc> shapes;
    std::vector<EmitterDesc> emitters;

    // Index of the bsdf with this id, or -1.
    int findBsdf(const std::string& id) const {
        for (std::size_t i = 0; i < bsdfs.size(); ++i)
            if (bsdfs[i].id == id) return int(i);
        return -1;
    }
};

}  // namespace phongfit
