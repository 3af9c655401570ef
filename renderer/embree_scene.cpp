#include "embree_scene.h"

#include <fmt/format.h>

#include <cmath>

#include "error.h"

namespace phongfit {
namespace {

void throwOnDeviceError(RTCDevice device, const char* what) {
    const RTCError code = rtcGetDeviceError(device);
    if (code != RTC_ERROR_NONE)
        throw Error(fmt::format("Embree failed while {} (error {})", what, int(code)));
}

// Smallest root of |o + t d - c|^2 = r^2 in (tNear, tFar), or NaN. Uses the form of Ray Tracing
// Gems ch. 7 (the discriminant from |f - (f.d) d|) to keep precision for distant or small spheres.
double intersectSphere(const Vec3d& o, const Vec3d& d, const Vec3d& c, double r, double tNear,
                       double tFar) {
    const Vec3d f = o - c;
    const double a = d.squaredNorm();
    const double b = -f.dot(d);
    const Vec3d l = f + (b / a) * d;
    const double disc = a * (r * r - l.squaredNorm());
    if (disc < 0) return std::nan("");
    const double q = b + std::copysign(std::sqrt(disc), b);
    double t0 = q / a, t1 = (f.squaredNorm() - r * r) / q;
    if (t0 > t1) std::swap(t0, t1);
    if (t0 > tNear && t0 < tFar) return t0;
    if (t1 > tNear && t1 < tFar) return t1;
    return std::nan("");
}

double intersectDisk(const EmbreeScene::AnalyticShape& s, const Vec3d& o, const Vec3d& d,
                     double tNear, double tFar) {
    const Vec3d ol = s.toLocal * o;
    const Vec3d dl = s.toLocal.linear() * d;
    if (dl.z() == 0) return std::nan("");
    const double t = -ol.z() / dl.z();
    if (!(t > tNear && t < tFar)) return std::nan("");
    const Vec3d pl = ol + t * dl;
    return pl.x() * pl.x() + pl.y() * pl.y() <= 1 ? t : std::nan("");
}

double intersectAnalytic(const EmbreeScene::AnalyticShape& s, const RTCRay& ray) {
    const Vec3d o(ray.org_x, ray.org_y, ray.org_z), d(ray.dir_x, ray.dir_y, ray.dir_z);
    return s.sphere ? intersectSphere(o, d, s.center, s.radius, ray.tnear, ray.tfar)
                    : intersectDisk(s, o, d, ray.tnear, ray.tfar);
}

void analyticBounds(const RTCBoundsFunctionArguments* args) {
    const auto& s = *static_cast<const EmbreeScene::AnalyticShape*>(args->geometryUserPtr);
    Vec3d lo, hi;
    if (s.sphere) {
        lo = s.center.array() - s.radius;
        hi = s.center.array() + s.radius;
    } else {
        lo = hi = s.toWorld * Vec3d(1, 0, 0);
        for (const auto& corner :
             {Vec3d(-1, -1, 0), Vec3d(1, -1, 0), Vec3d(-1, 1, 0), Vec3d(1, 1, 0)}) {
            const Vec3d p = s.toWorld * corner;
            lo = lo.cwiseMin(p);
            hi = hi.cwiseMax(p);
        }
    }
    // Round outwards so float bounds contain the double-precision shape.
    const double pad = 1e-6 * (1 + std::max(lo.cwiseAbs().maxCoeff(), hi.cwiseAbs().maxCoeff()));
    RTCBounds* b = args->bounds_o;
    b->lower_x = float(lo.x() - pad), b->lower_y = float(lo.y() - pad),
    b->lower_z = float(lo.z() - pad);
    b->upper_x = float(hi.x() + pad), b->upper_y = float(hi.y() + pad),
    b->upper_z = float(hi.z() + pad);
}

// Only rtcIntersect1/rtcOccluded1 are used, so N is always 1.
void analyticIntersect(const RTCIntersectFunctionNArguments* args) {
    if (!args->valid[0]) return;
    const auto& s = *static_cast<const EmbreeScene::AnalyticShape*>(args->geometryUserPtr);
    auto* rh = reinterpret_cast<RTCRayHit*>(args->rayhit);
    const double t = intersectAnalytic(s, rh->ray);
    if (std::isnan(t)) return;
    rh->ray.tfar = float(t);
    const Vec3d p = Vec3d(rh->ray.org_x, rh->ray.org_y, rh->ray.org_z) +
                    t * Vec3d(rh->ray.dir_x, rh->ray.dir_y, rh->ray.dir_z);
    const Vec3d n = s.sphere ? Vec3d((p - s.center) / s.radius) : s.normal;
    rh->hit.Ng_x = float(n.x()), rh->hit.Ng_y = float(n.y()), rh->hit.Ng_z = float(n.z());
    rh->hit.u = rh->hit.v = 0;
    rh->hit.primID = args->primID;
    rh->hit.geomID = args->geomID;
    rh->hit.instID[0] = args->context->instID[0];
}

void analyticOccluded(const RTCOccludedFunctionNArguments* args) {
    if (!args->valid[0]) return;
    const auto& s = *static_cast<const EmbreeScene::AnalyticShape*>(args->geometryUserPtr);
    auto* ray = reinterpret_cast<RTCRay*>(args->ray);
    if (!std::isnan(intersectAnalytic(s, *ray)))
        ray->tfar = -std::numeric_limits<float>::infinity();
}

}  // namespace

Vec3d offsetRayOrigin(const Vec3d& p, const Vec3d& ng, const Vec3d& dir) {
    const double eps = 1e-5 * std::max(1.0, p.cwiseAbs().maxCoeff());
    return p + (ng.dot(dir) > 0 ? eps : -eps) * ng;
}

EmbreeScene::EmbreeScene(const Scene& scene) : desc_(scene) {
    device_ = rtcNewDevice(nullptr);
    if (!device_) throw Error("could not create the Embree device");
    scene_ = rtcNewScene(device_);
    // Medium, Embree's default: the high quality's spatial splits assert on some ordinary scenes
    // (Debian's Embree 3 aborted on a Cornell box whose wall was turned by 91 degrees).
    rtcSetSceneBuildQuality(scene_, RTC_BUILD_QUALITY_MEDIUM);
    analytic_.resize(scene.shapes.size());  // fixed from here on: geometries keep pointers into it
    boundsMin_ = Vec3d::Constant(std::numeric_limits<double>::infinity());
    boundsMax_ = -boundsMin_;
    for (std::size_t i = 0; i < scene.shapes.size(); ++i) {
        const ShapeDesc& shape = scene.shapes[i];
        RTCGeometry geom;
        if (shape.type == ShapeDesc::Type::Sphere || shape.type == ShapeDesc::Type::Disk) {
            AnalyticShape& a = analytic_[i];
            a.sphere = shape.type == ShapeDesc::Type::Sphere;
            a.center = shape.center;
            a.radius = shape.radius;
            a.toWorld = shape.toWorld;
            a.toLocal = shape.toWorld.inverse();
            a.normal = (shape.toWorld.linear().inverse().transpose() * Vec3d::UnitZ()).normalized();
            geom = rtcNewGeometry(device_, RTC_GEOMETRY_TYPE_USER);
            rtcSetGeometryUserPrimitiveCount(geom, 1);
            rtcSetGeometryUserData(geom, &a);
            rtcSetGeometryBoundsFunction(geom, analyticBounds, nullptr);
            rtcSetGeometryIntersectFunction(geom, analyticIntersect);
            rtcSetGeometryOccludedFunction(geom, analyticOccluded);
            RTCBoundsFunctionArguments args{&a, 0, 0, nullptr};
            RTCBounds b;
            args.bounds_o = &b;
            analyticBounds(&args);
            boundsMin_ = boundsMin_.cwiseMin(Vec3d(b.lower_x, b.lower_y, b.lower_z));
            boundsMax_ = boundsMax_.cwiseMax(Vec3d(b.upper_x, b.upper_y, b.upper_z));
        } else {
            const TriangleMesh& mesh = shape.mesh;
            geom = rtcNewGeometry(device_, RTC_GEOMETRY_TYPE_TRIANGLE);
            auto* v = static_cast<float*>(
                rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                        3 * sizeof(float), mesh.positions.size()));
            for (std::size_t k = 0; k < mesh.positions.size(); ++k) {
                for (int c = 0; c < 3; ++c) v[3 * k + c] = mesh.positions[k][c];
                boundsMin_ = boundsMin_.cwiseMin(mesh.positions[k].cast<double>());
                boundsMax_ = boundsMax_.cwiseMax(mesh.positions[k].cast<double>());
            }
            auto* idx = static_cast<unsigned*>(
                rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                        3 * sizeof(unsigned), mesh.indices.size() / 3));
            std::copy(mesh.indices.begin(), mesh.indices.end(), idx);
        }
        rtcCommitGeometry(geom);
        const unsigned id = rtcAttachGeometry(scene_, geom);
        rtcReleaseGeometry(geom);
        if (geometryToShape_.size() <= id) geometryToShape_.resize(id + 1, -1);
        geometryToShape_[id] = int(i);
    }
    rtcCommitScene(scene_);
    throwOnDeviceError(device_, "building the scene");
    if (scene.shapes.empty()) boundsMin_ = boundsMax_ = Vec3d::Zero();
}

EmbreeScene::~EmbreeScene() {
    rtcReleaseScene(scene_);
    rtcReleaseDevice(device_);
}

namespace {
RTCRay toRtcRay(const Ray& ray) {
    RTCRay r;
    r.org_x = float(ray.origin.x()), r.org_y = float(ray.origin.y()),
    r.org_z = float(ray.origin.z());
    r.dir_x = float(ray.dir.x()), r.dir_y = float(ray.dir.y()), r.dir_z = float(ray.dir.z());
    r.tnear = 0;
    r.tfar = std::isfinite(ray.tMax) ? float(ray.tMax) : std::numeric_limits<float>::infinity();
    r.time = 0;
    r.mask = 0xFFFFFFFF;
    r.id = 0;
    r.flags = 0;
    return r;
}
}  // namespace

std::optional<Hit> EmbreeScene::intersect(const Ray& ray) const {
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    RTCRayHit rh;
    rh.ray = toRtcRay(ray);
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(scene_, &ctx, &rh);
    if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return std::nullopt;

    Hit hit;
    hit.shape = geometryToShape_[rh.hit.geomID];
    hit.t = rh.ray.tfar;
    hit.p = ray.origin + hit.t * ray.dir;
    const ShapeDesc& shape = desc_.shapes[hit.shape];
    if (shape.type == ShapeDesc::Type::Sphere) {
        const AnalyticShape& a = analytic_[hit.shape];
        hit.ng = ((hit.p - a.center) / a.radius).normalized();
        hit.p = a.center + a.radius * hit.ng;  // exactly on the sphere
        hit.ns = hit.ng;
        return hit;
    }
    if (shape.type == ShapeDesc::Type::Disk) {
        hit.ng = hit.ns = analytic_[hit.shape].normal;
        return hit;
    }
    // Embree's Ng is (v1 - v0) x (v2 - v0): the front side by counter-clockwise winding, as OBJ
    // and Mitsuba.
    hit.ng = Vec3d(rh.hit.Ng_x, rh.hit.Ng_y, rh.hit.Ng_z).normalized();
    const TriangleMesh& mesh = shape.mesh;
    if (mesh.normals.empty()) {
        hit.ns = hit.ng;
    } else {
        const std::uint32_t* tri = &mesh.indices[3 * rh.hit.primID];
        const double u = rh.hit.u, v = rh.hit.v;
        const Vec3d n = (1 - u - v) * mesh.normals[tri[0]].cast<double>() +
                        u * mesh.normals[tri[1]].cast<double>() +
                        v * mesh.normals[tri[2]].cast<double>();
        hit.ns = n.normalized();
        // Interpolated normals define the front: keep ng on their side.
        if (hit.ns.dot(hit.ng) < 0) hit.ng = -hit.ng;
    }
    return hit;
}

bool EmbreeScene::occluded(const Ray& ray) const {
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    RTCRay r = toRtcRay(ray);
    rtcOccluded1(scene_, &ctx, &r);
    return r.tfar < 0;
}

}  // namespace phongfit
