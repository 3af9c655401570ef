#include "path_growth.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numeric>
#include <vector>

namespace phongfit {
namespace {

using Paths = std::vector<std::vector<std::uint32_t>>;

TEST(PathsPerPixel, ReadsEachSetsCountsOrItsSpp) {
    PathSet uniform, shared;
    uniform.width = 2, uniform.height = 1, uniform.spp = 4;
    shared.width = 3, shared.height = 1, shared.spp = 4;
    shared.pixelPaths = {4, 9, 1028};
    EXPECT_EQ(pathsPerPixel({uniform, shared}), (Paths{{4, 4}, {4, 9, 1028}}));
}

TEST(WeighedPathVariance, SumsImportanceSquaredOverPaths) {
    // Pixels without importance (or without paths) add nothing.
    EXPECT_DOUBLE_EQ(weighedPathVariance({{2, 0, 3}, {1}}, {{4, 4, 9}, {0}}), 4.0 / 4 + 9.0 / 9);
}

TEST(PlannedPaths, SharesTheGrowthByImportanceWithinTheCap) {
    const Paths base{{4, 4, 4, 4}};
    EXPECT_EQ(plannedPaths({{1, 1, 0, 2}}, base, 1), base);
    // Factor 3: twice the mean base of the 3 pixels with importance more, 24 paths, 1:1:2.
    EXPECT_EQ(plannedPaths({{1, 1, 0, 2}}, base, 3), (Paths{{10, 10, 4, 16}}));
    // Far past the cap: every pixel with importance at kMostExtraPaths more, the others as before.
    const std::uint32_t capped = 4 + kMostExtraPaths;
    EXPECT_EQ(plannedPaths({{1, 1, 0, 2}}, base, 1e6), (Paths{{capped, capped, 4, capped}}));
}

TEST(MostPathGain, IsLargeWhereTheInformationIsSpread) {
    // Spread evenly over many pixels: the cap is 257 times the first round's 4 paths away.
    const std::vector<std::vector<float>> importance{std::vector<float>(1000, 1.0f)};
    const Paths base{std::vector<std::uint32_t>(1000, 4)};
    EXPECT_NEAR(mostPathGain(importance, base, 1), (4.0 + kMostExtraPaths) / 4, 1e-9);
    EXPECT_NEAR(mostPathGain(importance, base, 16), (4.0 + kMostExtraPaths) / 64, 1e-9);
}

TEST(MostPathGain, FallsBelowTwoOnceTheInformativePixelIsNearItsCap) {
    // One pixel of 1000 holds the information. At 4 paths a pixel the cap is far; at 1.3 times
    // the first round's paths (1200 extra, all but a tenth in that pixel) it is at the cap, and
    // more paths go where they inform nothing.
    std::vector<float> weights(1000, 1e-4f);
    weights[0] = 1;
    const std::vector<std::vector<float>> importance{weights};
    const Paths base{std::vector<std::uint32_t>(1000, 4)};
    EXPECT_GT(mostPathGain(importance, base, 1), 200);
    EXPECT_GE(mostPathGain(importance, base, 1.1), kLeastPathGain);
    EXPECT_LT(mostPathGain(importance, base, 1.3), 1.01);
    EXPECT_LT(mostPathGain(importance, base, 1.3), kLeastPathGain);
}

TEST(MostPathGain, IsInfiniteWithoutImportance) {
    EXPECT_TRUE(std::isinf(mostPathGain({{0, 0}}, {{4, 4}}, 2)));
}

}  // namespace
}  // namespace phongfit
