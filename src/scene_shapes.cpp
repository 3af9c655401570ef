#include "scene_shapes.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace phongfit::scene_xml {

TriangleMesh unitRectangle() {
    TriangleMesh m;
    m.positions = {Vec3f(-1, -1, 0), Vec3f(1, -1, 0), Vec3f(1, 1, 0), Vec3f(-1, 1, 0)};
    m.indices = {0, 1, 2, 0, 2, 3};
    return m;
}

TriangleMesh unitCube() {
    TriangleMesh m;
    for (int axis = 0; axis < 3; ++axis) {
        for (const float sign : {-1.0f, 1.0f}) {
            const Vec3f n = sign * Vec3f::Unit(axis);
            // cross(u, v) = n, so the face winds counter-clockwise seen from outside.
            Vec3f u = Vec3f::Unit((axis + 1) % 3), v = Vec3f::Unit((axis + 2) % 3);
            if (sign < 0) std::swap(u, v);
            const auto base = std::uint32_t(m.positions.size());
            for (const Vec3f& p :
                 {Vec3f(n - u - v), Vec3f(n + u - v), Vec3f(n + u + v), Vec3f(n - u + v)})
                m.positions.push_back(p);
            for (const std::uint32_t i : {0u, 1u, 2u, 0u, 2u, 3u}) m.indices.push_back(base + i);
        }
    }
    return m;
}

TriangleMesh transformed(TriangleMesh mesh, const Eigen::Affine3d& toWorld) {
    const Eigen::Matrix3d normalMatrix = toWorld.linear().inverse().transpose();
    for (Vec3f& p : mesh.positions) p = (toWorld * p.cast<double>()).cast<float>();
    for (Vec3f& n : mesh.normals) n = (normalMatrix * n.cast<double>()).normalized().cast<float>();
    if (toWorld.linear().determinant() < 0)
        for (std::size_t t = 0; t < mesh.indices.size(); t += 3)
            std::swap(mesh.indices[t + 1], mesh.indices[t + 2]);
    return mesh;
}

double worldExtent(const ShapeDesc& shape) {
    constexpr double kInfinity = std::numeric_limits<double>::infinity();
    const auto extent = [](const auto& v) {
        return v.allFinite() ? double(v.cwiseAbs().maxCoeff()) : kInfinity;
    };
    double e = 0;
    switch (shape.type) {
        case ShapeDesc::Type::Sphere:
            e = extent(shape.center) + (std::isfinite(shape.radius) ? shape.radius : kInfinity);
            break;
        case ShapeDesc::Type::Disk:
            e = extent(shape.toWorld.translation()) + extent(shape.toWorld.linear());
            break;
        default:
            for (const Vec3f& v : shape.mesh.positions) e = std::max(e, extent(v));
            for (const Vec3f& v : shape.mesh.normals)
                if (!v.allFinite()) e = kInfinity;
            break;
    }
    return e;
}

}  // namespace phongfit::scene_xml
