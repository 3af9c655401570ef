#include "path_growth.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

namespace phongfit {
namespace {

using Importance = std::vector<std::vector<float>>;

std::vector<PixelPaths> uniform(std::uint32_t spp) { return {PixelPaths{spp, {}}}; }

TEST(PathsPerPixel, ReadsEachSetsCountsOrItsSpp) {
    PathSet even, shared;
    even.width = 2, even.height = 1, even.spp = 4;
    shared.width = 3, shared.height = 1, shared.spp = 4;
    shared.pixelPaths = {4, 9, 1028};
    const std::vector<PixelPaths> paths = pathsPerPixel({even, shared});
    ASSERT_EQ(paths.size(), 2u);
    EXPECT_TRUE(paths[0].perPixel.empty());  // no copy of a uniform recording's counts
    EXPECT_EQ(paths[0].at(0), 4u);
    EXPECT_EQ(paths[0].at(1), 4u);
    EXPECT_EQ(paths[1].perPixel, (std::vector<std::uint32_t>{4, 9, 1028}));
    EXPECT_EQ(paths[1].at(2), 1028u);
}

TEST(MostPathGain, WeighsImportanceSquaredOverPaths) {
    // Pixels without importance, or without paths, add nothing: now 4/4 + 9/9 over the cap's
    // 4/1028 + 9/1033 + 1/1024.
    const std::vector<PixelPaths> base{PixelPaths{0, {4, 4, 9}}, PixelPaths{0, {0}}};
    const double most = 4.0 / 1028 + 9.0 / 1033 + 1.0 / 1024;
    EXPECT_NEAR(mostPathGain({{2, 0, 3}, {1}}, base, 1), (4.0 / 4 + 9.0 / 9) / most, 1e-12);
}

TEST(MostPathGain, SharesTheGrowthByImportanceWithinTheCap) {
    // Factor 3: twice the mean base of the 3 pixels with importance more, 24 paths shared 1:1:2,
    // 10, 10 and 16 paths: 1/10 + 1/10 + 4/16 against 6/1028 at the cap.
    const Importance weights{{1, 1, 0, 2}};
    EXPECT_NEAR(mostPathGain(weights, uniform(4), 3), 0.45 / (6.0 / 1028), 1e-9);
    // Far past the cap: every pixel with importance at kMostExtraPaths more, the others as before.
    EXPECT_NEAR(mostPathGain(weights, uniform(4), 1e6), 1, 1e-12);
}

TEST(MostPathGain, IsLargeWhereTheInformationIsSpread) {
    // Spread evenly over many pixels: the cap is 257 times the first round's 4 paths away.
    const Importance importance{std::vector<float>(1000, 1.0f)};
    EXPECT_NEAR(mostPathGain(importance, uniform(4), 1), (4.0 + kMostExtraPaths) / 4, 1e-9);
    EXPECT_NEAR(mostPathGain(importance, uniform(4), 16), (4.0 + kMostExtraPaths) / 64, 1e-9);
}

TEST(MostPathGain, FallsBelowTwoOnceTheInformativePixelIsNearItsCap) {
    // One pixel of 1000 holds the information. At 4 paths a pixel the cap is far; at 1.3 times
    // the first round's paths (1200 extra, all but a tenth in that pixel) it is at the cap, and
    // more paths go where they inform nothing.
    std::vector<float> weights(1000, 1e-4f);
    weights[0] = 1;
    const Importance importance{weights};
    EXPECT_GT(mostPathGain(importance, uniform(4), 1), 200);
    EXPECT_GE(mostPathGain(importance, uniform(4), 1.1), kLeastPathGain);
    EXPECT_LT(mostPathGain(importance, uniform(4), 1.3), 1.01);
    EXPECT_LT(mostPathGain(importance, uniform(4), 1.3), kLeastPathGain);
}

TEST(MostPathGain, IsInfiniteWithoutImportance) {
    EXPECT_TRUE(std::isinf(mostPathGain({{0, 0}}, uniform(4), 2)));
}

}  // namespace
}  // namespace phongfit
