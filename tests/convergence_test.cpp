#include "convergence.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

namespace phongfit {
namespace {

using Rgb = Eigen::Matrix<double, kRgbBlock, 1>;
using Grey = Eigen::Matrix<double, kGreyBlock, 1>;

FitOptions tolerances(double tolerance, double stdTolerance) {
    FitOptions o;
    o.tolerance = tolerance;
    o.stdTolerance = stdTolerance;
    return o;
}

// kd (r, g, b), ks (r, g, b), log n.
Rgb rgb(double kd, double ks, double logN) {
    Rgb y;
    y << kd, kd, kd, ks, ks, ks, logN;
    return y;
}

const std::vector<std::vector<double>> kNoStd(1, std::vector<double>(kRgbBlock, 0.0));

TEST(Convergence, ReflectancesMoveRelativelyLogNAbsolutely) {
    const FitOptions o = tolerances(1e-3, 3);
    const std::vector<Rgb> before = {rgb(0.5, 0.2, std::log(30.0))};
    EXPECT_TRUE(withinTolerance<kRgbBlock>(before, before, kNoStd, o));
    // kd 0.5 may move by 5e-4, ks 0.2 by 2e-4, log n by 1e-3.
    EXPECT_TRUE(withinTolerance<kRgbBlock>(before, {rgb(0.5004, 0.2, std::log(30.0))}, kNoStd, o));
    EXPECT_FALSE(withinTolerance<kRgbBlock>(before, {rgb(0.5006, 0.2, std::log(30.0))}, kNoStd, o));
    EXPECT_TRUE(withinTolerance<kRgbBlock>(before, {rgb(0.5, 0.2001, std::log(30.0))}, kNoStd, o));
    EXPECT_FALSE(withinTolerance<kRgbBlock>(before, {rgb(0.5, 0.2003, std::log(30.0))}, kNoStd, o));
    EXPECT_TRUE(
        withinTolerance<kRgbBlock>(before, {rgb(0.5, 0.2, std::log(30.0) + 9e-4)}, kNoStd, o));
    EXPECT_FALSE(
        withinTolerance<kRgbBlock>(before, {rgb(0.5, 0.2, std::log(30.0) + 1.1e-3)}, kNoStd, o));
}

TEST(Convergence, ReflectancesNearZeroCompareAgainstTheFloor) {
    const FitOptions o = tolerances(1e-3, 3);
    // ks 0 may move by 1e-3 * kReflectanceFloor = 1e-5.
    const std::vector<Rgb> before = {rgb(0.5, 0, 0)};
    EXPECT_TRUE(withinTolerance<kRgbBlock>(before, {rgb(0.5, 0.9e-5, 0)}, kNoStd, o));
    EXPECT_FALSE(withinTolerance<kRgbBlock>(before, {rgb(0.5, 1.1e-5, 0)}, kNoStd, o));
}

TEST(Convergence, AMoveWithinTheStandardErrorsPasses) {
    const FitOptions o = tolerances(1e-3, 3);
    const std::vector<Rgb> before = {rgb(0.5, 0.2, 3)}, after = {rgb(0.5, 0.2, 3.5)};
    std::vector<std::vector<double>> stdNatural = kNoStd;
    EXPECT_FALSE(withinTolerance<kRgbBlock>(before, after, stdNatural, o));
    stdNatural[0][BlockLayout<kRgbBlock>::kLogN] = 0.2;  // 0.5 is 2.5 standard errors
    EXPECT_TRUE(withinTolerance<kRgbBlock>(before, after, stdNatural, o));
    stdNatural[0][BlockLayout<kRgbBlock>::kLogN] = 0.1;  // 5 standard errors
    EXPECT_FALSE(withinTolerance<kRgbBlock>(before, after, stdNatural, o));
}

// A round's path noise is its standard error times the square root of the recordings' share; two
// rounds' independent noises add in quadrature.
TEST(Convergence, PathNoiseIsTheRecordingsShareAndAddsInQuadrature) {
    const std::vector<std::vector<double>> std = {{0.2, 0.4}}, share = {{0.25, 1.5}};
    const std::vector<std::vector<double>> paths = pathNoise(std, share);
    ASSERT_EQ(paths.size(), 1u);
    EXPECT_DOUBLE_EQ(paths[0][0], 0.1);
    EXPECT_DOUBLE_EQ(paths[0][1], 0.4);  // a share is at most 1
    EXPECT_TRUE(pathNoise(std, {}).empty());
    std::vector<std::vector<double>> noise = {{0.3, 0.3}};
    addPathNoise(noise, paths);
    EXPECT_DOUBLE_EQ(noise[0][0], std::hypot(0.3, 0.1));
    EXPECT_DOUBLE_EQ(noise[0][1], 0.5);
    addPathNoise(noise, {});
    EXPECT_DOUBLE_EQ(noise[0][1], 0.5);
}

TEST(Convergence, EveryBlockAndTheGreyLayout) {
    const FitOptions o = tolerances(1e-3, 3);
    Grey a, b;
    a << 0.4, 0.1, 2;  // kd, ks, log n
    b << 0.4, 0.1, 2.01;
    const std::vector<std::vector<double>> none(2, std::vector<double>(kGreyBlock, 0.0));
    EXPECT_TRUE(withinTolerance<kGreyBlock>({a, a}, {a, a}, none, o));
    EXPECT_FALSE(withinTolerance<kGreyBlock>({a, a}, {a, b}, none, o));
}

}  // namespace
}  // namespace phongfit
