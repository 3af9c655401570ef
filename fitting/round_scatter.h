// Standard errors no smaller than the rounds show. Each round re-records its paths independently,
// so the last rounds' estimates scatter by the recordings' noise; where a few pixels carry a
// parameter (a highlight smaller than a pixel), the per-pixel sandwich misses that noise and its
// standard errors came out 10-300x smaller than the scatter. docs/design/fitter.md.
#pragma once

#include "fitter.h"

namespace phongfit {

inline constexpr int kScatterRounds = 4;

// Per material: the scatter of kd and ks per channel and of log n over the last kScatterRounds
// estimates of rounds from the third on (rounds 0 and 1 are still travelling from the start),
// sqrt(mean of squared successive differences / 2) made unbiased for their few degrees of
// freedom (c4), a full window's first estimate left out where its move is travel (8 times the
// rms of the others' moves or more: a round still at the start's state); the estimates are
// `rounds`' but the sharper probes' (fewer paths, from a start away from the estimate) and then,
// if given, `latest`'s. Empty when there are fewer than two.
struct MaterialScatter {
    Color3 kd = Color3::Zero(), ks = Color3::Zero();
    double logN = 0;
};
std::vector<MaterialScatter> roundScatter(const std::vector<FitRound>& rounds,
                                          const std::vector<MaterialFit>* latest = nullptr);

// Raises each free parameter's standard error in `result.materials` to roundScatter of its
// rounds (n: n times the scatter of log n). Held and unconstrained parameters (standard error 0)
// are left alone.
void widenToRoundScatter(FitResult& result);

// For a fit that stopped while its estimate still moved, which has not shown where it stops:
// raises each free parameter's standard error in `result.materials` to how far its estimate may
// still go, judged from the last rounds that moved it the same way (sharper probes left out): the
// rest of a geometric series of their moves, the whole way they went where the moves do not
// shrink, at least the last move. n's drift is the farther of that in n and in log n (a climb's
// moves can shrink in one and not the other), within n's range; the bound where a climb that at
// least doubled n does not slow in log n.
void widenToDrift(FitResult& result);

}  // namespace phongfit
