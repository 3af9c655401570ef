// FitOptions::timeBudget in the rounds: how many paths the next round may record so that it ends
// within the budget (docs/design/fitter.md, "A time budget").
#pragma once

namespace phongfit {

// The share of the time left that a round shrunk to the budget is planned to take: a round's time
// is about proportional to its paths (less, for its fixed part), and one planned to end exactly at
// the budget would be cut short by rounding.
inline constexpr double kBudgetShare = 0.9;

// `growth` of the next round's paths against the last round's, capped so that, at `roundSeconds`
// for the last round's paths, the round ends within `budget` seconds (kBudgetShare of the time left
// after `elapsed`), but never below 1. No budget (<= 0): `growth`.
double withinTimeBudget(double budget, double elapsed, double roundSeconds, double growth);

struct BudgetedRound {
    double growth = 1;  // of the round's paths against the last round's
    bool starts = true;
};

// The next round, as it is about to start (the one place the budget applies): one grown past what
// ends within the budget (growth > 1, `shrinkable`) shrinks to withinTimeBudget's growth; one that
// still cannot end within the budget (at its growth, or at the last round's paths) does not start.
BudgetedRound budgetedRound(double budget, double elapsed, double lastRoundSeconds, double growth,
                            bool shrinkable);

}  // namespace phongfit
