#include "rng.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <functional>
#include <utility>
#include <vector>

#include "chi_square.h"

namespace phongfit {
namespace {

// A value is a pure function of (seed, stream, sample, dimension): replaying samples and dimensions
// in reverse, on a fresh generator, gives the same numbers (as pbrt-v4's Sampler.ConsistentValues).
TEST(CounterRng, ConsistentValuesInAnyOrder) {
    constexpr int kSamples = 64, kDims = 16;
    for (const std::uint64_t seed : {0ULL, 1ULL, 0xdeadbeefULL})
        for (const std::uint64_t stream : {0ULL, 7ULL, 1920ULL * 1080ULL}) {
            const CounterRng forward(seed, stream);
            std::vector<double> values;
            for (int i = 0; i < kSamples; ++i)
                for (int d = 0; d < kDims; ++d) values.push_back(forward.uniform(i, d));
            const CounterRng replay(seed, stream);
            for (int i = kSamples - 1; i >= 0; --i)
                for (int d = kDims - 1; d >= 0; --d)
                    ASSERT_EQ(replay.uniform(i, d), values[i * kDims + d])
                        << "seed " << seed << " stream " << stream << " sample " << i << " dim "
                        << d;
        }
    constexpr double atCompileTime = CounterRng(3, 4).uniform(5, 6);
    EXPECT_EQ(atCompileTime, CounterRng(3, 4).uniform(5, 6));
}

TEST(CounterRng, DifferentKeysGiveDifferentValues) {
    std::vector<std::uint64_t> bits;
    for (const std::uint64_t seed : {0ULL, 1ULL, 2ULL})
        for (std::uint64_t stream = 0; stream < 32; ++stream)
            for (std::uint64_t sample = 0; sample < 32; ++sample)
                for (std::uint32_t dim = 0; dim < 8; ++dim)
                    bits.push_back(CounterRng(seed, stream).bits(sample, dim));
    std::sort(bits.begin(), bits.end());
    EXPECT_EQ(std::adjacent_find(bits.begin(), bits.end()), bits.end())
        << "two (seed, stream, sample, dimension) keys gave the same 64 bits";
}

TEST(CounterRng, UniformInUnitIntervalWithMeanAndVarianceOfU01) {
    constexpr int kCount = 1'000'000;
    const CounterRng rng(42, 3);
    double sum = 0, sumSq = 0, lo = 1, hi = 0;
    for (int i = 0; i < kCount; ++i) {
        const double u = rng.uniform(i / 4, i % 4);
        ASSERT_GE(u, 0.0);
        ASSERT_LT(u, 1.0);
        lo = std::min(lo, u);
        hi = std::max(hi, u);
        sum += u;
        sumSq += u * u;
    }
    const double mean = sum / kCount, variance = sumSq / kCount - mean * mean;
    // Five standard errors: sd(u) = 0.289, sd(u^2 - E u^2) ~ 0.298.
    EXPECT_NEAR(mean, 0.5, 5 * 0.289 / 1000);
    EXPECT_NEAR(variance, 1.0 / 12, 5 * 0.075 / 1000);
    EXPECT_LT(lo, 1e-5);
    EXPECT_GT(hi, 1 - 1e-5);
}

// Pairs of numbers that a sampler uses together, (dimension d, d + 1), and neighbours across
// samples and streams, fill the unit square uniformly: chi-square over a 32 x 32 grid.
TEST(CounterRng, PairsAreUniformInTheUnitSquare) {
    constexpr int kGrid = 32, kPairs = 500'000;
    struct Pairing {
        const char* what;
        std::function<std::pair<double, double>(int)> pair;
    };
    const CounterRng rng(9, 0);
    const std::vector<Pairing> pairings = {
        {"dimensions 0 and 1",
         [&](int i) { return std::pair(rng.uniform(i, 0), rng.uniform(i, 1)); }},
        {"dimensions 5 and 6",
         [&](int i) { return std::pair(rng.uniform(i, 5), rng.uniform(i, 6)); }},
        {"samples i and i + 1",
         [&](int i) { return std::pair(rng.uniform(2 * i, 2), rng.uniform(2 * i + 1, 2)); }},
        {"streams s and s + 1",
         [](int i) {
             const std::uint64_t s = 2 * std::uint64_t(i);
             return std::pair(CounterRng(9, s).uniform(0, 0), CounterRng(9, s + 1).uniform(0, 0));
         }},
    };
    const double alpha = sidakSignificance(0.01, int(pairings.size()));
    for (const Pairing& p : pairings) {
        std::vector<double> observed(kGrid * kGrid, 0.0);
        for (int i = 0; i < kPairs; ++i) {
            const auto [a, b] = p.pair(i);
            ++observed[int(a * kGrid) * kGrid + int(b * kGrid)];
        }
        const std::vector<double> expected(kGrid * kGrid, double(kPairs) / (kGrid * kGrid));
        const ChiSquareResult r = chiSquareTest(observed, expected);
        EXPECT_EQ(r.dof, kGrid * kGrid - 1);
        EXPECT_GE(r.pValue, alpha) << p.what << ": chi2 = " << r.statistic;
    }
}

}  // namespace
}  // namespace phongfit
