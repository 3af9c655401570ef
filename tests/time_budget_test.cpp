// The rounds under a time budget (time_budget.h): growth capped to what ends within the time left,
// worked out by hand, and the round about to start shrunk rather than cut.
#include "time_budget.h"

#include <gtest/gtest.h>

namespace phongfit {
namespace {

TEST(TimeBudget, GrowthEndsWithinTheShareOfTheTimeLeftAndNeverBelowOne) {
    // 2.72 s left, 0.19 s a round at the last paths: 0.9 * 2.72 / 0.19 = 12.88x.
    EXPECT_DOUBLE_EQ(withinTimeBudget(3, 0.28, 0.19, 16), 0.9 * 2.72 / 0.19);
    EXPECT_DOUBLE_EQ(withinTimeBudget(3, 0.28, 0.19, 4), 4);   // fits as asked
    EXPECT_DOUBLE_EQ(withinTimeBudget(3, 2.9, 0.19, 16), 1);   // never fewer than the last paths
    EXPECT_DOUBLE_EQ(withinTimeBudget(3, 3.5, 0.19, 16), 1);   // past the budget
    EXPECT_DOUBLE_EQ(withinTimeBudget(0, 100, 0.19, 16), 16);  // no budget
}

// Matrix cell 0128 with --time-budget 3: its 16x round, planned at 0.28 s, was cut at the start
// because the start came a little later; it now starts, shrunk to end within the budget.
TEST(TimeBudget, AGrownRoundShrinksToTheBudgetInsteadOfStoppingTheFit) {
    const BudgetedRound round = budgetedRound(3, 0.30, 0.19, 16, true);
    EXPECT_TRUE(round.starts);
    EXPECT_DOUBLE_EQ(round.growth, 0.9 * 2.70 / 0.19);
    EXPECT_LE(0.30 + round.growth * 0.19, 3);
}

TEST(TimeBudget, ARoundThatCannotEndWithinTheBudgetDoesNotStart) {
    // Even at the last round's paths: 2.9 + 0.19 > 3.
    const BudgetedRound late = budgetedRound(3, 2.9, 0.19, 16, true);
    EXPECT_FALSE(late.starts);
    EXPECT_DOUBLE_EQ(late.growth, 1);
    // A probe round (not shrinkable) is started only as planned.
    const BudgetedRound probe = budgetedRound(3, 0.30, 0.19, 16, false);
    EXPECT_FALSE(probe.starts);
    EXPECT_DOUBLE_EQ(probe.growth, 16);
    EXPECT_TRUE(budgetedRound(3, 0.30, 0.19, 0.5, false).starts);
    // A round that fits as planned is left as it is.
    const BudgetedRound fits = budgetedRound(3, 0.30, 0.19, 4, true);
    EXPECT_TRUE(fits.starts);
    EXPECT_DOUBLE_EQ(fits.growth, 4);
}

TEST(TimeBudget, WithoutABudgetEveryRoundStartsAsPlanned) {
    const BudgetedRound round = budgetedRound(0, 1e6, 100, 16, true);
    EXPECT_TRUE(round.starts);
    EXPECT_DOUBLE_EQ(round.growth, 16);
}

}  // namespace
}  // namespace phongfit
