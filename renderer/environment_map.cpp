#include "environment_map.h"

#include <algorithm>
#include <cmath>

namespace phongfit {
namespace {

double luminance(const Color<float>& c) { return 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]; }

// Per texel: luminance times sin(theta) at the row's centre.
std::vector<double> samplingWeights(const Image& map) {
    std::vector<double> weights(map.pixelCount());
    for (int y = 0; y < map.height; ++y) {
        const double sinTheta = std::sin(kPi * (y + 0.5) / map.height);
        for (int x = 0; x < map.width; ++x)
            weights[map.index(x, y)] = luminance(map.at(x, y)) * sinTheta;
    }
    return weights;
}

// A point of the tent on [-1, 1] (density 1 - |t|) from a uniform xi.
double sampleTent(double xi) {
    return xi < 0.5 ? std::sqrt(2 * xi) - 1 : 1 - std::sqrt(2 * (1 - xi));
}

// Bilinear interpolation of per-texel values at(x, y) over a footprint.
template <typename T, typename F, typename At>
T bilinear(const F& f, At at) {
    const T top = (1 - f.tx) * at(f.x0, f.y0) + f.tx * at(f.x1, f.y0);
    const T bottom = (1 - f.tx) * at(f.x0, f.y1) + f.tx * at(f.x1, f.y1);
    return (1 - f.ty) * top + f.ty * bottom;
}

}  // namespace

EnvironmentMap::EnvironmentMap(std::shared_ptr<const Image> map, const Color3& scale,
                               const Eigen::Matrix3d& toWorld)
    : map_(std::move(map)),
      scale_(scale),
      toWorld_(toWorld),
      distribution_(samplingWeights(*map_), map_->width, map_->height),
      density_(map_->pixelCount()) {
    for (int y = 0; y < map_->height; ++y)
        for (int x = 0; x < map_->width; ++x)
            density_[map_->index(x, y)] =
                distribution_.probability(x, y) * double(map_->width) * map_->height;
}

Vec2d EnvironmentMap::directionToUv(const Vec3d& local) {
    double u = std::atan2(local.x(), -local.z()) * (0.5 * kInvPi);
    if (u < 0) u += 1;
    if (u >= 1) u = 0;
    return Vec2d(u, std::acos(std::clamp(local.y(), -1.0, 1.0)) * kInvPi);
}

Vec3d EnvironmentMap::uvToDirection(const Vec2d& uv) {
    const double phi = 2 * kPi * uv.x(), theta = kPi * uv.y();
    const double sinTheta = std::sin(theta);
    return Vec3d(sinTheta * std::sin(phi), std::cos(theta), -sinTheta * std::cos(phi));
}

EnvironmentMap::Footprint EnvironmentMap::footprint(const Vec2d& uv) const {
    const int w = map_->width, h = map_->height;
    const double px = uv.x() * w - 0.5, py = uv.y() * h - 0.5;
    const double fx = std::floor(px), fy = std::floor(py);
    const int x0 = (int(fx) % w + w) % w;
    return {x0,      (x0 + 1) % w, std::clamp(int(fy), 0, h - 1), std::clamp(int(fy) + 1, 0, h - 1),
            px - fx, py - fy};
}

Color3 EnvironmentMap::radianceAt(const Footprint& f) const {
    return scale_ * bilinear<Color3>(
                        f, [&](int x, int y) -> Color3 { return map_->at(x, y).cast<double>(); });
}

double EnvironmentMap::pdfUvAt(const Footprint& f) const {
    return bilinear<double>(f, [&](int x, int y) { return density_[map_->index(x, y)]; });
}

EnvironmentMap::Lookup EnvironmentMap::lookup(const Vec3d& dir) const {
    const Vec3d local = toWorld_.transpose() * dir;
    const Footprint f = footprint(directionToUv(local));
    const double sinTheta = std::sqrt(std::max(0.0, 1 - local.y() * local.y()));
    const double pdf = sinTheta > 0 ? pdfUvAt(f) / (2 * kPi * kPi * sinTheta) : 0;
    return {radianceAt(f), pdf};
}

std::optional<EnvironmentMap::DirectionSample> EnvironmentMap::sample(const Vec2d& u) const {
    // A texel, then a point of its tent; tents reach past the poles fold back (so they sum to the
    // interpolant clamped in v) and wrap around in u.
    const Distribution2D::Sample texel = distribution_.sample(u);
    double su = (texel.x + 0.5 + sampleTent(texel.within.x())) / map_->width;
    double sv = (texel.y + 0.5 + sampleTent(texel.within.y())) / map_->height;
    su -= std::floor(su);
    if (sv < 0) sv = -sv;
    if (sv > 1) sv = 2 - sv;
    const Vec2d uv(su, sv);
    const Footprint f = footprint(uv);
    const double sinTheta = std::sin(kPi * sv);
    const double pdf = pdfUvAt(f);
    if (!(sinTheta > 0) || !(pdf > 0)) return std::nullopt;
    const Vec3d wi = (toWorld_ * uvToDirection(uv)).normalized();
    return DirectionSample{wi, radianceAt(f), pdf / (2 * kPi * kPi * sinTheta)};
}

}  // namespace phongfit
