// The scene's geometry in Embree 3: triangles for rectangles, cubes and meshes; exact analytic
// spheres and disks as user geometry intersected in double precision, with exact normals.
#pragma once

#include <embree3/rtcore.h>

#include <optional>
#include <vector>

#include "scene.h"

namespace phongfit {

struct Ray {
    Vec3d origin;
    Vec3d dir;  // unit length
    double tMax = std::numeric_limits<double>::infinity();
};

struct Hit {
    double t;
    Vec3d p;
    Vec3d ng;  // unit geometric normal, the side the shape defines as front
    Vec3d ns;  // unit shading normal (interpolated vertex normals, or ng)
    int shape;
};

// Origin for a ray leaving the surface at p towards the side of `dir`, offset along the geometric
// normal so the surface it leaves is not hit again.
Vec3d offsetRayOrigin(const Vec3d& p, const Vec3d& ng, const Vec3d& dir);

class EmbreeScene {
public:
    explicit EmbreeScene(const Scene& scene);
    ~EmbreeScene();
    EmbreeScene(const EmbreeScene&) = delete;
    EmbreeScene& operator=(const EmbreeScene&) = delete;

    std::optional<Hit> intersect(const Ray& ray) const;
    bool occluded(const Ray& ray) const;

    // The committed Embree scene, for measuring raw traversal throughput.
    RTCScene rtcScene() const { return scene_; }

    // Scene bounds (for the environment light's reach and ray epsilons).
    Vec3d boundsMin() const { return boundsMin_; }
    Vec3d boundsMax() const { return boundsMax_; }

    // An exact sphere or disk, intersected in double precision by Embree user-geometry callbacks.
    struct AnalyticShape {
        bool sphere = true;
        Vec3d center = Vec3d::Zero();  // sphere
        double radius = 1;
        Eigen::Affine3d toWorld =
            Eigen::Affine3d::Identity();  // disk: unit disk at z = 0, normal +z
        Eigen::Affine3d toLocal = Eigen::Affine3d::Identity();
        Vec3d normal = Vec3d::UnitZ();  // disk: world-space unit normal
    };

private:
    RTCDevice device_ = nullptr;
    RTCScene scene_ = nullptr;
    const Scene& desc_;
    std::vector<int> geometryToShape_;
    std::vector<AnalyticShape> analytic_;  // indexed like geometryToShape_ (unused for triangles)
    Vec3d boundsMin_, boundsMax_;
};

}  // namespace phongfit
