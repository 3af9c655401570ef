// A round's result as the rounds loop and the report take it.
#pragma once

#include <cstddef>
#include <map>
#include <string>
#include <vector>

#include "fitter.h"
#include "parameter_state.h"

namespace phongfit {

// The outcome of one round: the solution with its uncertainty and what the round cost.
struct RoundOutcome {
    std::vector<MaterialFit> materials;
    ExposureFit exposure;                         // with FitOptions::fitExposure
    std::vector<std::vector<double>> naturalStd;  // per block, in natural coordinates
    // With FitOptions::precision, per block, the share of each parameter's variance that is the
    // recordings' own noise (recordingShare); else empty.
    std::vector<std::vector<double>> pathShare;
    double rmse = 0;
    int iterations = 0;
    double minimizerSeconds = 0;
    bool solverConverged = false;  // the round's last solve
    std::size_t pixelsUsed = 0;
    std::map<std::string, std::size_t> leftOut;
};

// The standard deviation of n where log n is normal with standard error s (n s to first order):
// n sqrt((e^(s^2) - 1) e^(s^2)). Where s is large (a lobe the recordings barely resolve)
// the first order understates the sharp side by orders of magnitude: n 527 +- 1204 (s = 2.3) for
// a true 30000 is +- 97000 as a log-normal. At most half n's range. A fit's result has at least
// this of its logNStd; its rounds keep n s.
double logNormalStd(double n, double s);

// Whether the fit's ks shows a lobe (lobeConfirmed), from its channels not listed unconstrained.
bool lobeConfirmed(const MaterialFit& fit);

// Whether a lobe holds the fit's n: n resolved (nStd < n), or a lobe confirmed (some ks group at
// least kReflectanceFloor and kLobeConfirmation standard errors above 0). An n neither holds is
// listed unconstrained in the result, wherever it went (1e6 for a sphere with no lobe under a
// 40-degree light); not in the rounds, whose logic (probes, convergence) takes "unconstrained" as
// held.
bool lobeHoldsExponent(const MaterialFit& fit);

// Whether the fit shows no lobe: n unconstrained and ks confirming none. Its ks is then a lobe's
// at an n the images do not determine, bounded by its standard error.
bool noLobeSeen(const MaterialFit& fit);

// A fit's result, n's uncertainty as far as its standard errors reach: nStd at least
// logNormalStd's, and n listed unconstrained where no lobe holds it. An n a lobe holds has an nStd
// reaching log n's 3-standard-error upper end, n e^(3 s) (capped at kMaxExponent): the
// log-normal's standard deviation falls short of it, by a few percent where s is small and by
// far where the images bound n from one side (n 2660 +- 7384, s 1.1, for a true 30000). s is the
// fit's own (logNStd), not one read back from nStd, whose widenings in n (a drift, a probe's
// reach) are reaches already; or logNSharperImageStd where that is larger (the image's noise
// where the lobe is sharper).
void finishExponentUncertainty(MaterialFit& fit);

// Sets `fit`'s counted image noise (MaterialFit::kdCountedImageStd, ...): the image's part
// (noisePart) of material block `m`'s standard errors in `out` (naturalStd; where out has no
// pathShare for it, all of them).
template <int P>
void countImageNoise(const ParameterState<P>& params, int m, const RoundOutcome& out,
                     MaterialFit& fit);

// Material block `m` at `params`' point, with standard errors `stdNatural` (its natural ones)
// and the parameters it holds named unconstrained.
template <int P>
MaterialFit materialFit(const ParameterState<P>& params, int m,
                        const std::vector<double>& stdNatural);

// The exposure at `params`' point, with its standard error from the block's (`stdNatural`).
template <int P>
ExposureFit exposureFit(const ParameterState<P>& params, const std::vector<double>& stdNatural);

}  // namespace phongfit
