#include "used_pixels.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <map>
#include <vector>

#include "error.h"

namespace phongfit {
namespace {

// A width x height path set whose pixels have one term per listed slot (vertex log cos 0) and the
// given background (0 elsewhere).
PathSet pathSet(int width, int height, const std::map<int, std::vector<std::uint32_t>>& terms,
                const std::map<int, float>& background = {}, int slots = 2) {
    PathSet ps;
    ps.width = width;
    ps.height = height;
    ps.spp = 1;
    ps.slots = slots;
    ps.pixelStart.push_back(0);
    for (int p = 0; p < width * height; ++p) {
        const auto b = background.find(p);
        ps.background.push_back(Color<float>::Constant(b == background.end() ? 0.0f : b->second));
        const auto t = terms.find(p);
        if (t != terms.end()) {
            for (std::uint32_t slot : t->second) {
                PathTerm term;
                term.pixel = std::uint32_t(p);
                term.firstVertex = std::uint32_t(ps.vertices.size());
                term.vertexCount = 1;
                term.constant = Color<float>::Constant(1.0f);
                ps.vertices.push_back({0.0f, slot});
                ps.terms.push_back(term);
            }
        }
        ps.pixelStart.push_back(std::uint32_t(ps.terms.size()));
    }
    return ps;
}

Observation observation(int width, int height, float value = 0.5f) {
    Observation obs;
    obs.width = width;
    obs.height = height;
    obs.rgb.assign(std::size_t(3 * width * height), value);
    return obs;
}

TEST(UsedPixels, KeepsPixelsThatSeeAMaterialAndCountsTheOthersByReason) {
    // A row of 6 pixels: 0 sees slot 1, 1 is masked, 2 has a NaN observation, 3 sees slots 1 and
    // 0 (listed sorted), 4 has only background, 5 sees nothing.
    const std::vector<PathSet> set = {
        pathSet(6, 1, {{0, {1}}, {1, {0}}, {2, {0}}, {3, {1, 0}}}, {{4, 0.2f}})};
    Observation obs = observation(6, 1);
    obs.valid = {1, 0, 1, 1, 1, 1};
    obs.rgb[3 * 2 + 1] = std::numeric_limits<float>::quiet_NaN();
    obs.weight = {2, 1, 1, 1, 1, 1};
    const UsedPixels used = selectUsedPixels({obs}, {&set}, 2, 0, ExposureBlock());

    ASSERT_EQ(used.pixels.size(), 2u);
    EXPECT_EQ(used.seeingMaterial, 2u);
    EXPECT_EQ(used.pixels[0].pixel, 0u);
    EXPECT_EQ(used.pixels[1].pixel, 3u);
    EXPECT_EQ(std::vector<std::uint32_t>(used.slotsOf(used.pixels[0]).begin(),
                                         used.slotsOf(used.pixels[0]).end()),
              std::vector<std::uint32_t>({1}));
    EXPECT_EQ(std::vector<std::uint32_t>(used.slotsOf(used.pixels[1]).begin(),
                                         used.slotsOf(used.pixels[1]).end()),
              std::vector<std::uint32_t>({0, 1}));
    EXPECT_EQ(used.leftOut.at("masked"), 1u);
    EXPECT_EQ(used.leftOut.at("non_finite"), 1u);
    EXPECT_EQ(used.leftOut.at("no_fitted_material"), 2u);
    EXPECT_EQ(used.index[0], (std::vector<std::int32_t>{0, -1, -1, 1, -1, -1}));
    EXPECT_EQ(used.slotSeen, (std::vector<bool>{true, true}));
    EXPECT_DOUBLE_EQ(used.meanObserved, 0.5);
    // Of weight * observation: pixel 0 has weight 2.
    EXPECT_DOUBLE_EQ(used.rmsObserved, std::sqrt((4 * 0.25 * 3 + 0.25 * 3) / 6));
}

TEST(UsedPixels, NeighboursWithinTheRadiusEnterAfterThoseThatSeeAMaterial) {
    // 9 x 1: pixel 4 sees slot 0. With radius 2, pixels 2..6 enter; 2, 3, 5, 6 see no material.
    const std::vector<PathSet> set = {pathSet(9, 1, {{4, {0}}})};
    const UsedPixels used = selectUsedPixels({observation(9, 1)}, {&set}, 2, 2, ExposureBlock());
    ASSERT_EQ(used.pixels.size(), 5u);
    EXPECT_EQ(used.seeingMaterial, 1u);
    EXPECT_EQ(used.pixels[0].pixel, 4u);
    EXPECT_TRUE(used.pixels[0].seesMaterial);
    for (std::size_t i = 1; i < used.pixels.size(); ++i) {
        EXPECT_FALSE(used.pixels[i].seesMaterial);
        EXPECT_EQ(used.index[0][used.pixels[i].pixel], std::int32_t(i));
    }
    EXPECT_EQ(used.leftOut.at("no_fitted_material"), 4u);
    EXPECT_EQ(used.slotSeen, (std::vector<bool>{true, false}));
    // Only the pixels that see a material enter the observed mean.
    EXPECT_DOUBLE_EQ(used.meanObserved, 0.5);
}

TEST(UsedPixels, APixelEntersWhereEitherSetSeesAMaterial) {
    // Selecting by one set alone would select that set's residuals by its own noise.
    const std::vector<PathSet> a = {pathSet(3, 1, {{0, {0}}})};
    const std::vector<PathSet> b = {pathSet(3, 1, {{2, {1}}})};
    const UsedPixels used = selectUsedPixels({observation(3, 1)}, {&a, &b}, 2, 0, ExposureBlock());
    ASSERT_EQ(used.pixels.size(), 2u);
    EXPECT_EQ(used.pixels[0].pixel, 0u);
    EXPECT_EQ(used.pixels[1].pixel, 2u);
    EXPECT_TRUE(used.pixels[1].seesMaterial);
}

TEST(UsedPixels, WithAFittedExposureEveryLitPixelSeesItsBlock) {
    // The exposure is block 2 after two materials: pixel 1 has only background light, pixel 2
    // none.
    const std::vector<PathSet> set = {pathSet(3, 1, {{0, {0}}}, {{1, 0.3f}})};
    const UsedPixels used = selectUsedPixels({observation(3, 1)}, {&set}, 3, 0, ExposureBlock(2));
    ASSERT_EQ(used.pixels.size(), 2u);
    EXPECT_EQ(used.seeingMaterial, 2u);
    EXPECT_EQ(std::vector<std::uint32_t>(used.slotsOf(used.pixels[0]).begin(),
                                         used.slotsOf(used.pixels[0]).end()),
              std::vector<std::uint32_t>({0, 2}));
    EXPECT_EQ(std::vector<std::uint32_t>(used.slotsOf(used.pixels[1]).begin(),
                                         used.slotsOf(used.pixels[1]).end()),
              std::vector<std::uint32_t>({2}));
    EXPECT_EQ(used.leftOut.at("no_fitted_material"), 1u);
}

TEST(UsedPixels, ThrowsWhenNoPixelIsLeft) {
    const std::vector<PathSet> set = {pathSet(2, 1, {})};
    EXPECT_THROW(selectUsedPixels({observation(2, 1)}, {&set}, 2, 2, ExposureBlock()), Error);
}

}  // namespace
}  // namespace phongfit
