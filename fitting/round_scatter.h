// Standard errors no smaller than the rounds show. Each round re-records its paths independently,
// so the last rounds' estimates scatter by the recordings' noise; where a few pixels carry a
// parameter (a highlight smaller than a pixel), the per-pixel sandwich misses that noise and its
// standard errors came out 10-300x smaller than the scatter. docs/design/fitter.md.
#pragma once

#include "fitter.h"

namespace phongfit {

// Raises each free parameter's standard error in `result.materials` to the scatter of the last
// kScatterRounds estimates of rounds from the third on (rounds 0 and 1 are still travelling from
// the start), sqrt(mean of squared successive differences / 2), when there are at least two. n's
// scatter is taken in log n. Held and unconstrained parameters (standard error 0) are left alone.
void widenToRoundScatter(FitResult& result);

inline constexpr int kScatterRounds = 4;

}  // namespace phongfit
