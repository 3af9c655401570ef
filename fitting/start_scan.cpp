#include "start_scan.h"

#include <Eigen/Cholesky>
#include <cmath>
#include <limits>

namespace phongfit {

template <int P>
void matchExposure(Objective<P>& objective, ParameterState<P>& params) {
    using L = BlockLayout<P>;
    const std::vector<double> y = params.naturalCoordinates();
    double squares = 0;
    Eigen::VectorXd gradient;
    Eigen::MatrixXd gramian;
    objective.leastSquaresSums(y.data(), {}, false, squares, &gradient, &gramian);
    const Eigen::Index e = Eigen::Index(params.exposure().slot()) * P + L::kLogN;
    // With s I the weighted prediction: gradient = <sI, sI - y>, gramian = <sI, sI>.
    const double predicted = gramian(e, e), product = predicted - gradient[e];
    params.setExposure(
        ExposureBlock::matched(params.exposure().template value<P>(y.data()), predicted, product));
}

namespace {

// Exponents of the scan's grid: factors of 4 from 1 to kMaxExponent, and kMaxExponent.
std::vector<double> logExponentGrid() {
    std::vector<double> grid;
    for (double n = 1; n < kMaxExponent; n *= 4) grid.push_back(std::log(n));
    grid.push_back(std::log(kMaxExponent));
    return grid;
}

// Material s's exponent from `grid` (with its own first) by the cost after one Gauss-Newton step
// of its free kd and ks; `y` (natural coordinates) and `params` take the best. At the start the
// cost is pooled least squares, and the own exponent's step is taken where it stays best. In a
// `laterRound`, recorded at the estimate, it is the cross products of the two recordings (their
// noise, which favours the exponent they were recorded at, cancels) and only a grid exponent that
// wins moves the material.
template <int P>
void scanMaterial(Objective<P>& objective, ParameterState<P>& params, int s,
                  const std::vector<double>& grid, bool laterRound, std::vector<double>& y) {
    using L = BlockLayout<P>;
    const UsedPixels& prep = objective.pixels();
    const HeldParams& held = params.held(s);
    const std::size_t at = std::size_t(s) * P;
    std::vector<int> reflectances;  // free kd and ks coordinates of the material
    for (int i = 0; i < L::kLogN; ++i)
        if (!params.isHeld(s, i)) reflectances.push_back(int(at) + i);
    double bestCost = std::numeric_limits<double>::infinity();
    std::vector<double> trial, best;
    const double margin =
        1e-9 * 3.0 * double(prep.seeingMaterial) * prep.rmsObserved * prep.rmsObserved;
    std::vector<double> candidates{y[at + L::kLogN]};
    candidates.insert(candidates.end(), grid.begin(), grid.end());
    bool gridWins = false;
    for (std::size_t c = 0; c < candidates.size(); ++c) {
        const double logN = candidates[c];
        trial = y;
        trial[at + L::kLogN] = logN;
        if (!reflectances.empty()) {
            double squares = 0;
            Eigen::VectorXd gradient;
            Eigen::MatrixXd gramian;
            objective.leastSquaresSums(trial.data(), {}, false, squares, &gradient, &gramian);
            Eigen::MatrixXd h = gramian(reflectances, reflectances);
            h.diagonal().array() += 1e-12 * (h.diagonal().maxCoeff() + 1e-300);
            const Eigen::VectorXd step = h.ldlt().solve(-gradient(reflectances));
            for (std::size_t k = 0; k < reflectances.size(); ++k)
                if (std::isfinite(step[Eigen::Index(k)]))
                    trial[std::size_t(reflectances[k])] += step[Eigen::Index(k)];
            clampReflectances<P>(trial.data() + at, held);
        }
        double cost = 0;
        objective.leastSquaresSums(trial.data(), {}, laterRound, cost, nullptr, nullptr);
        if (cost < bestCost - margin) bestCost = cost, best = trial, gridWins = c > 0;
    }
    if (laterRound && !gridWins) return;
    y = best;
    params.setNatural(s, y.data() + at);
}

}  // namespace

template <int P>
void scanExponents(Objective<P>& objective, ParameterState<P>& params) {
    const UsedPixels& prep = objective.pixels();
    std::vector<double> y = params.naturalCoordinates();
    const std::vector<double> grid = logExponentGrid();
    for (int s = 0; s < params.materialCount(); ++s)
        if (!params.held(s).n && prep.slotSeen[s])
            scanMaterial(objective, params, s, grid, false, y);
}

template <int P>
void scanBroaderExponents(Objective<P>& objective, ParameterState<P>& params,
                          const std::vector<bool>& materials) {
    using L = BlockLayout<P>;
    const UsedPixels& prep = objective.pixels();
    std::vector<double> y = params.naturalCoordinates();
    const std::vector<double> grid = logExponentGrid();
    for (int s = 0; s < params.materialCount(); ++s) {
        if (!materials[std::size_t(s)] || params.held(s).n || !prep.slotSeen[s]) continue;
        const double logN = y[std::size_t(s) * P + L::kLogN];
        std::vector<double> broader;
        for (double g : grid)
            if (g < logN - std::log(2.0)) broader.push_back(g);
        if (!broader.empty()) scanMaterial(objective, params, s, broader, true, y);
    }
}

template void matchExposure<kRgbBlock>(Objective<kRgbBlock>&, ParameterState<kRgbBlock>&);
template void matchExposure<kGreyBlock>(Objective<kGreyBlock>&, ParameterState<kGreyBlock>&);
template void scanExponents<kRgbBlock>(Objective<kRgbBlock>&, ParameterState<kRgbBlock>&);
template void scanExponents<kGreyBlock>(Objective<kGreyBlock>&, ParameterState<kGreyBlock>&);
template void scanBroaderExponents<kRgbBlock>(Objective<kRgbBlock>&, ParameterState<kRgbBlock>&,
                                              const std::vector<bool>&);
template void scanBroaderExponents<kGreyBlock>(Objective<kGreyBlock>&, ParameterState<kGreyBlock>&,
                                               const std::vector<bool>&);

}  // namespace phongfit
