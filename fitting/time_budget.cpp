#include "time_budget.h"

#include <algorithm>

namespace phongfit {

double withinTimeBudget(double budget, double elapsed, double roundSeconds, double growth) {
    if (budget <= 0) return growth;
    return std::clamp(kBudgetShare * (budget - elapsed) / roundSeconds, 1.0, growth);
}

BudgetedRound budgetedRound(double budget, double elapsed, double lastRoundSeconds, double growth,
                            bool shrinkable) {
    if (budget <= 0) return {growth, true};
    if (shrinkable && growth > 1)
        growth = withinTimeBudget(budget, elapsed, lastRoundSeconds, growth);
    return {growth, elapsed + growth * lastRoundSeconds <= budget};
}

}  // namespace phongfit
