#include "lights.h"

#include <algorithm>
#include <cmath>

#include "warp.h"

namespace phongfit {
namespace {

Vec3d squareToUniformSphere(double u1, double u2) {
    const double z = 1 - 2 * u1;
    const double r = std::sqrt(std::max(0.0, 1 - z * z));
    return sphericalDirection(r, z, 2 * kPi * u2);
}

// Uniform point on the unit disk (concentric mapping keeps strata intact).
Vec2d squareToUniformDisk(double u1, double u2) {
    const double a = 2 * u1 - 1, b = 2 * u2 - 1;
    if (a == 0 && b == 0) return Vec2d::Zero();
    double r, phi;
    if (std::abs(a) > std::abs(b)) {
        r = a;
        phi = kPi / 4 * (b / a);
    } else {
        r = b;
        phi = kPi / 2 - kPi / 4 * (a / b);
    }
    return Vec2d(r * std::cos(phi), r * std::sin(phi));
}

// The cone of directions from p that meet the sphere.
struct SphereCone {
    Vec3d axis;             // unit, from p towards the centre
    double sin2Max;         // sin^2(theta_max) = r^2 / distance^2
    double oneMinusCosMax;  // 1 - cos(theta_max), as sin^2 / (1 + cos): its digits for any size
};

// The cone of directions from p that meet the sphere; none when p is not outside it.
std::optional<SphereCone> sphereCone(const ShapeDesc& sphere, const Vec3d& p) {
    const Vec3d toCentre = sphere.center - p;
    const double dc2 = toCentre.squaredNorm();
    const double r2 = sphere.radius * sphere.radius;
    if (!(dc2 > r2 * (1 + 1e-9))) return std::nullopt;
    const double sin2Max = r2 / dc2;
    return SphereCone{toCentre / std::sqrt(dc2), sin2Max, sin2Max / (1 + std::sqrt(1 - sin2Max))};
}

// A direction uniform in the cone from p around the sphere's centre, and where it meets the sphere
// first (pbrt-v4, Sphere::Sample with a reference point): every sample lands on the visible cap,
// with a constant solid-angle density, which area sampling of a large sphere is far from.
LightSample sampleSphereCone(const ShapeDesc& sphere, const Vec3d& p, const SphereCone& cone,
                             const Vec2d& u, const Color3& radiance) {
    // The angle theta from the axis, then alpha: the angle at the centre between the axis back
    // towards p and the point where that direction meets the sphere.
    const double oneMinusCos = cone.oneMinusCosMax * u.x();
    const double cosTheta = 1 - oneMinusCos;
    const double sin2Theta = oneMinusCos * (2 - oneMinusCos);
    const double cosAlpha = sin2Theta / std::sqrt(cone.sin2Max) +
                            cosTheta * std::sqrt(std::max(0.0, 1 - sin2Theta / cone.sin2Max));
    const double sinAlpha = std::sqrt(std::max(0.0, 1 - cosAlpha * cosAlpha));
    const Frame<double> frame(cone.axis);
    const Vec3d n = frame.toWorld(-sphericalDirection(sinAlpha, cosAlpha, 2 * kPi * u.y()));
    const Vec3d d = sphere.center + sphere.radius * n - p;
    const double dist = d.norm();
    return LightSample{d / dist, dist, radiance, 1 / (2 * kPi * cone.oneMinusCosMax), false};
}

Vec3d triangleVertex(const TriangleMesh& m, std::size_t tri, int k) {
    return m.positions[m.indices[3 * tri + k]].cast<double>();
}

}  // namespace

LightSet::LightSet(const Scene& scene, const EmbreeScene&) : scene_(scene) {
    shapeLight_.assign(scene.shapes.size(), -1);
    for (const EmitterDesc& e : scene.emitters) {
        Light l;
        l.value = e.value;
        switch (e.type) {
            case EmitterDesc::Type::Point:
                l.type = Light::Type::Point;
                l.position = e.position;
                break;
            case EmitterDesc::Type::Directional:
                l.type = Light::Type::Directional;
                l.direction = e.direction.normalized();
                break;
            case EmitterDesc::Type::Constant:
                l.type = Light::Type::Environment;
                environment_ = int(lights_.size());
                envRadiance_ = e.value;
                break;
            case EmitterDesc::Type::EnvMap:
                l.type = Light::Type::Environment;
                environment_ = int(lights_.size());
                envMap_ = std::make_unique<const EnvironmentMap>(e.map, e.value, e.toWorld);
                break;
        }
        lights_.push_back(std::move(l));
    }
    for (std::size_t s = 0; s < scene.shapes.size(); ++s) {
        const ShapeDesc& shape = scene.shapes[s];
        if (!shape.areaRadiance) continue;
        Light l;
        l.value = *shape.areaRadiance;
        l.shape = int(s);
        switch (shape.type) {
            case ShapeDesc::Type::Sphere:
                l.type = Light::Type::Sphere;
                l.area = 4 * kPi * shape.radius * shape.radius;
                break;
            case ShapeDesc::Type::Disk: {
                l.type = Light::Type::Disk;
                const Eigen::Matrix3d m = shape.toWorld.linear();
                l.area = kPi * m.col(0).cross(m.col(1)).norm();
                l.normal = (m.inverse().transpose() * Vec3d::UnitZ()).normalized();
                break;
            }
            case ShapeDesc::Type::Rectangle: {
                // Sampled as the parallelogram its two triangles make (corners 0, 1, 3): no search,
                // and a stratified point stays stratified.
                l.type = Light::Type::Parallelogram;
                const TriangleMesh& m = shape.mesh;
                const Vec3d v0 = m.positions[0].cast<double>();
                const Vec3d e1 = m.positions[1].cast<double>() - v0,
                            e2 = m.positions[3].cast<double>() - v0;
                const Vec3d front = (triangleVertex(m, 0, 1) - triangleVertex(m, 0, 0))
                                        .cross(triangleVertex(m, 0, 2) - triangleVertex(m, 0, 0));
                const Vec3d n = e1.cross(e2);
                l.area = n.norm();
                l.position = v0;
                l.edges = {e1, e2};
                l.normal = (n.dot(front) < 0 ? -n : n).normalized();
                break;
            }
            default: {
                l.type = Light::Type::Mesh;
                const TriangleMesh& m = shape.mesh;
                for (std::size_t t = 0; t < m.indices.size() / 3; ++t) {
                    const Vec3d v0 = triangleVertex(m, t, 0);
                    const Vec3d e1 = triangleVertex(m, t, 1) - v0,
                                e2 = triangleVertex(m, t, 2) - v0;
                    const Vec3d n = e1.cross(e2);
                    l.area += 0.5 * n.norm();
                    l.triangleCdf.push_back(l.area);
                    l.triangles.push_back({v0, e1, e2, n.normalized()});
                }
                break;
            }
        }
        if (!(l.area > 0)) continue;  // a degenerate emitter cannot emit
        shapeLight_[s] = int(lights_.size());
        lights_.push_back(std::move(l));
    }
}

std::optional<LightSample> LightSet::sample(int index, const Vec3d& p, const Vec2d& u) const {
    const Light& l = lights_[index];
    switch (l.type) {
        case Light::Type::Point: {
            const Vec3d d = l.position - p;
            const double dist2 = d.squaredNorm();
            if (!(dist2 > 0)) return std::nullopt;
            const double dist = std::sqrt(dist2);
            return LightSample{d / dist, dist, l.value / dist2, 1, true};
        }
        case Light::Type::Directional:
            return LightSample{-l.direction, std::numeric_limits<double>::infinity(), l.value, 1,
                               true};
        case Light::Type::Environment: {
            constexpr double kInfinity = std::numeric_limits<double>::infinity();
            if (!envMap_)
                return LightSample{squareToUniformSphere(u.x(), u.y()), kInfinity, l.value,
                                   0.25 * kInvPi, false};
            const auto s = envMap_->sample(u);
            if (!s) return std::nullopt;
            return LightSample{s->wi, kInfinity, s->radiance, s->pdf, false};
        }
        default:
            break;
    }
    const ShapeDesc& shape = scene_.shapes[l.shape];
    if (l.type == Light::Type::Sphere) {
        if (const std::optional<SphereCone> cone = sphereCone(shape, p))
            return sampleSphereCone(shape, p, *cone, u, l.value);
    }
    // Area light: a uniform point on the shape, then convert the area density to solid angle.
    Vec3d q, n;
    if (l.type == Light::Type::Sphere) {
        n = squareToUniformSphere(u.x(), u.y());
        q = shape.center + shape.radius * n;
    } else if (l.type == Light::Type::Disk) {
        const Vec2d d = squareToUniformDisk(u.x(), u.y());
        q = shape.toWorld * Vec3d(d.x(), d.y(), 0);
        n = l.normal;
    } else if (l.type == Light::Type::Parallelogram) {
        q = l.position + u.x() * l.edges[0] + u.y() * l.edges[1];
        n = l.normal;
    } else {
        // u.x picks the triangle and is then reused within it, so that a stratified (u.x, u.y)
        // stays stratified over the whole mesh (a rectangle's two triangles share the square).
        const double target = u.x() * l.area;
        const auto it = std::upper_bound(l.triangleCdf.begin(), l.triangleCdf.end(), target);
        const std::size_t t =
            std::min<std::size_t>(it - l.triangleCdf.begin(), l.triangleCdf.size() - 1);
        const double before = t > 0 ? l.triangleCdf[t - 1] : 0;
        const double width = l.triangleCdf[t] - before;
        const double ux = width > 0 ? std::clamp((target - before) / width, 0.0, 1.0) : 0.5;
        const auto& [v0, e1, e2, normal] = l.triangles[t];
        const double su = std::sqrt(ux);
        q = v0 + su * (1 - u.y()) * e1 + su * u.y() * e2;
        n = normal;
    }
    const Vec3d d = q - p;
    const double dist2 = d.squaredNorm();
    if (!(dist2 > 0)) return std::nullopt;
    const double dist = std::sqrt(dist2);
    const Vec3d wi = d / dist;
    const double cosLight = -n.dot(wi);
    if (!(cosLight > 0)) return std::nullopt;  // back side: emits nothing this way
    return LightSample{wi, dist, l.value, dist2 / (cosLight * l.area), false};
}

EnvironmentMap::Lookup LightSet::environmentLookup(const Vec3d& dir) const {
    return envMap_ ? envMap_->lookup(dir) : EnvironmentMap::Lookup{envRadiance_, 0.25 * kInvPi};
}

double LightSet::pdfArea(int index, const Vec3d& p, const Hit& hit) const {
    const Light& l = lights_[index];
    if (l.type == Light::Type::Sphere)
        if (const std::optional<SphereCone> cone = sphereCone(scene_.shapes[l.shape], p))
            return 1 / (2 * kPi * cone->oneMinusCosMax);
    const Vec3d d = hit.p - p;
    const double cosLight = std::abs(hit.ng.dot(d.normalized()));
    if (!(cosLight > 0)) return 0;
    return d.squaredNorm() / (cosLight * l.area);
}

Color3 LightSet::emitted(const Hit& hit, const Vec3d& dir) const {
    const int index = shapeLight_[hit.shape];
    if (index < 0 || !(hit.ng.dot(dir) < 0)) return Color3::Zero();
    return lights_[index].value;
}

std::optional<LightCone> LightSet::cone(int index, const Vec3d& p) const {
    const Light& l = lights_[index];
    LightCone c;
    if (l.type == Light::Type::Sphere) {
        const std::optional<SphereCone> sc = sphereCone(scene_.shapes[l.shape], p);
        if (!sc) return std::nullopt;
        c.normals[0] = sc->axis;
        c.offsets[0] = std::sqrt(1 - sc->sin2Max);
        c.planes = 1;
        return c;
    }
    if (l.type != Light::Type::Parallelogram || !(l.normal.dot(p - l.position) > 0))
        return std::nullopt;
    const std::array<Vec3d, 4> corners = {(l.position - p).normalized(),
                                          (l.position + l.edges[0] - p).normalized(),
                                          (l.position + l.edges[0] + l.edges[1] - p).normalized(),
                                          (l.position + l.edges[1] - p).normalized()};
    const Vec3d centre = (l.position + 0.5 * (l.edges[0] + l.edges[1]) - p).normalized();
    for (int k = 0; k < 4; ++k) {
        const Vec3d m = corners[k].cross(corners[(k + 1) % 4]);
        if (!(m.squaredNorm() > 0)) return std::nullopt;  // seen edge-on
        c.normals[k] = (m.dot(centre) < 0 ? -m : m).normalized();
    }
    c.planes = 4;
    return c;
}

double LightSet::distanceTo(int index, const Vec3d& p, const Vec3d& wi) const {
    const Light& l = lights_[index];
    if (l.type == Light::Type::Sphere) {
        const ShapeDesc& s = scene_.shapes[l.shape];
        const Vec3d toCentre = s.center - p;
        const double b = toCentre.dot(wi);
        const double miss2 = (toCentre - b * wi).squaredNorm();
        return b - std::sqrt(std::max(0.0, s.radius * s.radius - miss2));
    }
    return l.normal.dot(l.position - p) / l.normal.dot(wi);
}

}  // namespace phongfit
