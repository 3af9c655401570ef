// Where the next round's paths should go: per pixel, how much another path there lowers the
// variance of the estimate (docs/design/fitter.md, "Paths where the information is").
//
// A pixel's recorded estimate has per-path variance s_p^2, and moving parameter k by one unit
// moves it by J_pk. With the estimate's variances roughly diagonal, pixel p adds to the variance of
// parameter k about (J_pk std_k^2)^2 s_p^2 / paths_p; the paths that minimise the sum of the
// parameters' relative variances, sum_k Var_k / scale_k^2, for a given total are (Neyman's
// allocation) paths_p proportional to
//
//     importance_p = s_p * sqrt(sum_k (J_pk std_k^2 / scale_k)^2)
//
// with scale_k = max(|y_k|, 0.01) for kd and ks and 1 for log n (whose std is n's relative one).
// Parameters the images leave unconstrained (std 0) and the exposure do not count.
#pragma once

#include <vector>

#include "observation.h"
#include "path_set.h"

namespace phongfit {

// Per view, per pixel: importance_p as above (0 where no fitted material is seen or the pixel is
// not valid), from a round's two recordings `first` and `second` (one set per view each),
// replayed at the natural coordinates `natural` (P per slot, in slot order) with standard errors
// `naturalStd` (same layout). s_p is estimated from the two sets' difference, averaged over the
// pixels within 2 (one pixel's difference has 3 degrees of freedom). Deterministic.
template <int P>
std::vector<std::vector<float>> pathImportance(const std::vector<Observation>& observations,
                                               const std::vector<PathSet>& first,
                                               const std::vector<PathSet>& second,
                                               const std::vector<double>& natural,
                                               const std::vector<double>& naturalStd, int threads);

// Extra paths per pixel for a recording: `extra` in all, shared in proportion to `importance`
// (Neyman's allocation), at most `most` in a pixel. Fixed before tracing, from an earlier round's
// recordings, so every pixel's estimate stays unbiased.
std::vector<int> allocatePaths(const std::vector<float>& importance, double extra, int most);

}  // namespace phongfit
