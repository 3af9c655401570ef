// Where a converged lobe is probed, and when the probe round says it came back.
#include "sharper_probe.h"

#include <gtest/gtest.h>

#include <cmath>

#include "material_params.h"

namespace phongfit {
namespace {

MaterialFit lobe(double n, double nStd) {
    MaterialFit m;
    m.kd = Color3(0.4, 0.3, 0.2);
    m.ks = Color3::Constant(0.5);
    m.n = n;
    m.nStd = nStd;
    return m;
}

// A precise lobe is probed kProbeFactor sharper; an imprecise one by exp(3 standard errors of log
// n); kd and ks stay. A held n, or one within kProbeFactor of kMaxExponent, is not probed: it is
// recorded where the next round would record it (a held n reported where it went broader, 30,
// at its start, 300); with nothing to probe the list is empty.
TEST(SharperProbe, RaisesEachFreeLobeBeyondItsStandardErrors) {
    MaterialFit held = lobe(30, 0);
    held.unconstrained = {"n"};
    const std::vector<MaterialFit> fits{lobe(1000, 10), lobe(1000, 600), held,
                                        lobe(kMaxExponent / 2, 10)};
    std::vector<PhongMaterial> at;
    for (const MaterialFit& m : fits) at.push_back(m.material());
    at[2].n = 300;
    const std::vector<PhongMaterial> p = sharperProbe(fits, at);
    ASSERT_EQ(p.size(), 4u);
    EXPECT_DOUBLE_EQ(p[0].n, 1000 * kProbeFactor);
    EXPECT_DOUBLE_EQ(p[1].n, 1000 * std::exp(3 * 0.6));
    EXPECT_EQ(p[2].n, 300);
    EXPECT_EQ(p[3].n, kMaxExponent / 2);
    EXPECT_TRUE((p[1].kd == lobe(1000, 600).kd).all());
    EXPECT_TRUE((p[1].ks == lobe(1000, 600).ks).all());
    EXPECT_TRUE(sharperProbe({held, fits[3]}, {at[2], at[3]}).empty());
}

// Converged at n 1000 +- 10, probed at 4000: nearer 1000 than 4000 (in log n) is back, nearer
// 4000 is not, unless within 3 of the probe's own standard errors; a probe round that cannot tell
// 1000 from 4000 (3 standard errors of log n at least log 4, or n's at least n) vouches for
// nothing; one that held n saw no lobe there.
TEST(SharperProbe, ComesBackNearerTheConvergedExponentThanTheProbe) {
    const MaterialFit converged = lobe(1000, 10);
    EXPECT_TRUE(probeReturned({converged}, {lobe(1000, 10)}));
    EXPECT_TRUE(probeReturned({converged}, {lobe(1900, 10)}));
    EXPECT_TRUE(probeReturned({converged}, {lobe(550, 10)}));
    EXPECT_FALSE(probeReturned({converged}, {lobe(2100, 10)}));
    EXPECT_FALSE(probeReturned({converged}, {lobe(450, 10)}));
    EXPECT_FALSE(probeReturned({converged}, {lobe(30000, 1000)}));
    // log(2500 / 1000) = 0.92 is within 3 standard errors of 0.4 (1.2 < log 4).
    EXPECT_TRUE(probeReturned({converged}, {lobe(2500, 1000)}));
    // 3 x 0.5 > log 4: the probe stayed near its start, and could not have told.
    EXPECT_FALSE(probeReturned({converged}, {lobe(3500, 1750)}));
    EXPECT_FALSE(probeReturned({converged}, {lobe(1000, 480)}));
    EXPECT_FALSE(probeReturned({converged}, {lobe(1200, 1200)}));
    MaterialFit held = lobe(100, 0);
    held.unconstrained = {"n"};
    EXPECT_TRUE(probeReturned({converged}, {held}));
    // Every probed material must come back.
    EXPECT_FALSE(probeReturned({converged, converged}, {lobe(1000, 10), lobe(5000, 10)}));
}

// A second probe round's paths, where the first could not tell the converged n from its start
// (the Cornell box under a 5-degree light, n 1, ks 0.05: n 1.19 +- 0.125 at 32 times the first
// round's paths, the probe at half of them 6.7 +- 4.4): enough that its predicted standard error of
// log n (the converged round's, as 1 / sqrt(paths)) is kProbeMargin short of what probeReturned
// asks; the most any probed lobe needs. A lobe resolved well enough for kProbePaths, one it would
// take more than kMostProbePaths to resolve (n 9232 +- 3330 at 64x), or a held one, asks for none
// (kProbePaths). The first probe told the converged n from its start where it resolved its n to
// a third of the probe's factor in log n, or held it.
TEST(SharperProbe, ASecondProbeRecordsThePathsToTellARoughLobeFromItsStart) {
    EXPECT_EQ(probePaths({lobe(1000, 10)}, 32), kProbePaths);
    const MaterialFit weak = lobe(1.192, 0.125);
    const double paths = probePaths({weak}, 32);
    EXPECT_GT(paths, kProbePaths);
    EXPECT_LE(paths, kMostProbePaths);
    const double probeStd = 0.125 / 1.192 * std::sqrt(32 / paths);
    EXPECT_NEAR(3 * kProbeMargin * probeStd, std::log(kProbeFactor), 1e-12);
    // An imprecise lobe is probed further (exp(3 x 0.6)), and asked for less than log 4 implies.
    const double further = probePaths({lobe(100, 60)}, 1);
    EXPECT_NEAR(3 * kProbeMargin * 0.6 * std::sqrt(1 / further), 3 * 0.6, 1e-12);
    EXPECT_EQ(probePaths({lobe(9232, 3330)}, 64), kProbePaths);
    MaterialFit held = weak;
    held.unconstrained = {"n"};
    EXPECT_EQ(probePaths({held}, 32), kProbePaths);
    EXPECT_EQ(probePaths({lobe(1000, 10), weak, lobe(9232, 3330)}, 32), paths);
    EXPECT_FALSE(probeTold({weak}, {lobe(6.7, 4.4)}));
    EXPECT_TRUE(probeTold({weak}, {lobe(6.7, 0.5)}));
    EXPECT_TRUE(probeTold({weak}, {held}));
    EXPECT_FALSE(probeTold({lobe(1000, 10), weak}, {lobe(4000, 10), lobe(6.7, 4.4)}));
    // The first probe asks only where n goes, unless it is the last round: no second probe can
    // follow it there.
    EXPECT_EQ(firstProbePaths({weak}, 32, false), kProbePaths);
    EXPECT_EQ(firstProbePaths({weak}, 32, true), paths);
    EXPECT_EQ(firstProbePaths({lobe(1000, 10)}, 32, true), kProbePaths);
}

// A probe that came back past a rough lobe (no probe of at most kMostProbePaths could tell it from
// its start) to a broader one was pulled there by its few paths: the Cornell box under its area
// light at 96 x 96 (n 4475) converged at 379.7 +- 182 in a round of 16 times the first's paths,
// and its probe from 1600 at half the first's came back to 157.8 +- 66. A probe that came back
// sharper, one that held n, or a probe of a lobe a second probe can tell (the same lobe from a
// round at the first's paths, or a precise one) is not pulled.
TEST(SharperProbe, AProbeOfARoughLobeThatCameBackBroaderWasPulledByItsFewPaths) {
    const MaterialFit rough = lobe(379.7, 182);
    EXPECT_TRUE(probeReturned({rough}, {lobe(157.8, 66)}));
    EXPECT_TRUE(pulledBroader({rough}, {lobe(157.8, 66)}, 16));
    EXPECT_FALSE(pulledBroader({rough}, {lobe(500, 100)}, 16));
    MaterialFit held = lobe(100, 0);
    held.unconstrained = {"n"};
    EXPECT_FALSE(pulledBroader({rough}, {held}, 16));
    EXPECT_FALSE(pulledBroader({rough}, {lobe(157.8, 66)}, 1));
    EXPECT_FALSE(pulledBroader({lobe(1000, 10)}, {lobe(550, 10)}, 32));
    EXPECT_TRUE(pulledBroader({lobe(1000, 10), rough}, {lobe(1200, 10), lobe(157.8, 66)}, 16));
}

// A probe from 6000 left in the last round at n 5000 +- 1000 widens the converged n 1500 +- 100
// to reach 8000; one that cannot tell 1500 from its start widens it to reach the start, and as far
// as 3 of its own standard errors beyond where it went (the Cornell box under the 40-degree light,
// n 30000, ks 0.05: converged at 2200 +- 529, the probe from 8800 went to 12777 +- 10740, and the
// start alone, 2200 +- 6599, left the truth 4.2 of those away); one that went past the converged
// n to a broader lobe widens it to reach the start too; one that told them apart and went on
// sharper than its start, to the bound; a probe that held n, or a lobe not probed, leaves it.
TEST(SharperProbe, WidensTheConvergedExponentToWhatTheProbeDidNotRuleOut) {
    MaterialFit held = lobe(100, 0);
    held.unconstrained = {"n"};
    MaterialFit notProbed = lobe(300, 0);
    notProbed.unconstrained = {"n"};
    std::vector<MaterialFit> converged = {lobe(1500, 100), lobe(1500, 100), lobe(1500, 100),
                                          notProbed};
    widenToProbe(converged, {lobe(5000, 1000), lobe(6000, 6000), held, lobe(6000, 1000)});
    EXPECT_DOUBLE_EQ(converged[0].nStd, 5000 - 1500 + 3 * 1000);
    EXPECT_DOUBLE_EQ(converged[1].nStd, 6000 - 1500 + 3 * 6000);
    std::vector<MaterialFit> cornell = {lobe(2200, 529), lobe(2200, 529)};
    widenToProbe(cornell, {lobe(12777, 10740), lobe(2300, 2000)});
    EXPECT_DOUBLE_EQ(cornell[0].nStd, 12777 - 2200 + 3 * 10740);
    EXPECT_DOUBLE_EQ(cornell[1].nStd, 2200 * (kProbeFactor - 1));  // the start reaches further
    // The quad light at n 1e6: the probe from 985304 told 246326 +- 99744 from its start but went
    // past it, to 53294 +- 13746; its start stands.
    std::vector<MaterialFit> quad = {lobe(246326, 99744)};
    widenToProbe(quad, {lobe(53294, 13746)});
    EXPECT_DOUBLE_EQ(quad[0].nStd, 246326 * (kProbeFactor - 1));
    // A Cornell box under a 15-degree light, n 46924: converged at 743 +- 558, the probe from
    // 7080 went on to 7743 +- 1163; and one that stayed at its start.
    std::vector<MaterialFit> sharper = {lobe(743, 558), lobe(1500, 100)};
    widenToProbe(sharper, {lobe(7743, 1163), lobe(6000, 1000)});
    EXPECT_DOUBLE_EQ(sharper[0].nStd, kMaxExponent - 743);
    EXPECT_DOUBLE_EQ(sharper[1].nStd, kMaxExponent - 1500);
    EXPECT_EQ(converged[2].nStd, 100);
    EXPECT_EQ(converged[3].nStd, 0);
    EXPECT_EQ(converged[0].n, 1500);
}

// A lobe within kProbeFactor of kMaxExponent, never probed (issue 12's quad light at n 1e6 ended
// at 473673 +- 82400, 6.4 standard errors short): its n reaches the bound. One a probe can reach,
// a held n and one already as wide keep theirs.
TEST(SharperProbe, ALobeTooNearTheBoundToProbeReachesIt) {
    MaterialFit held = lobe(5e5, 0);
    held.unconstrained = {"n"};
    std::vector<MaterialFit> fits{lobe(473673, 82400), lobe(kMaxExponent / kProbeFactor, 100), held,
                                  lobe(8e5, 5e5), lobe(kMaxExponent, 10)};
    widenToBound(fits);
    EXPECT_DOUBLE_EQ(fits[0].nStd, kMaxExponent - 473673);
    EXPECT_EQ(fits[1].nStd, 100);
    EXPECT_EQ(fits[2].nStd, 0);
    EXPECT_EQ(fits[3].nStd, 5e5);
    EXPECT_EQ(fits[4].nStd, 10);
    EXPECT_EQ(fits[0].n, 473673);
}

}  // namespace
}  // namespace phongfit
