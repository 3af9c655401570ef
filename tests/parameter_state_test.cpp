#include "parameter_state.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "grey_material.h"

namespace phongfit {
namespace {

using L = BlockLayout<kRgbBlock>;
constexpr int P = kRgbBlock;

PhongMaterial material(double kd, double ks, double n) { return test::greyMaterial(kd, ks, n); }

TEST(ParameterState, MaterialsThenTheExposureAsBlocksOfTheirOwnKind) {
    const ParameterState<P> without({material(0.3, 0.2, 50)}, false);
    EXPECT_EQ(without.blockCount(), 1);
    EXPECT_FALSE(without.exposure().fitted());

    ParameterState<P> state({material(0.3, 0.2, 50), material(0.1, 0.1, 5)}, true);
    EXPECT_EQ(state.materialCount(), 2);
    EXPECT_EQ(state.blockCount(), 3);
    EXPECT_EQ(state.exposure().slot(), 2);
    // Only the exposure's scale is free; flags are per flat coordinate.
    const std::vector<bool> flags = state.heldFlags();
    ASSERT_EQ(flags.size(), std::size_t(3 * P));
    for (int i = 0; i < P; ++i) {
        EXPECT_FALSE(flags[i]);
        EXPECT_EQ(flags[2 * P + i], i != L::kLogN) << i;
    }
    state.startAt({{material(0.3, 0.2, 50), material(0.1, 0.1, 5)}, 2.0});
    EXPECT_NEAR(state.exposureValue(), 2.0, 1e-14);
    EXPECT_NEAR(state.natural(0)[L::kLogN], std::log(50.0), 1e-14);
    // The estimate's natural blocks, as the convergence test compares them.
    const auto blocks =
        state.naturalBlocks(Estimate{{material(0.3, 0.2, 50), material(0.1, 0.1, 5)}, 4.0});
    ASSERT_EQ(blocks.size(), 3u);
    EXPECT_NEAR(blocks[2][L::kLogN], std::log(4.0 * kExposureCentre), 1e-14);
    EXPECT_EQ(blocks[2][L::diffuse(0)], 0);
}

TEST(ParameterState, HoldingKeepsTheStartValueAndTheOtherParameters) {
    ParameterState<P> state({material(0.3, 0.2, 50)}, false);
    state.startAt({{material(0.5, 0.4, 20)}, 1.0});
    const int ksGreen = L::specular(1);
    EXPECT_TRUE(state.hold({ksGreen}));
    EXPECT_FALSE(state.hold({ksGreen})) << "already held";
    EXPECT_TRUE(state.isHeld(0, ksGreen));
    const auto y = state.natural(0);
    EXPECT_NEAR(y[ksGreen], 0.2, 1e-15);
    EXPECT_NEAR(y[L::specular(0)], 0.4, 1e-15);
    EXPECT_NEAR(y[L::diffuse(1)], 0.5, 1e-15);
    EXPECT_NEAR(y[L::kLogN], std::log(20.0), 1e-15);
    // A new round starts the held coordinate at its start value again, the others at the estimate.
    state.startAt({{material(0.45, 0.35, 25)}, 1.0});
    EXPECT_NEAR(state.natural(0)[ksGreen], 0.2, 1e-15);
    EXPECT_NEAR(state.natural(0)[L::specular(2)], 0.35, 1e-15);
}

// A broad lobe whose ks is not significant keeps its n where it is (holdUnseenExponents): sent
// back to a sharp start, the lobe's share of the shading went to kd.
TEST(ParameterState, HoldingWhereItIsKeepsTheCurrentValue) {
    ParameterState<P> state({material(0.3, 0.3, 100)}, false);
    state.startAt({{material(0.7, 0.05, 1.2)}, 1.0});
    EXPECT_TRUE(state.hold({L::kLogN}, false));
    EXPECT_TRUE(state.isHeld(0, L::kLogN));
    EXPECT_NEAR(state.natural(0)[L::kLogN], std::log(1.2), 1e-15);
    EXPECT_NEAR(state.natural(0)[L::specular(0)], 0.05, 1e-15);
}

TEST(ParameterState, ReleasingExponentsLeavesTheExposureAlone) {
    ParameterState<P> state({material(0.3, 0.2, 50)}, true);
    state.startAt({{material(0.3, 0.2, 50)}, 1.0});
    EXPECT_TRUE(state.hold({L::kLogN, P + L::kLogN}));
    EXPECT_TRUE(state.held(0).n && state.held(1).n);
    state.releaseExponents();
    EXPECT_FALSE(state.held(0).n);
    EXPECT_TRUE(state.held(1).n);
}

TEST(ParameterState, SetExposureMovesItsStartAndValue) {
    ParameterState<P> state({material(0.3, 0.2, 50)}, true);
    state.startAt({{material(0.3, 0.2, 50)}, 1.0});
    state.setExposure(3.0);
    EXPECT_NEAR(state.exposureValue(), 3.0, 1e-14);
    EXPECT_DOUBLE_EQ(ExposureBlock::fromMaterial(state.start(1)), 3.0);
}

// Only s kd and s ks are seen: holding s rescales the free reflectances to keep the products.
TEST(ParameterState, HoldingTheExposureRescalesTheMaterialsToKeepTheProducts) {
    ParameterState<P> state({material(0.3, 0.2, 50)}, true);
    state.setExposure(1.2);  // the matched start
    state.startAt({{material(0.6, 0.3, 40)}, 2.0});
    // kd + ks = 0.9 at s = 2: held at s = 1.2 they would be 1.5; the lowest s that keeps them at
    // most 1 is 2 * 0.9 = 1.8.
    EXPECT_TRUE(state.hold({P + L::kLogN}));
    EXPECT_TRUE(state.held(1).n);
    EXPECT_NEAR(state.exposureValue(), 1.8, 1e-12);
    EXPECT_NEAR(ExposureBlock::fromMaterial(state.start(1)), 1.8, 1e-12);
    const auto y = state.natural(0);
    for (int g = 0; g < 3; ++g) {
        EXPECT_NEAR(1.8 * y[L::diffuse(g)], 2.0 * 0.6, 1e-12) << g;
        EXPECT_NEAR(1.8 * y[L::specular(g)], 2.0 * 0.3, 1e-12) << g;
    }
    EXPECT_NEAR(y[L::kLogN], std::log(40.0), 1e-14) << "n is not a scale";

    // From a dim estimate the start is kept, and a held kd is not rescaled.
    ParameterState<P> dim({material(0.3, 0.2, 50)}, true);
    dim.setExposure(1.2);
    dim.startAt({{material(0.2, 0.1, 40)}, 2.0});
    EXPECT_TRUE(dim.hold({L::diffuse(0)}));  // kd.r held at its start, 0.3
    EXPECT_TRUE(dim.hold({P + L::kLogN}));
    EXPECT_NEAR(dim.exposureValue(), 1.2, 1e-12);
    const auto z = dim.natural(0);
    EXPECT_NEAR(z[L::diffuse(0)], 0.3, 1e-15);
    EXPECT_NEAR(z[L::diffuse(1)], 0.2 * 2.0 / 1.2, 1e-12);
    EXPECT_NEAR(z[L::specular(0)], 0.1 * 2.0 / 1.2, 1e-12);
}

}  // namespace
}  // namespace phongfit
