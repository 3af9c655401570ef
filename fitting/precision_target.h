// FitOptions::precision: whether a round's estimate is as precise as asked and, if not, how many
// more paths the next round needs or whether the image's own noise stands in the way
// (docs/design/fitter.md, "A precision target").
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <vector>

#include "analysis.h"
#include "fitter.h"
#include "instruments.h"
#include "objective.h"
#include "parameter_state.h"
#include "standard_errors.h"

namespace phongfit {

// The most the paths may grow from one round to the next: the shares below are estimates from one
// round, and a round at the new estimate measures them again. A parameter is said to be at the
// noise floor only once the paths have grown this much: far from the solution the misfit of a
// lobe the recordings do not yet resolve looks like the image's noise.
inline constexpr double kMostPathGrowth = 16;

// A reflectance's precision is relative to max(value, kPrecisionFloor): at the default 1% a kd or
// ks near 0 is asked for a standard error of 0.001, so that 3 of them stay within the recovery
// matrix's absolute tolerance, 0.003. Relative to 0.01 (kReflectanceFloor, the convergence test's)
// a ks of 0 under a noisy sky was asked for 1e-4 and took 57-131 s.
inline constexpr double kPrecisionFloor = 0.1;

// What a reflectance's relative precision is taken of.
inline double reflectancePrecisionScale(double value) {
    return std::max(std::abs(value), kPrecisionFloor);
}

// What a relative precision is taken of: kd and ks max(value, kPrecisionFloor), log n 1 (`i`, a
// natural coordinate of the block `y`). The ks of a material that shows no lobe (`noLobe`: n held,
// ks confirming none) is a lobe's at an exponent the images do not determine: it is asked how
// much of its group's albedo a lobe could hide, max(kd + ks, kPrecisionFloor)
// (docs/design/fitter.md, "The ks of no lobe").
template <int P>
double precisionScale(int i, const Eigen::Matrix<double, P, 1>& y, bool noLobe = false) {
    using L = BlockLayout<P>;
    if (i == L::kLogN) return 1.0;
    if (noLobe && i >= L::specular(0)) {
        const int group = i - L::specular(0);
        return reflectancePrecisionScale(y[L::diffuse(group)] + y[i]);
    }
    return reflectancePrecisionScale(y[i]);
}

// Per block, the share of each parameter's variance that is the recordings' own noise (the rest is
// the image's), at the linearization `at` of a round's instrumental-variables solution `analysis`:
// the same sandwich as the standard errors' with each pixel's moment W_B Z_B^T r_A + W_A Z_A^T r_B
// replaced by W_B Z_B^T r_A - W_A Z_A^T r_B, in which the image's noise cancels and the
// recordings' stays. 0 without instruments or with fewer than two sets: exact or pooled sets
// leave no difference to measure it by. Where the solution is an anchor of the moments instead
// (`anchor`), from that anchor's sandwich (anchorScores) and its recordings' part alone.
template <int P>
std::vector<std::vector<double>> recordingShare(Objective<P>& objective, const Linearization<P>& at,
                                                const Instruments<P>* instruments,
                                                const Analysis& analysis,
                                                const std::vector<HeldParams>& held,
                                                const AnchorSandwich* anchor);

// Per material block, whether it shows no lobe: n held, and no free ks group confirms a lobe
// (lobeConfirmed) by the round's `naturalStd`.
template <int P>
std::vector<bool> showsNoLobe(const ParameterState<P>& params,
                              const std::vector<std::vector<double>>& naturalStd);

struct PrecisionPlan {
    bool met = false;       // every free parameter's relative standard error is at most the target
    bool floor = false;     // not met, and more paths cannot get there: the image's own noise
    double pathGrowth = 1;  // the next round's paths relative to this round's, in [1, growth cap]
};

// From a round's standard errors `naturalStd` and the share of each variance that is the
// recordings' own noise, `pathShare` (per material block, natural coordinates; the exposure block,
// if any, is left out), for relative standard error `target` (kd and ks: std / max(value,
// kPrecisionFloor); n: std of log n; as precisionScale, a material's ks by showsNoLobe). A
// parameter whose variance from the image alone exceeds target^2 is at the noise floor; the others
// need paths m times as many, m = path variance / (target^2 - image variance). `pathFactor`: the
// round's paths relative to the first round's.
template <int P>
PrecisionPlan planPrecision(const ParameterState<P>& params,
                            const std::vector<std::vector<double>>& naturalStd,
                            const std::vector<std::vector<double>>& pathShare, double target,
                            double pathFactor);

// Which standard errors of a MaterialFit meetsPrecision judges: those the fit reports, or the
// image's own noise's (kdImageStd, ...).
enum class PrecisionOf { Reported, ImageNoise };

// Whether `which` standard errors leave every parameter of `materials` as precise as `target`
// asks, as planPrecision measures it (kd and ks relative to reflectancePrecisionScale, n through
// log n). An n listed unconstrained is not asked; the ks of a fit that shows no lobe (noLobeSeen)
// is taken relative to max(kd + ks, kPrecisionFloor), as precisionScale.
bool meetsPrecision(const std::vector<MaterialFit>& materials, double target, PrecisionOf which);

// Whether some free parameter moved from `before` to `after` (natural coordinates, per block) by
// more than `target` asks of its standard error (target times its precisionScale at `before`, a
// material's ks by showsNoLobe with the round's `naturalStd`): a move that more paths could make
// smaller matters to the target.
template <int P>
bool movedPastTarget(const ParameterState<P>& params,
                     const std::vector<std::vector<double>>& naturalStd,
                     const std::vector<Eigen::Matrix<double, P, 1>>& before,
                     const std::vector<Eigen::Matrix<double, P, 1>>& after, double target);

}  // namespace phongfit
