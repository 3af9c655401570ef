// Standard errors are raised to the scatter of the last rounds' estimates, computed by hand here.
#include "round_scatter.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <tuple>

#include "material_params.h"

namespace phongfit {
namespace {

// E sqrt(q) / sigma for q a variance estimate with `dof` degrees of freedom (chi-square).
double c4(double dof) {
    return std::sqrt(2 / dof) * std::tgamma((dof + 1) / 2) / std::tgamma(dof / 2);
}

FitRound roundAt(double kd, double ks, double n) {
    FitRound r;
    MaterialFit m;
    m.kd = Color3::Constant(kd);
    m.ks = Color3::Constant(ks);
    m.n = n;
    r.materials.push_back(m);
    return r;
}

// Six rounds: 0 and 1 travel (ignored); 2 to 5 alternate ks 0.25, 0.254 and n 1000, 1100, with
// kd steady. Successive differences 0.004 and log(1.1) three times: scatter 0.004 / sqrt(2) and
// n log(1.1) / sqrt(2), over c4 of 4 estimates' 2 * 3^2 / 8 degrees of freedom. The sandwich's
// smaller errors are raised, a larger one kept, a held parameter (0) left alone.
TEST(RoundScatter, RaisesStandardErrorsToTheLastRoundsScatter) {
    FitResult result;
    result.rounds = {roundAt(0.1, 0.9, 5),     roundAt(0.5, 0.3, 800),
                     roundAt(0.6, 0.25, 1000), roundAt(0.6, 0.254, 1100),
                     roundAt(0.6, 0.25, 1000), roundAt(0.6, 0.254, 1100)};
    MaterialFit last = result.rounds.back().materials[0];
    last.kdStd = Color3(1e-4, 1e-4, 0);
    last.ksStd = Color3(1e-5, 0.01, 1e-5);
    last.nStd = 3;
    result.materials = {last};
    widenToRoundScatter(result);
    const MaterialFit& m = result.materials[0];
    EXPECT_EQ(m.kdStd[0], 1e-4);
    EXPECT_EQ(m.kdStd[2], 0);
    const double unbiased = 1 / c4(2.25);
    EXPECT_NEAR(unbiased, 1.1141, 1e-4);
    EXPECT_NEAR(m.ksStd[0], 0.004 / std::sqrt(2.0) * unbiased, 1e-12);
    EXPECT_EQ(m.ksStd[1], 0.01);
    EXPECT_NEAR(m.nStd, 1100 * std::log(1.1) / std::sqrt(2.0) * unbiased, 1e-9);
}

// Fewer estimates than a full window: sqrt(mean squared successive difference / 2), over c4 of
// their 2 (k - 1)^2 / (3 k - 4) degrees of freedom (three: 8 / 5).
TEST(RoundScatter, FewerEstimatesTakeTheMeanSquaredDifference) {
    const std::vector<FitRound> rounds = {roundAt(0.1, 0.9, 5), roundAt(0.5, 0.3, 800),
                                          roundAt(0.6, 0.25, 1000), roundAt(0.6, 0.254, 1100),
                                          roundAt(0.6, 0.25, 1000)};
    const std::vector<MaterialScatter> s = roundScatter(rounds);
    ASSERT_EQ(s.size(), 1u);
    const double unbiased = 1 / c4(1.6);
    EXPECT_NEAR(s[0].ks[0], 0.004 / std::sqrt(2.0) * unbiased, 1e-12);
    EXPECT_NEAR(s[0].logN, std::log(1.1) / std::sqrt(2.0) * unbiased, 1e-12);
}

// Round 2 still at the state the first rounds could not tell from the estimate (session 35's
// 0056: n 254, then 2562, 2927, 2923 for 3000): its move, 24 times the rms of the others, is
// travel, and the scatter is the last three estimates'. With it the scatter said n +- 7234. A
// move 8 times the others' or less stays, and so does one where the others are exactly 0.
TEST(RoundScatter, AFullWindowLeavesOutAFirstMoveThatTravelled) {
    FitResult result;
    result.rounds = {roundAt(0.42, 0.54, 236), roundAt(0.45, 0.49, 247), roundAt(0.46, 0.49, 254),
                     roundAt(0.45, 0.5, 2562), roundAt(0.45, 0.5, 2927), roundAt(0.45, 0.5, 2923)};
    result.materials = {result.rounds.back().materials[0]};
    result.materials[0].nStd = 40.9;
    widenToRoundScatter(result);
    const double last3 =
        std::sqrt(
            (std::pow(std::log(2927.0 / 2562.0), 2) + std::pow(std::log(2923.0 / 2927.0), 2)) / 4) /
        c4(1.6);
    EXPECT_NEAR(result.materials[0].nStd, 2923 * last3, 1e-9);
    EXPECT_LT(result.materials[0].nStd, 0.15 * 2923);

    const auto logNScatter = [](std::vector<double> n) {
        std::vector<FitRound> rounds = {roundAt(0.5, 0.5, 1), roundAt(0.5, 0.5, 1)};
        for (double x : n) rounds.push_back(roundAt(0.5, 0.5, x));
        return roundScatter(rounds)[0].logN;
    };
    const double e = std::exp(1.0);
    // Moves 7.9, 1, -1 (rms 1): all four count.
    EXPECT_NEAR(logNScatter({1, std::pow(e, 7.9), std::pow(e, 8.9), std::pow(e, 7.9)}),
                std::sqrt((7.9 * 7.9 + 2) / 6) / c4(2.25), 1e-9);
    EXPECT_NEAR(logNScatter({1, std::pow(e, 8.1), std::pow(e, 9.1), std::pow(e, 8.1)}),
                std::sqrt(2.0 / 4) / c4(1.6), 1e-9);
    EXPECT_NEAR(logNScatter({1, 1000, 1000, 1000}), std::log(1000.0) / std::sqrt(6) / c4(2.25),
                1e-9);
}

// Near unbiased for the standard deviation of independent estimates: the mean scatter of log n
// over 200000 draws of normal estimates (sigma 0.1; its standard error 0.1%). A full window
// (first moves left out as travel 1.2% of the time) within 0.5%; three estimates' c4, whose
// degrees of freedom are von Neumann's approximation, is 1% high (wide).
TEST(RoundScatter, IsUnbiasedForIndependentEstimates) {
    std::mt19937_64 rng(7);
    std::normal_distribution<double> normal(0, 0.1);
    for (const auto& [estimates, bias, within] :
         {std::tuple{kScatterRounds, 0.0, 0.0005}, std::tuple{3, 0.001, 0.0005}}) {
        double sum = 0;
        constexpr int kDraws = 200000;
        for (int d = 0; d < kDraws; ++d) {
            std::vector<FitRound> rounds = {roundAt(0.5, 0.5, 100), roundAt(0.5, 0.5, 100)};
            for (int k = 0; k < estimates; ++k)
                rounds.push_back(roundAt(0.5, 0.5, 100 * std::exp(normal(rng))));
            sum += roundScatter(rounds)[0].logN;
        }
        EXPECT_NEAR(sum / kDraws, 0.1 + bias, within) << estimates << " estimates";
    }
}

// The scatter needs two estimates from round 2 on, and only the last kScatterRounds count.
TEST(RoundScatter, NeedsTwoSettledRoundsAndLooksAtTheLastFew) {
    FitResult result;
    result.rounds = {roundAt(0.1, 0.9, 5), roundAt(0.5, 0.3, 800), roundAt(0.6, 0.25, 1000)};
    MaterialFit last = result.rounds.back().materials[0];
    last.kdStd = last.ksStd = Color3::Constant(1e-5);
    last.nStd = 1;
    result.materials = {last};
    widenToRoundScatter(result);
    EXPECT_EQ(result.materials[0].ksStd[0], 1e-5);
    EXPECT_EQ(result.materials[0].nStd, 1);

    // Round 2 far off, then kScatterRounds steady rounds: only the steady ones count.
    result.rounds.back() = roundAt(0.9, 0.05, 10);
    for (int i = 0; i < kScatterRounds; ++i) result.rounds.push_back(roundAt(0.6, 0.25, 1000));
    result.materials = {result.rounds.back().materials[0]};
    result.materials[0].ksStd = Color3::Constant(1e-5);
    result.materials[0].nStd = 1;
    widenToRoundScatter(result);
    EXPECT_EQ(result.materials[0].ksStd[0], 1e-5);
    EXPECT_EQ(result.materials[0].nStd, 1);
}

// A sharper probe's round (fewer paths, a start 4x away) is not the recordings' scatter.
TEST(RoundScatter, LeavesSharperProbesOut) {
    std::vector<FitRound> rounds = {roundAt(0.1, 0.9, 5), roundAt(0.5, 0.3, 800),
                                    roundAt(0.6, 0.25, 1000), roundAt(0.6, 0.25, 1000),
                                    roundAt(0.6, 0.3, 4000)};
    rounds.back().probe = true;
    const std::vector<MaterialScatter> s = roundScatter(rounds);
    ASSERT_EQ(s.size(), 1u);
    EXPECT_EQ(s[0].ks[0], 0);
    EXPECT_EQ(s[0].logN, 0);
}

// The lobe test asks during the last round, before it joins the list: its estimate comes last.
// Two estimates: one degree of freedom, E |d| / sqrt(2) = sqrt(2 / pi) sigma.
TEST(RoundScatter, TakesTheRoundUnderWayAsTheLatestEstimate) {
    const std::vector<FitRound> rounds = {roundAt(0.1, 0.9, 5), roundAt(0.5, 0.3, 800),
                                          roundAt(0.6, 2e-7, 1000)};
    EXPECT_TRUE(roundScatter(rounds).empty());
    const std::vector<MaterialFit> latest = roundAt(0.6, 6e-7, 1000).materials;
    const std::vector<MaterialScatter> s = roundScatter(rounds, &latest);
    ASSERT_EQ(s.size(), 1u);
    EXPECT_NEAR(s[0].ks[1], 4e-7 / std::sqrt(2.0) / std::sqrt(2 / M_PI), 1e-18);
    EXPECT_EQ(s[0].kd[0], 0);
    EXPECT_EQ(s[0].logN, 0);
}

FitResult history(const std::vector<double>& n, double nStd) {
    FitResult result;
    for (double x : n) result.rounds.push_back(roundAt(0.6, 0.25, x));
    result.materials = {result.rounds.back().materials[0]};
    result.materials[0].nStd = nStd;
    result.materials[0].kdStd = Color3::Constant(1e-3);
    return result;
}

// A fit that stopped while moving: a climb whose moves do not shrink in n (the 40-degree sphere at
// n 30000: 857, 2036, 8743, 11000, 15240, 17070) may go on as far as it went; one that converges
// geometrically (moves 200, 65, 4.5, 0.4: rho 0.126) has the last move left at least; a swing
// back has the last move. n is judged in log n too: a climb by steady factors may go on by the
// factor it went, within n's range; one that went 2x or more (the 40-degree sphere at 128 x 128:
// 275, 533, 1299, 2269, 5736, still 5.2x short; a Cornell box under a 30-degree light, n 165106:
// 1151, 1470, 1651, 2658) has shown no end, and reaches the bound. Steady kd keeps its standard
// error; probe rounds do not count.
TEST(RoundDrift, RaisesStandardErrorsToHowFarTheEstimateMayStillGo) {
    FitResult climb = history({857, 2036, 8743, 11000, 15240, 17070}, 2890);
    widenToDrift(climb);
    EXPECT_DOUBLE_EQ(climb.materials[0].nStd, 17070 - 857);
    EXPECT_EQ(climb.materials[0].kdStd[0], 1e-3);

    FitResult factors = history({100, 120, 150}, 1);
    widenToDrift(factors);
    EXPECT_NEAR(factors.materials[0].nStd, 150 * (150.0 / 100 - 1), 1e-9);
    FitResult unended = history({275.4, 533.2, 1299, 2269, 5736}, 5461);
    widenToDrift(unended);
    EXPECT_DOUBLE_EQ(unended.materials[0].nStd, kMaxExponent - 5736);
    FitResult cornell = history({1424, 1257, 1151, 1470, 1651, 2658}, 3480);
    widenToDrift(cornell);
    EXPECT_DOUBLE_EQ(cornell.materials[0].nStd, kMaxExponent - 2658);

    // Moves down: log n's drift reaches n (1 - e^-d), less than the last move here.
    FitResult converging = history({300, 100, 35, 30.5, 30.1}, 0.1);
    widenToDrift(converging);
    EXPECT_NEAR(converging.materials[0].nStd, 0.4, 1e-12);

    // Moves 4, 2, 1 (rho 0.5): one more move of 1 is left, in log n one more of its factor
    // 107 / 106 with its own rho; a standard error above both stays.
    FitResult halving = history({100, 104, 106, 107}, 0.5);
    widenToDrift(halving);
    const double last = std::log(107.0 / 106), rho = std::sqrt(last / std::log(1.04));
    EXPECT_NEAR(halving.materials[0].nStd, 107 * std::expm1(std::max(last, last * rho / (1 - rho))),
                1e-9);
    EXPECT_GT(halving.materials[0].nStd, 1);
    halving.materials[0].nStd = 3;
    widenToDrift(halving);
    EXPECT_EQ(halving.materials[0].nStd, 3);

    FitResult swing = history({1000, 1100, 1000, 1100}, 10);
    widenToDrift(swing);
    EXPECT_NEAR(swing.materials[0].nStd, 110, 1e-9);

    FitResult probed = history({1000, 1100, 5000, 1200}, 10);
    probed.rounds[2].probe = true;
    widenToDrift(probed);
    EXPECT_NEAR(probed.materials[0].nStd, 1200 * (1200.0 / 1000 - 1), 1e-9);

    // A round that kept its start exactly does not end the run: the Cornell box under the
    // 40-degree light (n 30000, ks 0.5) climbed 537, 875, 7985, 9232, 9232, 9833 and reported
    // 9833 +- 651, the last move alone, 31 of those from the truth.
    FitResult stalled = history({537, 875, 7985, 9231.7, 9231.7, 9832.7}, 651);
    widenToDrift(stalled);
    EXPECT_DOUBLE_EQ(stalled.materials[0].nStd, 9832.7 - 537);

    FitResult held = history({857, 2036, 8743}, 0);
    widenToDrift(held);
    EXPECT_EQ(held.materials[0].nStd, 0);
}

}  // namespace
}  // namespace phongfit
