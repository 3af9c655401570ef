// PathSetFilm (path_set_film.h): the set it assembles holds each pixel's terms, and their
// vertices, in the order they were traced, pass after pass, whatever order the tiles' records
// interleave the pixels in; a dropped sample leaves nothing, and a pixel that kept fewer samples
// is the mean of those it kept.
#include "path_set_film.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include "rng.h"

namespace phongfit {
namespace {

// Term k of pixel p's sample s: a vertex count and a log-cosine that say which it is.
std::uint32_t vertexCount(std::uint32_t p, int s) { return 1 + (p + std::uint32_t(s)) % 3; }
float logCos(std::uint32_t p, int s, std::uint32_t v) { return -float(1000 * p + 10 * s + v); }

TEST(PathSetFilm, EachPixelKeepsItsTermsInTheOrderTracedAcrossPasses) {
    // A 32x2 film in two 16x2 tiles, as the tile loop traces it: passes of 1, 2, 4 and 4 samples,
    // each over every tile's pixels in order. Some samples leave no term, some two, one is dropped.
    const int width = 32, height = 2, spp = 11;
    std::vector<int> paths(width * height, spp);
    paths[3] = 7;  // a pixel that takes fewer
    PathSetFilm film(width, height, paths, 2);
    const auto terms = [](std::uint32_t p, int s) {
        return (p * 7 + std::uint32_t(s)) % 4 == 0 ? 0 : 1 + (s % 5 == 4);
    };
    const auto dropped = [](std::uint32_t p, int s) { return p == 17 && s == 5; };
    for (const auto& [s0, s1] : {std::pair{0, 1}, {1, 3}, {3, 7}, {7, 11}})
        for (std::size_t tile = 0; tile < 2; ++tile)
            for (std::uint32_t y = 0; y < std::uint32_t(height); ++y)
                for (std::uint32_t x = 16 * std::uint32_t(tile); x < 16 * (tile + 1); ++x) {
                    const std::uint32_t p = y * width + x;
                    for (int s = s0; s < std::min(s1, film.samples(p)); ++s) {
                        auto sample = film.startSample(tile, p, s);
                        for (int t = 0; t < terms(p, s); ++t) {
                            std::vector<PathVertex> vertices;
                            for (std::uint32_t v = 0; v < vertexCount(p, s); ++v)
                                vertices.push_back({logCos(p, s, v), p});
                            sample.add(Color3::Constant(s + 0.25 * t), vertices);
                        }
                        if (dropped(p, s))
                            sample.drop();
                        else
                            sample.keep(Color3::Zero());
                    }
                }
    const PathSet set = film.assemble(spp, 1);

    ASSERT_EQ(set.pixelStart.size(), std::size_t(width * height + 1));
    for (std::uint32_t p = 0; p < std::uint32_t(width * height); ++p) {
        const int kept = paths[p] - (p == 17 ? 1 : 0);
        std::uint32_t i = set.pixelStart[p];
        for (int s = 0; s < paths[p]; ++s) {
            if (dropped(p, s)) continue;
            for (int t = 0; t < terms(p, s); ++t, ++i) {
                ASSERT_LT(i, set.pixelStart[p + 1]) << "pixel " << p << " sample " << s;
                const PathTerm& term = set.terms[i];
                EXPECT_EQ(term.pixel, p);
                EXPECT_FLOAT_EQ(term.constant[0], float((s + 0.25 * t) / kept)) << p << " " << s;
                ASSERT_EQ(term.vertexCount, vertexCount(p, s));
                for (std::uint32_t v = 0; v < term.vertexCount; ++v)
                    EXPECT_EQ(set.vertices[term.firstVertex + v].logCos, logCos(p, s, v))
                        << "pixel " << p << " sample " << s << " vertex " << v;
            }
        }
        EXPECT_EQ(i, set.pixelStart[p + 1]) << "pixel " << p;
    }
}

// A film whose pixels each take 4 ringed samples and 12 sampled ones of the same mean, the
// sampled ones heavy-tailed (mostly 0, a quarter of them 4x the mean: light samples in a lobe),
// the two means about as noisy as each other (weights near 1/2, where weights taken from a
// pixel's own samples would bias it most).
struct MixedFilm {
    static constexpr int kSize = 48, kRinged = 4, kPaths = 16;
    static constexpr double kMean = 2;
    PathSet set;
    std::vector<double> ringedSum, sampledSum;  // per pixel
    std::vector<double> ringedSquares, sampledSquares;

    static double value(std::uint32_t p, int s) {
        const CounterRng rng(5, p);
        const double u = rng.uniform(std::uint64_t(s), 0);
        if (s < kRinged) return kMean + 3.5 * (2 * u - 1);
        return u < 0.25 ? 4 * kMean : 0.0;
    }

    MixedFilm() {
        const std::size_t pixels = std::size_t(kSize) * kSize;
        PathSetFilm film(kSize, kSize, std::vector<int>(pixels, kPaths), 1, kRinged);
        ringedSum.assign(pixels, 0);
        sampledSum.assign(pixels, 0);
        ringedSquares.assign(pixels, 0);
        sampledSquares.assign(pixels, 0);
        for (std::uint32_t p = 0; p < pixels; ++p)
            for (int s = 0; s < kPaths; ++s) {
                const double y = value(p, s);
                auto sample = film.startSample(0, p, s);
                sample.add(Color3::Constant(y), std::vector<PathVertex>{{-0.5f, 0}});
                sample.keep(Color3::Constant(y));
                (s < kRinged ? ringedSum : sampledSum)[p] += y;
                (s < kRinged ? ringedSquares : sampledSquares)[p] += y * y;
            }
        set = film.assemble(kPaths, 1);
    }

    // The pixel's estimate: the sum of its terms' constants (one vertex each, f left out).
    double estimate(std::size_t p) const {
        double sum = set.background[p][0];
        for (std::uint32_t t = set.pixelStart[p]; t < set.pixelStart[p + 1]; ++t)
            sum += set.terms[t].constant[0];
        return sum;
    }
};

// Each group's mean weighted by the inverse of its variance, the variances pooled over the 3 x 3
// neighbours (not the pixel itself), as computed here from the samples directly.
TEST(PathSetFilm, RingedAndSampledPathsAreWeightedByTheirNeighboursVariances) {
    const MixedFilm m;
    constexpr int n = MixedFilm::kSize;
    ASSERT_EQ(m.set.groups.size(), std::size_t(n * n));
    const auto spread = [](double sum, double squares, double k) {
        return squares - sum * sum / k;
    };
    for (int y = 0; y < n; ++y)
        for (int x = 0; x < n; ++x) {
            const std::size_t p = std::size_t(y) * n + std::size_t(x);
            double ringed = 0, sampled = 0, ringedFreedom = 0, sampledFreedom = 0;
            for (int v = std::max(y - 1, 0); v <= std::min(y + 1, n - 1); ++v)
                for (int u = std::max(x - 1, 0); u <= std::min(x + 1, n - 1); ++u) {
                    if (u == x && v == y) continue;
                    const std::size_t q = std::size_t(v) * n + std::size_t(u);
                    ringed += spread(m.ringedSum[q], m.ringedSquares[q], MixedFilm::kRinged);
                    sampled += spread(m.sampledSum[q], m.sampledSquares[q],
                                      MixedFilm::kPaths - MixedFilm::kRinged);
                    ringedFreedom += MixedFilm::kRinged - 1;
                    sampledFreedom += MixedFilm::kPaths - MixedFilm::kRinged - 1;
                }
            const double a = ringed / ringedFreedom / MixedFilm::kRinged;
            const double b = sampled / sampledFreedom / (MixedFilm::kPaths - MixedFilm::kRinged);
            const double w = std::clamp(b / (a + b), 1e-3, 1 - 1e-3);
            const double expected =
                w * m.ringedSum[p] / MixedFilm::kRinged +
                (1 - w) * m.sampledSum[p] / (MixedFilm::kPaths - MixedFilm::kRinged);
            ASSERT_NEAR(m.estimate(p), expected, 1e-6 * (1 + std::abs(expected))) << x << " " << y;
            EXPECT_EQ(m.set.groups[p].ringedTerms, std::uint32_t(MixedFilm::kRinged));
            EXPECT_FLOAT_EQ(m.set.groups[p].ringedScale, float(w * 16 / 4));
        }
}

// Weights from the neighbours are independent of the pixel's own samples, so each pixel's estimate
// stays unbiased where the sampled paths are heavy-tailed (weights from its own samples give the
// pixels whose sampled paths came out high the least weight there: biased low), and less noisy
// than the plain mean of its paths.
TEST(PathSetFilm, WeightedPixelsStayUnbiasedAndAreLessNoisyThanTheMean) {
    const MixedFilm m;
    const std::size_t pixels = m.set.background.size();
    double sum = 0, squares = 0, plainSquares = 0;
    for (std::size_t p = 0; p < pixels; ++p) {
        const double e = m.estimate(p) - MixedFilm::kMean;
        const double plain =
            (m.ringedSum[p] + m.sampledSum[p]) / MixedFilm::kPaths - MixedFilm::kMean;
        sum += e;
        squares += e * e;
        plainSquares += plain * plain;
    }
    const double mean = sum / double(pixels);
    const double standardError =
        std::sqrt((squares / double(pixels) - mean * mean) / double(pixels));
    EXPECT_LT(std::abs(mean), 3 * standardError);
    EXPECT_LT(squares, 0.9 * plainSquares);
}

}  // namespace
}  // namespace phongfit
