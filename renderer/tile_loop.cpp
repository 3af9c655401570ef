#include "tile_loop.h"

#include <cmath>
#include <limits>
#include <tuple>

namespace phongfit {
namespace {

constexpr int kTileSize = 16;
constexpr std::size_t kNonFiniteReported = 10;

// Follows a replayed sample's sum vertex by vertex.
struct DiagnosingSink {
    NonFiniteSample& where;  // gets depth and bsdf
    Color3 sum = Color3::Zero();
    int depth = 0, bsdf = -1;  // of the vertex being traced
    bool found = false;
    void vertex(int d, int b) { depth = d, bsdf = b; }
    void add(const Color3& c, std::span<const PathVertex>) {
        sum += c;
        if (found || representable(sum)) return;
        found = true;
        where.depth = depth;
        where.bsdf = bsdf;
    }
};

bool pathOrder(const NonFiniteSample& a, const NonFiniteSample& b) {
    return std::tie(a.y, a.x, a.sample) < std::tie(b.y, b.x, b.sample);
}

}  // namespace

std::vector<Tile> makeTiles(int width, int height) {
    std::vector<Tile> tiles;
    for (int y = 0; y < height; y += kTileSize)
        for (int x = 0; x < width; x += kTileSize)
            tiles.push_back(
                {x, y, std::min(x + kTileSize, width), std::min(y + kTileSize, height)});
    return tiles;
}

// Box: uniform over the pixel. Gaussian and tent: the filter is importance-sampled (Box-Muller
// around the pixel centre; the tent's inverse CDF along each axis), so every sample still belongs
// to one pixel with weight 1 and no splatting is needed (as pbrt-v4 and Tungsten).
Vec2d filmPosition(const SensorDesc& sensor, int x, int y, double u0, double u1) {
    switch (sensor.filter) {
        case SensorDesc::Filter::Box:
            return Vec2d(x + u0, y + u1);
        case SensorDesc::Filter::Gaussian: {
            const double r = sensor.filterWidth * std::sqrt(-2 * std::log1p(-u0));
            return Vec2d(x + 0.5 + r * std::cos(2 * kPi * u1),
                         y + 0.5 + r * std::sin(2 * kPi * u1));
        }
        case SensorDesc::Filter::Tent:
            break;
    }
    const double r = sensor.filterWidth;
    const auto offset = [r](double u) {
        return u < 0.5 ? r * (std::sqrt(2 * u) - 1) : r * (1 - std::sqrt(2 - 2 * u));
    };
    return Vec2d(x + 0.5 + offset(u0), y + 0.5 + offset(u1));
}

bool representable(const Color3& c) {
    return (c.abs() <= double(std::numeric_limits<float>::max())).all();
}

NonFiniteSample diagnoseNonFinite(const PathIntegrator& integrator, const Ray& ray,
                                  const PixelSampler& rng, int x, int y, int sample) {
    NonFiniteSample where{x, y, sample};
    DiagnosingSink diagnosis{where};
    std::uint64_t rays = 0;  // a replay, not counted
    integrator.trace(ray, rng, sample, diagnosis, rays);
    return where;
}

void keepFirstNonFinite(std::vector<NonFiniteSample>& list, const NonFiniteSample& s) {
    list.insert(std::upper_bound(list.begin(), list.end(), s, pathOrder), s);
    if (list.size() > kNonFiniteReported) list.pop_back();
}

}  // namespace phongfit
