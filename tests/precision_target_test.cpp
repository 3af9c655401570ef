// The precision target's plan (precision_target.h): met, more paths, or the images' noise floor,
// checked against the variance split worked out by hand.
#include "precision_target.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

namespace phongfit {
namespace {

using L = BlockLayout<kRgbBlock>;
constexpr int P = kRgbBlock;

PhongMaterial material(double kd, double ks) {
    PhongMaterial m;
    m.kd = Color3::Constant(kd);
    m.ks = Color3::Constant(ks);
    m.n = 30;
    return m;
}

ParameterState<P> stateAt(const PhongMaterial& m) {
    ParameterState<P> s({m}, false);
    s.startAt({{m}, 1.0});
    return s;
}

ParameterState<P> state() { return stateAt(material(0.5, 0.2)); }

// Standard errors (natural coordinates) giving every parameter the relative error `relative`.
std::vector<std::vector<double>> stdAt(double relative) {
    std::vector<double> s(P);
    for (int g = 0; g < L::kGroups; ++g) {
        s[std::size_t(L::diffuse(g))] = relative * 0.5;
        s[std::size_t(L::specular(g))] = relative * 0.2;
    }
    s[L::kLogN] = relative;
    return {s};
}

std::vector<std::vector<double>> shareOf(double share) { return {std::vector<double>(P, share)}; }

TEST(PrecisionTarget, MetWhenEveryFreeParameterIsAsPrecise) {
    const PrecisionPlan plan = planPrecision<P>(state(), stdAt(0.009), shareOf(1), 0.01, 1);
    EXPECT_TRUE(plan.met);
    EXPECT_FALSE(plan.floor);
    EXPECT_EQ(plan.pathGrowth, 1);
}

TEST(PrecisionTarget, PathsGrowByThePathVarianceOverWhatTheImageLeaves) {
    // Relative variance 4e-4 for a goal of 1e-4: with half of it the image's (2e-4 > 1e-4) the
    // target is out of reach; with a quarter (1e-4 of image, 3e-4 of paths) still; with a tenth
    // (0.4e-4 image, 3.6e-4 paths) the paths must grow 3.6 / (1 - 0.4) = 6 times.
    const PrecisionPlan tenth = planPrecision<P>(state(), stdAt(0.02), shareOf(0.9), 0.01, 1);
    EXPECT_FALSE(tenth.met);
    EXPECT_FALSE(tenth.floor);
    EXPECT_NEAR(tenth.pathGrowth, 6, 1e-9);
    // All paths: 4x.
    EXPECT_NEAR(planPrecision<P>(state(), stdAt(0.02), shareOf(1), 0.01, 1).pathGrowth, 4, 1e-9);
    // Far off, capped at kMostPathGrowth.
    EXPECT_EQ(planPrecision<P>(state(), stdAt(1), shareOf(1), 0.01, 1).pathGrowth, kMostPathGrowth);
}

TEST(PrecisionTarget, TheNoiseFloorIsClaimedOnlyOnceThePathsHaveGrown) {
    // Image-dominated: first more paths (the misfit of an unresolved lobe looks like image
    // noise), then, with kMostPathGrowth times the paths, the floor.
    const PrecisionPlan early = planPrecision<P>(state(), stdAt(0.02), shareOf(0.5), 0.01, 1);
    EXPECT_FALSE(early.floor);
    EXPECT_EQ(early.pathGrowth, kMostPathGrowth);
    const PrecisionPlan late =
        planPrecision<P>(state(), stdAt(0.02), shareOf(0.5), 0.01, kMostPathGrowth);
    EXPECT_TRUE(late.floor);
    EXPECT_FALSE(late.met);
}

// A lobe the recordings do not resolve (session 23, the Cornell box under a 40-degree light at n
// 30000, path factor 64): n's relative standard error 0.53 with 98.4% of its variance the
// recordings'. The image's 1.6% (0.0044) is past the goal, but the paths hold 60x more: not the
// image's noise floor; the paths grow (capped at kMostPathGrowth).
TEST(PrecisionTarget, NoFloorWhileThePathsHoldMostOfTheVariance) {
    const PrecisionPlan plan = planPrecision<P>(state(), stdAt(0.53), shareOf(0.984), 0.01, 64);
    EXPECT_FALSE(plan.met);
    EXPECT_FALSE(plan.floor);
    EXPECT_EQ(plan.pathGrowth, kMostPathGrowth);
    // Image and paths half and half: the floor.
    EXPECT_TRUE(planPrecision<P>(state(), stdAt(0.53), shareOf(0.5), 0.01, 64).floor);
}

TEST(PrecisionTarget, HeldParametersAndSmallReflectancesOnTheirFloor) {
    ParameterState<P> s = state();
    // n held (unconstrained): its huge standard error does not count.
    s.hold({L::kLogN});
    std::vector<std::vector<double>> std = stdAt(0.005);
    std[0][L::kLogN] = 10;
    EXPECT_TRUE(planPrecision<P>(s, std, shareOf(1), 0.01, 1).met);
    // A reflectance of 0.001 is compared with 0.1 (kPrecisionFloor): std 5e-4 is 0.5%, 2e-3 is 2%.
    std = stdAt(0.005);
    for (int g = 0; g < L::kGroups; ++g)
        std[0][std::size_t(L::diffuse(g))] = std[0][std::size_t(L::specular(g))] = 5e-4;
    EXPECT_TRUE(planPrecision<P>(stateAt(material(0.001, 0.001)), std, shareOf(1), 0.01, 1).met);
    for (int g = 0; g < L::kGroups; ++g) std[0][std::size_t(L::specular(g))] = 2e-3;
    EXPECT_FALSE(planPrecision<P>(stateAt(material(0.001, 0.001)), std, shareOf(1), 0.01, 1).met);
}

// A lobeless sphere under the Kerner probe (random round trip c009 of seed 91, 96 x 96, kd 0.64,
// ks 0): n held, ks 0.0003 +- 0.0066. That ks is a lobe's at an n the images do not determine;
// asked for 0.001 (1% of kPrecisionFloor) it grew the paths 58x and took 17.9 s to end at the
// noise floor. It is asked for 1% of its albedo, kd + ks, instead: how much of the albedo a lobe
// could hide. Where the ks shows a lobe, or n is free (the lobe still sought), as before.
TEST(PrecisionTarget, TheKsOfNoLobeIsAskedRelativeToTheAlbedo) {
    std::vector<std::vector<double>> std = stdAt(0.009);
    for (int g = 0; g < L::kGroups; ++g) std[0][std::size_t(L::specular(g))] = 0.0049;
    ParameterState<P> lobeless = stateAt(material(0.5, 0.0003));
    lobeless.hold({L::kLogN});
    EXPECT_TRUE(planPrecision<P>(lobeless, std, shareOf(1), 0.01, 1).met);
    EXPECT_FALSE(planPrecision<P>(stateAt(material(0.5, 0.0003)), std, shareOf(1), 0.01, 1).met);
    ParameterState<P> lobe = stateAt(material(0.5, 0.2));
    lobe.hold({L::kLogN});
    EXPECT_FALSE(planPrecision<P>(lobe, std, shareOf(1), 0.01, 1).met);
    // Paths grow until the lobeless ks is 1% of kd + ks: (0.0098 / 0.005)^2 = 3.84x.
    for (int g = 0; g < L::kGroups; ++g) std[0][std::size_t(L::specular(g))] = 0.0098;
    EXPECT_NEAR(planPrecision<P>(lobeless, std, shareOf(1), 0.01, 1).pathGrowth,
                std::pow(0.0098 / 0.005003, 2), 1e-9);
    // A move of the lobeless ks counts against the target at the same scale.
    std::vector<Eigen::Matrix<double, P, 1>> before = lobeless.naturalBlocks(), after = before;
    for (int g = 0; g < L::kGroups; ++g) after[0][L::specular(g)] += 0.004;
    EXPECT_FALSE(movedPastTarget<P>(lobeless, std, before, after, 0.01));
    EXPECT_TRUE(movedPastTarget<P>(stateAt(material(0.5, 0.0003)), std, before, after, 0.01));
    for (int g = 0; g < L::kGroups; ++g) after[0][L::specular(g)] += 0.002;
    EXPECT_TRUE(movedPastTarget<P>(lobeless, std, before, after, 0.01));

    MaterialFit m;
    m.kd = Color3::Constant(0.6395);
    m.ks = Color3::Constant(0.0003);
    m.n = 0.0173;
    m.kdStd = Color3::Constant(0.0061);
    m.ksStd = Color3::Constant(0.0061);
    m.unconstrained = {"n"};
    EXPECT_TRUE(meetsPrecision({m}, 0.01, PrecisionOf::Reported));
    m.ksStd = Color3::Constant(0.0066);
    EXPECT_FALSE(meetsPrecision({m}, 0.01, PrecisionOf::Reported));
    // A confirmed lobe's ks is asked relative to itself.
    m.ks = Color3::Constant(0.2);
    m.ksStd = Color3::Constant(0.0061);
    EXPECT_FALSE(meetsPrecision({m}, 0.01, PrecisionOf::Reported));
}

// What a fit reports, judged as the plan judges a round: matrix cell 0109 (Cornell box, n 30,
// ks 0.05) met 1% in its last round (n 30.275 +- 0.2), and the rounds' scatter widened n to
// +- 1.8 (log n +- 0.059): the result is not 1% precise. Its image's noise alone is.
TEST(PrecisionTarget, JudgesTheReportedOrTheImageNoiseStandardErrors) {
    MaterialFit m;
    m.kd = Color3::Constant(0.7);
    m.ks = Color3::Constant(0.05);
    m.n = 30.275;
    m.kdStd = Color3::Constant(0.0011);
    m.ksStd = Color3::Constant(0.001);  // 1% of max(0.05, kPrecisionFloor)
    m.logNStd = 0.0066;
    m.kdImageStd = m.ksImageStd = Color3::Constant(0.0005);
    m.logNImageStd = 0.005;
    EXPECT_TRUE(meetsPrecision({m}, 0.01, PrecisionOf::Reported));
    m.logNStd = 0.059;
    EXPECT_FALSE(meetsPrecision({m}, 0.01, PrecisionOf::Reported));
    EXPECT_TRUE(meetsPrecision({m}, 0.01, PrecisionOf::ImageNoise));
    EXPECT_TRUE(meetsPrecision({m}, 0.06, PrecisionOf::Reported));
    // An n listed unconstrained (no lobe holds it) keeps its own wide error and is not asked.
    m.unconstrained = {"n"};
    EXPECT_TRUE(meetsPrecision({m}, 0.01, PrecisionOf::Reported));
    // kd per channel, relative to its value; the image's noise judged apart.
    m.kdStd[2] = 0.0071;
    EXPECT_FALSE(meetsPrecision({m}, 0.01, PrecisionOf::Reported));
    m.kdImageStd[1] = 0.0071;
    EXPECT_FALSE(meetsPrecision({m}, 0.01, PrecisionOf::ImageNoise));
}

}  // namespace
}  // namespace phongfit
