#include "lost_lobe.h"

#include <gtest/gtest.h>

#include "identifiability.h"

namespace phongfit {
namespace {

MaterialFit lobe(double ks, double ksStd, double n, std::vector<std::string> unconstrained = {}) {
    MaterialFit m;
    m.kd = Color3::Constant(0.8);
    m.ks = Color3::Constant(ks);
    m.ksStd = Color3::Constant(ksStd);
    m.n = n;
    m.nStd = n / 4;
    m.unconstrained = std::move(unconstrained);
    return m;
}

TEST(LostLobe, ALobeShownIsOneResolvedWithKsAtThreeStandardErrors) {
    EXPECT_TRUE(showsLobe(lobe(0.1, 0.016, 51)));
    EXPECT_FALSE(showsLobe(lobe(0.1, 0.1 / kLobeConfirmation * 1.01, 51)));
    EXPECT_FALSE(showsLobe(lobe(0.1, 0.016, 51, {"n"})));  // n held: no lobe shape resolved
    EXPECT_FALSE(showsLobe(lobe(0.3, 0, 51, {"ks", "n"})));
    MaterialFit green = lobe(0.01, 0.01, 51);  // one channel's lobe is enough
    green.ks[1] = 0.1;
    EXPECT_TRUE(showsLobe(green));
}

// Lost: shown the round before, then ks (or a channel of it) and n both unconstrained. An n held
// alone (no lobe at this round's estimate, ks free) is the rounds' own test of ks, not a loss.
TEST(LostLobe, IsALobeShownThenHeldWithItsKs) {
    const std::vector<MaterialFit> before = {lobe(0.1, 0.016, 51), lobe(0.001, 0.01, 30)};
    EXPECT_EQ(lostLobes(before, {lobe(0.3, 0, 1e6, {"ks", "n"}), lobe(0.3, 0, 1e6, {"ks", "n"})}),
              std::vector<int>{0});
    EXPECT_EQ(lostLobes(before, {lobe(0.3, 0, 1e6, {"ks.g", "n"}), lobe(0.1, 0.01, 30)}),
              std::vector<int>{0});
    EXPECT_TRUE(lostLobes(before, {lobe(0.1, 0.01, 1.4, {"n"}), lobe(0.1, 0.01, 30)}).empty());
    EXPECT_TRUE(lostLobes(before, {lobe(0.12, 0.01, 60), lobe(0.1, 0.01, 30)}).empty());
}

}  // namespace
}  // namespace phongfit
