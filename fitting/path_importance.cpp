#include "path_importance.h"

#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <cmath>
#include <numeric>

#include "instruments.h"
#include "material_params.h"
#include "replay_jacobian.h"

namespace phongfit {

// In a named namespace: pathImportance's closures (external linkage) hold these, and in a unity
// build (scripts/build.sh) gcc warns of a closure that holds an anonymous namespace's type.
namespace importance_detail {

// Floats, 8 bytes: one per pixel of a view while the fitter's paths are held.
struct PixelSpread {
    float sensitivity = 0;    // sqrt(sum_k (J_pk std_k^2 / scale_k)^2): a float's range holds it
    float pathVariance = -1;  // s_p^2, from this pixel alone; negative where no path is seen
    bool seen() const { return pathVariance >= 0; }
};

template <int P>
PixelSpread spread(const PathSet& a, const PathSet& b, std::uint32_t pixel,
                   std::span<const std::uint32_t> slots, const std::vector<double>& natural,
                   const std::vector<double>& weights, std::vector<PhongParams<PackedJet>>& theta) {
    using L = BlockLayout<P>;
    PixelSpread s;
    if (a.pixelStart[pixel + 1] == a.pixelStart[pixel] &&
        b.pixelStart[pixel + 1] == b.pixelStart[pixel])
        return s;
    double sensitivity = 0;
    Eigen::Matrix<double, 3, P> ja, jb;
    Color3 ia = Color3::Zero(), ib = Color3::Zero();
    for (std::uint32_t seeded : slots) {
        ia = replayNaturalJacobian<P>(a, pixel, slots, natural.data(), seeded, theta, ja);
        ib = replayNaturalJacobian<P>(b, pixel, slots, natural.data(), seeded, theta, jb);
        const double* w = weights.data() + std::size_t(seeded) * P;
        for (int c = 0; c < 3; ++c)
            for (int k : {L::diffuse(L::group(c)), L::specular(L::group(c)), int(L::kLogN)}) {
                const double term = 0.5 * (ja(c, k) + jb(c, k)) * w[k];
                sensitivity += term * term;
            }
    }
    const double paths = a.pathsAt(pixel);
    s.sensitivity = float(std::sqrt(sensitivity));
    s.pathVariance = float(0.5 * paths * (ia - ib).matrix().squaredNorm());
    return s;
}

}  // namespace importance_detail

template <int P>
std::vector<std::vector<float>> pathImportance(const std::vector<Observation>& observations,
                                               const std::vector<PathSet>& first,
                                               const std::vector<PathSet>& second,
                                               const std::vector<double>& natural,
                                               const std::vector<double>& naturalStd, int threads) {
    using L = BlockLayout<P>;
    using importance_detail::PixelSpread;
    const std::uint32_t slots = std::uint32_t(first.at(0).slots);
    std::vector<std::uint32_t> allSlots(slots);
    std::iota(allSlots.begin(), allSlots.end(), 0u);
    // std_k^2 / scale_k per natural coordinate.
    std::vector<double> weights(std::size_t(slots) * P, 0.0);
    for (std::size_t i = 0; i < weights.size(); ++i) {
        const bool logN = int(i % P) == L::kLogN;
        const double scale = logN ? 1.0 : std::max(std::abs(natural[i]), 0.01);
        weights[i] = naturalStd[i] * naturalStd[i] / scale;
    }

    tbb::task_arena arena(threads);
    std::vector<std::vector<float>> importance(observations.size());
    for (std::size_t v = 0; v < observations.size(); ++v) {
        const Observation& o = observations[v];
        const int width = o.width, height = o.height;
        std::vector<PixelSpread> spreads(std::size_t(width) * height);
        arena.execute([&] {
            tbb::parallel_for(0, height, [&](int y) {
                std::vector<PhongParams<PackedJet>> theta(slots);
                for (int x = 0; x < width; ++x) {
                    const std::uint32_t p = std::uint32_t(y) * std::uint32_t(width) + x;
                    if (!o.valid.empty() && !o.valid[p]) continue;
                    PixelSpread& s = spreads[p];
                    s = importance_detail::spread<P>(first[v], second[v], p, allSlots, natural,
                                                     weights, theta);
                    if (!o.weight.empty())
                        s.sensitivity = float(s.sensitivity * std::abs(double(o.weight[p])));
                }
            });
        });
        importance[v].assign(spreads.size(), 0.0f);
        arena.execute([&] {
            tbb::parallel_for(0, height, [&](int y) {
                for (int x = 0; x < width; ++x) {
                    const std::size_t p = std::size_t(y) * width + x;
                    if (!spreads[p].seen() || !(spreads[p].sensitivity > 0)) continue;
                    double sum = 0;
                    int count = 0;
                    for (int dy = -kInstrumentRadius; dy <= kInstrumentRadius; ++dy)
                        for (int dx = -kInstrumentRadius; dx <= kInstrumentRadius; ++dx) {
                            const int nx = x + dx, ny = y + dy;
                            if (nx < 0 || ny < 0 || nx >= width || ny >= height) continue;
                            const PixelSpread& n = spreads[std::size_t(ny) * width + nx];
                            if (!n.seen()) continue;
                            sum += n.pathVariance;
                            ++count;
                        }
                    importance[v][p] =
                        float(std::sqrt(sum / count) * double(spreads[p].sensitivity));
                }
            });
        });
    }
    return importance;
}

std::vector<int> allocatePaths(const std::vector<float>& importance, double extra, int most) {
    std::vector<int> paths(importance.size(), 0);
    const double total = std::accumulate(importance.begin(), importance.end(), 0.0);
    if (!(total > 0) || !(extra > 0)) return paths;
    // Systematic rounding: the carried remainder keeps the total, in a fixed order.
    double carry = 0;
    for (std::size_t p = 0; p < importance.size(); ++p) {
        if (!(importance[p] > 0)) continue;
        const double share = extra * importance[p] / total + carry;
        const double whole = std::floor(share);
        carry = share - whole;
        paths[p] = int(std::min<double>(most, whole));
    }
    return paths;
}

template std::vector<std::vector<float>> pathImportance<kRgbBlock>(const std::vector<Observation>&,
                                                                   const std::vector<PathSet>&,
                                                                   const std::vector<PathSet>&,
                                                                   const std::vector<double>&,
                                                                   const std::vector<double>&, int);
template std::vector<std::vector<float>> pathImportance<kGreyBlock>(
    const std::vector<Observation>&, const std::vector<PathSet>&, const std::vector<PathSet>&,
    const std::vector<double>&, const std::vector<double>&, int);

}  // namespace phongfit
