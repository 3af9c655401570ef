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

// Material block `m` at `params`' point, with standard errors `stdNatural` (its natural ones)
// and the parameters it holds named unconstrained.
template <int P>
MaterialFit materialFit(const ParameterState<P>& params, int m,
                        const std::vector<double>& stdNatural);

// The exposure at `params`' point, with its standard error from the block's (`stdNatural`).
template <int P>
ExposureFit exposureFit(const ParameterState<P>& params, const std::vector<double>& stdNatural);

}  // namespace phongfit
