#include "path_importance.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numeric>
#include <vector>

#include "material_params.h"

namespace phongfit {
namespace {

// A 5x1 recording: one term per pixel with one vertex at log(cos alpha) `logCos[p]`; set A's
// constants are 1 + noise[p], set B's 1 - noise[p] (the two recordings' difference).
PathSet recording(const std::vector<float>& logCos, const std::vector<double>& noise, int sign) {
    PathSet set;
    set.width = int(logCos.size());
    set.height = 1;
    set.spp = 4;
    set.slots = 1;
    set.background.assign(logCos.size(), Color<float>::Zero());
    set.pixelStart.push_back(0);
    for (std::size_t p = 0; p < logCos.size(); ++p) {
        set.terms.push_back(PathTerm{std::uint32_t(p), std::uint32_t(p), 1,
                                     Color<float>::Constant(float(1 + sign * noise[p]))});
        set.vertices.push_back(PathVertex{logCos[p], 0});
        set.pixelStart.push_back(std::uint32_t(p + 1));
    }
    return set;
}

Observation image(int width) {
    Observation o;
    o.width = width;
    o.height = 1;
    o.rgb.assign(std::size_t(3 * width), 1.0f);
    return o;
}

using L = BlockLayout<kGreyBlock>;

std::vector<float> importanceOf(const std::vector<float>& logCos, const std::vector<double>& noise,
                                const std::vector<double>& std,
                                const std::vector<float>& valid = {}) {
    Observation o = image(int(logCos.size()));
    for (float v : valid) o.valid.push_back(std::uint8_t(v));
    const std::vector<double> natural{0.3, 0.3, std::log(100.0)};
    return pathImportance<kGreyBlock>({o}, {recording(logCos, noise, 1)},
                                      {recording(logCos, noise, -1)}, natural, std, 1)[0];
}

TEST(PathImportance, PathsGoWhereTheLobeIsWhenTheExponentIsUncertain) {
    // Pixels 0-1 see the lobe (alpha 0 and 0.1), 2-7 only its far tail: with only n uncertain,
    // a path there tells nothing.
    const std::vector<float> logCos{0, float(std::log(std::cos(0.1))), -5, -5, -5, -5, -5, -5};
    const std::vector<double> noise(8, 0.2);
    std::vector<double> std(kGreyBlock, 0.0);
    std[L::kLogN] = 0.3;
    const std::vector<float> w = importanceOf(logCos, noise, std);
    EXPECT_GT(w[0], 0);
    EXPECT_GT(w[1], 0);
    for (int p = 2; p < 8; ++p) EXPECT_LT(w[p], 1e-30 * w[0]) << p;
    // With kd uncertain too, every pixel informs it: alike where the diffuse Jacobians and the
    // noise around are the same (pixels 6 and 7, beyond the lobe's noise at 0-1), more where a
    // lobe pixel's noise is near.
    std[L::diffuse(0)] = 0.01;
    const std::vector<float> both = importanceOf(logCos, noise, std);
    EXPECT_GT(both[7], 0);
    EXPECT_FLOAT_EQ(both[6], both[7]);
    EXPECT_GT(both[2], both[7]);
}

TEST(PathImportance, GrowsWithThePathsNoiseAndLeavesInvalidPixelsOut) {
    const std::vector<float> logCos(5, 0.0f);
    std::vector<double> std(kGreyBlock, 0.0);
    std[L::specular(0)] = 0.02;
    const std::vector<float> once = importanceOf(logCos, std::vector<double>(5, 0.1), std);
    const std::vector<float> twice = importanceOf(logCos, std::vector<double>(5, 0.2), std);
    for (int p = 0; p < 5; ++p) EXPECT_NEAR(twice[p], 2 * once[p], 1e-6 * once[p]) << p;
    const std::vector<float> masked =
        importanceOf(logCos, std::vector<double>(5, 0.1), std, {1, 0, 1, 1, 1});
    EXPECT_EQ(masked[1], 0);
    EXPECT_GT(masked[0], 0);
    // No standard error anywhere (everything held): no pixel is worth more paths.
    const std::vector<float> none =
        importanceOf(logCos, std::vector<double>(5, 0.1), std::vector<double>(kGreyBlock, 0.0));
    for (float v : none) EXPECT_EQ(v, 0);
}

TEST(AllocatePaths, SharesTheExtraPathsInProportionWithinTheCap) {
    const std::vector<float> importance{0, 1, 3, 0, 4};
    const std::vector<int> paths = allocatePaths(importance, 80, 1000);
    EXPECT_EQ(paths, (std::vector<int>{0, 10, 30, 0, 40}));
    // The total is kept through rounding.
    const std::vector<int> odd = allocatePaths({1, 1, 1}, 10, 1000);
    EXPECT_EQ(std::accumulate(odd.begin(), odd.end(), 0), 10);
    // At most `most` in a pixel.
    EXPECT_EQ(allocatePaths({1, 0, 0}, 5000, 1024), (std::vector<int>{1024, 0, 0}));
    // Nothing to share, or nowhere to put it.
    EXPECT_EQ(allocatePaths({0, 0}, 10, 1024), (std::vector<int>{0, 0}));
    EXPECT_EQ(allocatePaths({1, 2}, 0, 1024), (std::vector<int>{0, 0}));
}

}  // namespace
}  // namespace phongfit
