#include "exposure_block.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "error.h"

namespace phongfit {
namespace {

TEST(ExposureBlock, MapsTheScaleToTheLogCoordinateOfItsBlock) {
    // Block 1 after one material: its log n coordinate is log(s * kExposureCentre).
    const ExposureBlock exposure(1);
    EXPECT_TRUE(exposure.fitted());
    std::vector<double> y(2 * kRgbBlock, 0.0);
    y[kRgbBlock + BlockLayout<kRgbBlock>::kLogN] = std::log(2.5 * kExposureCentre);
    EXPECT_NEAR(exposure.value<kRgbBlock>(y.data()), 2.5, 1e-14);
    EXPECT_DOUBLE_EQ(ExposureBlock::fromCoordinate(std::log(kExposureCentre)), 1);
    // Its layout as a material: kd, ks 0 and held, n = s * kExposureCentre.
    const PhongMaterial m = ExposureBlock::asMaterial(2.5);
    EXPECT_TRUE((m.kd == 0).all() && (m.ks == 0).all());
    EXPECT_DOUBLE_EQ(m.n, 2.5 * kExposureCentre);
    EXPECT_DOUBLE_EQ(ExposureBlock::fromMaterial(m), 2.5);
    const HeldParams held = ExposureBlock::startHeld();
    for (int g = 0; g < 3; ++g) EXPECT_TRUE(held.kd[g] && held.ks[g]) << g;
    EXPECT_FALSE(held.n);
    // Its range is the exponent's.
    EXPECT_NEAR(kMinExposure * kExposureCentre, kMinExponent, 1e-15);
    EXPECT_NEAR(kMaxExposure * kExposureCentre, kMaxExponent, 1e-6);
}

TEST(ExposureBlock, NotFittedIsOne) {
    const ExposureBlock none;
    EXPECT_FALSE(none.fitted());
    EXPECT_EQ(none.slot(), -1);
    const std::vector<double> y(kGreyBlock, 5.0);
    EXPECT_EQ(none.value<kGreyBlock>(y.data()), 1);
}

TEST(ExposureBlock, MatchedIsTheLeastSquaresScale) {
    // Prediction 2 I at s = 2 against images y = 3 I: <sI, sI> = 4 |I|^2, <sI, y> = 6 |I|^2.
    EXPECT_DOUBLE_EQ(ExposureBlock::matched(2, 4, 6), 3);
    try {
        ExposureBlock::matched(1, 0, 1);
        FAIL() << "a black start has nothing to scale";
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find("start materials render black"), std::string::npos);
    }
    try {
        ExposureBlock::matched(1, 1, 0);
        FAIL() << "black images have nothing to match";
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find("images are black"), std::string::npos);
    }
    try {
        ExposureBlock::matched(1, 1, 1e9);
        FAIL() << "beyond kMaxExposure";
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find("times as bright"), std::string::npos);
    }
}

TEST(ExposureBlock, HeldAtItsStartOrAsHighAsKdPlusKsAtMostOneNeeds) {
    // Materials with kd + ks up to 0.8 at s = 2: rescaled by 2 / s they stay <= 1 for any s >= 1.6.
    EXPECT_DOUBLE_EQ(ExposureBlock::heldValue(1.8, 2, 0.8), 1.8);
    EXPECT_DOUBLE_EQ(ExposureBlock::heldValue(1.2, 2, 0.8), 1.6);
}

}  // namespace
}  // namespace phongfit
