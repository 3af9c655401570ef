// Rounds pooled by their recordings' noise (pooled_rounds.h): the weighted mean, its variances
// and its chi-square against the formulas worked out by hand, and against many simulated rounds.
#include "pooled_rounds.h"

#include <gtest/gtest.h>

#include <cmath>
#include <optional>
#include <random>
#include <vector>

#include "grey_material.h"

namespace phongfit {
namespace {

using L = BlockLayout<kRgbBlock>;
constexpr int P = kRgbBlock;

PhongMaterial material(double kd, double ks, double n) { return test::greyMaterial(kd, ks, n); }

ParameterState<P> stateAt(const PhongMaterial& m) {
    ParameterState<P> s({m}, false);
    s.startAt({{m}, 1.0});
    return s;
}

// A round's outcome at `params`' point: every parameter's standard error `std`, the recordings'
// share of its variance `share`.
RoundOutcome outcome(const ParameterState<P>& params, double std, double share) {
    RoundOutcome out;
    out.naturalStd = {std::vector<double>(P, std)};
    out.pathShare = {std::vector<double>(P, share)};
    out.materials = {materialFit(params, 0, out.naturalStd[0])};
    return out;
}

// A pool of rounds at kd 0.4 with `factors` times the paths, simulated: each round's
// recordings' noise of variance s / paths, independent, and the image's of variance `image`,
// common to all; each round reports its variance and the recordings' share exactly.
PooledRounds<P> simulatedPool(const std::vector<double>& factors, double image, double s,
                              std::mt19937& rng) {
    std::normal_distribution<double> normal(0, 1);
    const double common = std::sqrt(image) * normal(rng);
    std::optional<PooledRounds<P>> pool;
    for (const double f : factors) {
        ParameterState<P> params = stateAt(material(0.4, 0.3, 100));
        std::vector<double> y = params.naturalCoordinates();
        y[L::diffuse(0)] = 0.4 + common + std::sqrt(s / f) * normal(rng);
        params.setNatural(0, y.data());
        const double variance = image + s / f;
        const PooledRounds<P> own =
            poolOfRound<P>(outcome(params, std::sqrt(variance), (s / f) / variance), params, f);
        pool = pool ? pooled<P>(*pool, own) : own;
    }
    return *pool;
}

TEST(PooledRounds, WeighEachRoundByTheInverseOfItsRecordingsVariance) {
    ParameterState<P> a = stateAt(material(0.4, 0.3, 100)), b = stateAt(material(0.41, 0.29, 102));
    // Within their recordings' noise of each other (chi-square below 1: not widened). Round a:
    // variance 4e-4, 3/4 of it the recordings' (3e-4) and 1e-4 the image's; round b,
    // with three times the paths: 1e-4 of recordings, 1e-4 of image.
    const PooledRounds<P> first = poolOfRound<P>(outcome(a, 0.02, 0.75), a, 4);
    const PooledRounds<P> second = poolOfRound<P>(outcome(b, std::sqrt(2e-4), 0.5), b, 12);
    ASSERT_TRUE(poolable<P>(first, second));
    const PooledRounds<P> pool = pooled<P>(first, second);
    EXPECT_EQ(pool.rounds, 2);
    EXPECT_EQ(pool.pathFactor, 16);
    // Weights 1/3e-4 and 1/1e-4: a quarter and three quarters.
    EXPECT_NEAR(pool.estimate[0][L::diffuse(0)], 0.25 * 0.4 + 0.75 * 0.41, 1e-12);
    EXPECT_NEAR(pool.estimate[0][L::specular(1)], 0.25 * 0.3 + 0.75 * 0.29, 1e-12);
    EXPECT_NEAR(pool.estimate[0][L::kLogN], 0.25 * std::log(100.0) + 0.75 * std::log(102.0), 1e-12);
    // The recordings' variance: 1 / (1/3e-4 + 1/1e-4) = 7.5e-5; the image's, of the round with
    // the most paths.
    EXPECT_NEAR(pool.pathVariance[0][0], 7.5e-5, 1e-15);
    EXPECT_NEAR(pool.imageVariance[0][0], 1e-4, 1e-15);
    EXPECT_EQ(pool.imagePathFactor, 12);

    RoundOutcome out = outcome(b, std::sqrt(2e-4), 0.5);
    adoptPool<P>(pool, b, out);
    EXPECT_NEAR(out.naturalStd[0][0], std::sqrt(1.75e-4), 1e-12);
    EXPECT_NEAR(out.pathShare[0][0], 7.5e-5 / 1.75e-4, 1e-12);
    EXPECT_NEAR(out.materials[0].kd[1], 0.4075, 1e-9);
    EXPECT_NEAR(out.materials[0].n, std::exp(0.25 * std::log(100.0) + 0.75 * std::log(102.0)),
                1e-9);
    EXPECT_NEAR(out.materials[0].kdStd[2], std::sqrt(1.75e-4), 1e-12);
    EXPECT_NEAR(b.natural(0)[L::specular(2)], 0.2925, 1e-12);
}

// The image noise's standard error for ks of a pool of a round whose model gave `first`, at
// `firstFactor` times the paths, joined by one that gave `second` at `secondFactor`.
double pooledImageNoise(double first, double firstFactor, double second, double secondFactor) {
    const ParameterState<P> params = stateAt(material(0.4, 0.3, 100));
    const auto round = [&](double ksImage, double factor) {
        RoundOutcome out = outcome(params, 0.01, 0.5);
        out.materials[0].ksImageStd = Color3::Constant(ksImage);
        return poolOfRound<P>(out, params, factor);
    };
    return pooled<P>(round(first, firstFactor), round(second, secondFactor))
        .imageNoise[0]
        .ksImageStd[0];
}

TEST(PooledRounds, TheImageNoiseIsTheLargestOfRoundsWithComparablePaths) {
    // Within kImageNoisePathRatio of each other: the larger reading, whichever came first.
    EXPECT_EQ(pooledImageNoise(0.002, 16, 0, 32), 0.002);
    EXPECT_EQ(pooledImageNoise(0, 16, 0.002, 8), 0.002);
    // A round of the first round's paths read its noise where its recordings barely resolved
    // the estimate: one of 15 times as many stands alone, joining it or joined by it.
    EXPECT_EQ(pooledImageNoise(0.01, 1, 0, 15), 0);
    EXPECT_EQ(pooledImageNoise(0.001, 16, 0.01, 2), 0.001);
}

TEST(PooledRounds, AreNotPooledAcrossHeldParametersOrWithoutTheRecordingsShare) {
    ParameterState<P> a = stateAt(material(0.4, 0.3, 100)), b = stateAt(material(0.4, 0.3, 100));
    const PooledRounds<P> first = poolOfRound<P>(outcome(a, 0.01, 0.5), a, 1);
    ASSERT_TRUE(poolable<P>(first, poolOfRound<P>(outcome(b, 0.01, 0.5), b, 1)));
    // No split measured (no precision target): nothing to weigh by.
    EXPECT_FALSE(poolable<P>(first, poolOfRound<P>(outcome(b, 0.01, 0), b, 1)));
    b.hold({L::kLogN});
    EXPECT_FALSE(poolable<P>(first, poolOfRound<P>(outcome(b, 0.01, 0.5), b, 1)));
    EXPECT_FALSE(poolable<P>(PooledRounds<P>{}, first));
}

// Rounds of 1, 4 and 11 times the paths: recordings' noise of variance s / paths each,
// independent, and the image's noise common to all. The pool's estimate scatters about the truth
// by its reported standard error, sqrt(image + pooled recordings' variance).
TEST(PooledRounds, ThePoolsStandardErrorIsItsEstimatesScatter) {
    const double image = 0.01 * 0.01, s = 0.05 * 0.05;
    const std::vector<double> factors = {1, 4, 11};
    std::mt19937 rng(5);
    const int draws = 20000;
    double squares = 0, reported = 0;
    for (int d = 0; d < draws; ++d) {
        const PooledRounds<P> pool = simulatedPool(factors, image, s, rng);
        squares += std::pow(pool.estimate[0][L::diffuse(0)] - 0.4, 2) / draws;
        reported +=
            (pool.pathVariance[0][L::diffuse(0)] + pool.imageVariance[0][L::diffuse(0)]) / draws;
    }
    EXPECT_NEAR(reported, image + s / 16, 1e-12);
    // The mean of 20000 squared normals is within 3% of its expectation (4 sigma: 2 / 20000
    // relative variance).
    EXPECT_NEAR(squares / reported, 1, 0.04);
}

// Rounds that disagree by more than their recordings' noise: kd 0.4 and 0.44 with recordings'
// variances 3e-4 and 1e-4 are 0.04 apart, chi-square 1.6e-3 / 4e-4 = 4 on one degree of freedom.
// The pooled recordings' variance 7.5e-5 is widened four times (Birge) before the image's 1e-4 is
// added; parameters that agree (ks, n) are not widened.
TEST(PooledRounds, RoundsThatDisagreeByMoreThanTheirNoiseWidenThePool) {
    ParameterState<P> a = stateAt(material(0.4, 0.3, 100)), b = stateAt(material(0.44, 0.3, 100));
    const PooledRounds<P> pool = pooled<P>(poolOfRound<P>(outcome(a, 0.02, 0.75), a, 4),
                                           poolOfRound<P>(outcome(b, std::sqrt(2e-4), 0.5), b, 12));
    EXPECT_NEAR(pool.chiSquare[0][L::diffuse(0)], 4, 1e-9);
    EXPECT_EQ(pool.chiSquare[0][L::specular(0)], 0);
    RoundOutcome out = outcome(b, std::sqrt(2e-4), 0.5);
    adoptPool<P>(pool, b, out);
    EXPECT_NEAR(out.naturalStd[0][L::diffuse(0)], std::sqrt(4 * 7.5e-5 + 1e-4), 1e-12);
    EXPECT_NEAR(out.pathShare[0][L::diffuse(0)], 3e-4 / 4e-4, 1e-9);
    EXPECT_NEAR(out.naturalStd[0][L::specular(0)], std::sqrt(1.75e-4), 1e-12);
}

// A move between a pool and a round is judged against the round's standard error and the pool's
// recordings' noise: the image's, common to both, once.
TEST(PooledRounds, TheMoveToJoinIsJudgedByTheRoundsNoiseAndThePoolsRecordings) {
    ParameterState<P> a = stateAt(material(0.4, 0.3, 100)), b = stateAt(material(0.4, 0.3, 100));
    const PooledRounds<P> pool = poolOfRound<P>(outcome(a, 0.1, 0.5), a, 16);
    const PooledRounds<P> round = poolOfRound<P>(outcome(b, 0.4, 0.25), b, 1);
    const auto noise = poolingNoise<P>(pool, round);
    for (int i = 0; i < P; ++i)
        EXPECT_NEAR(noise[0][std::size_t(i)], std::sqrt(0.16 + 0.005), 1e-12);
}

// Rounds are pooled only where each resolves every free parameter to kPoolableStd: an estimate
// whose standard errors change with where it is (n +- 60% on a climb) is not averaged with others.
TEST(PooledRounds, AreNotPooledWhereTheyResolveTheirParametersPoorly) {
    ParameterState<P> a = stateAt(material(0.4, 0.3, 100)), b = stateAt(material(0.4, 0.3, 100));
    const PooledRounds<P> precise = poolOfRound<P>(outcome(a, 0.01, 0.5), a, 4);
    EXPECT_TRUE(preciseEnoughToPool<P>(precise));
    EXPECT_TRUE(poolable<P>(precise, poolOfRound<P>(outcome(b, 0.02, 0.5), b, 4)));
    // log n +- 0.6 (and kd, ks +- 0.6 too).
    const PooledRounds<P> coarse = poolOfRound<P>(outcome(b, 0.6, 0.5), b, 4);
    EXPECT_FALSE(preciseEnoughToPool<P>(coarse));
    EXPECT_FALSE(poolable<P>(precise, coarse));
    EXPECT_FALSE(poolable<P>(coarse, precise));
}

// The chi-square of rounds whose recordings' noise is as reported, with the image's common to
// them, has its rounds - 1 degrees of freedom as its mean: rounds at one point are not widened
// on average by more than Birge's max(1, chi-square / (rounds - 1)) allows by chance.
TEST(PooledRounds, TheChiSquareOfRoundsAtOnePointHasItsDegreesOfFreedom) {
    const double image = 0.01 * 0.01, s = 0.05 * 0.05;
    std::mt19937 rng(7);
    for (const std::vector<double>& factors :
         {std::vector<double>{1, 3}, std::vector<double>{16, 16, 9},
          std::vector<double>{1, 2, 4, 8}}) {
        const int draws = 20000;
        double chiSquare = 0;
        for (int d = 0; d < draws; ++d)
            chiSquare += simulatedPool(factors, image, s, rng).chiSquare[0][L::diffuse(0)] / draws;
        // The mean of 20000 chi-squares with k - 1 degrees of freedom: relative standard
        // deviation sqrt(2 / ((k - 1) 20000)), at most 1%; 4% is 4 of those.
        EXPECT_NEAR(chiSquare / double(factors.size() - 1), 1, 0.04) << factors.size() << " rounds";
    }
}

// The next round at a pool records the paths the pool lacks (the plan's growth less the pool),
// bounded below by the first round's and a quarter of the pool's, above by the pool's own or
// 16 times the first round's, whichever is more.
TEST(PooledRounds, TheNextRoundRecordsOnlyThePathsThePoolLacks) {
    EXPECT_DOUBLE_EQ(pathsThePoolLacks(4, 2), 4);       // the plan asks for the pool again
    EXPECT_DOUBLE_EQ(pathsThePoolLacks(4, 3.5), 10);    // 14 asked, 4 held
    EXPECT_DOUBLE_EQ(pathsThePoolLacks(4, 10), 16);     // at most 16x the first round's
    EXPECT_DOUBLE_EQ(pathsThePoolLacks(32, 10), 32);    // or the pool's, if more
    EXPECT_DOUBLE_EQ(pathsThePoolLacks(32, 1.1), 8);    // at least a quarter of the pool's
    EXPECT_DOUBLE_EQ(pathsThePoolLacks(2, 1.1), 1);     // and at least the first round's
    EXPECT_DOUBLE_EQ(pathsThePoolLacks(64, 1.25), 16);  // 80 asked, 64 held
}

}  // namespace
}  // namespace phongfit
