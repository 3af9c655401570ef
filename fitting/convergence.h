// When an estimate has stopped moving (FitOptions::tolerance, stdTolerance).
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <vector>

#include "fitter.h"
#include "material_params.h"
#include "precision_target.h"
#include "round_outcome.h"

namespace phongfit {

// Reflectances below this are compared absolutely.
inline constexpr double kReflectanceFloor = 0.01;

// Whether every parameter moved from `before` to `after` (natural coordinates, per block) by less
// than tolerance * max(|before|, kReflectanceFloor) (log n: tolerance), or by less than
// stdTolerance times its standard error in `naturalStd` (0: that test never passes).
template <int P>
bool withinTolerance(const std::vector<Eigen::Matrix<double, P, 1>>& before,
                     const std::vector<Eigen::Matrix<double, P, 1>>& after,
                     const std::vector<std::vector<double>>& naturalStd,
                     const FitOptions& options) {
    using L = BlockLayout<P>;
    for (std::size_t s = 0; s < before.size(); ++s) {
        for (int i = 0; i < P; ++i) {
            const double change = std::abs(after[s][i] - before[s][i]);
            const double scale =
                i == L::kLogN ? 1.0 : std::max(std::abs(before[s][i]), kReflectanceFloor);
            if (change > options.tolerance * scale &&
                change > options.stdTolerance * naturalStd[s][i])
                return false;
        }
    }
    return true;
}

// The part of standard errors `std` (one block's) that is the recordings' own noise
// (`recordings`: std sqrt(share)) or the image's (std sqrt(1 - share)), by the recordings' share of
// each variance `pathShare` (RoundOutcome's). A parameter with no share is returned whole.
inline std::vector<double> noisePart(std::vector<double> std, const std::vector<double>& pathShare,
                                     bool recordings) {
    for (std::size_t i = 0; i < std.size() && i < pathShare.size(); ++i) {
        const double share = std::clamp(pathShare[i], 0.0, 1.0);
        std[i] *= std::sqrt(recordings ? share : 1 - share);
    }
    return std;
}

// Per block and parameter, the part of a round's standard error `naturalStd` that is its
// recordings' own noise (`pathShare`, RoundOutcome's); empty without a share.
inline std::vector<std::vector<double>> pathNoise(
    const std::vector<std::vector<double>>& naturalStd,
    const std::vector<std::vector<double>>& pathShare) {
    if (pathShare.size() != naturalStd.size()) return {};
    std::vector<std::vector<double>> noise;
    for (std::size_t b = 0; b < naturalStd.size(); ++b)
        noise.push_back(noisePart(naturalStd[b], pathShare[b], true));
    return noise;
}

// `noise`, per block and parameter, with the independent noise `more` added (none if empty).
inline void addPathNoise(std::vector<std::vector<double>>& noise,
                         const std::vector<std::vector<double>>& more) {
    for (std::size_t b = 0; b < noise.size() && b < more.size(); ++b)
        for (std::size_t i = 0; i < noise[b].size() && i < more[b].size(); ++i)
            noise[b][i] = std::hypot(noise[b][i], more[b][i]);
}

// A round's path noise (pathNoise) and paths, for the next round's move; only where its
// recordings resolve its estimate (a parameter as uncertain as it is large is no estimate to be
// near, and its standard error would pass any move).
struct RoundPathNoise {
    std::vector<std::vector<double>> pathNoise;  // empty for none
    double pathFactor = 1;
};

// Whether a round recorded at `last`'s estimate with more paths, `pathFactor`, settled there: as
// precise as FitOptions::precision asks, and moved by less than stdTolerance times its own
// standard errors (`noise`) and `last`'s path noise together. After the paths grew its own are
// the smaller part of that move's noise; `last` need not have settled, only resolved its estimate
// (docs/design/fitter.md, "After the paths grew").
template <int P>
bool settledAgain(const std::vector<Eigen::Matrix<double, P, 1>>& before,
                  const std::vector<Eigen::Matrix<double, P, 1>>& after,
                  std::vector<std::vector<double>> noise, const RoundPathNoise& last,
                  const RoundOutcome& out, const ParameterState<P>& params,
                  const FitOptions& options, double pathFactor) {
    if (last.pathNoise.empty() || options.precision <= 0 || pathFactor <= last.pathFactor ||
        !planPrecision<P>(params, out.naturalStd, out.pathShare, options.precision, pathFactor).met)
        return false;
    addPathNoise(noise, last.pathNoise);
    return withinTolerance<P>(before, after, noise, options);
}

}  // namespace phongfit
