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

// How many standard deviations of their difference the cross products must fit better by to
// overrule pooled least squares' pick at the start (`crossSignificant`).
constexpr double kCrossSignificance = 3;

// The least ks (in some channel) a lobe must have for the cross products to overrule that pick: a
// fainter lobe is within the recovery matrix's absolute tolerance of none, and a significant one
// that faint is the model's mismatch with the image, not a lobe (0048: ks 3.7e-6).
constexpr double kLeastOverrulingKs = 0.003;

// Exponents of the scan's grid: factors of 4 from 1 to kMaxExponent, and kMaxExponent.
std::vector<double> logExponentGrid() {
    std::vector<double> grid;
    for (double n = 1; n < kMaxExponent; n *= 4) grid.push_back(std::log(n));
    grid.push_back(std::log(kMaxExponent));
    return grid;
}

// Of the `trials` (the material's block at `at`), the one whose cross products of the two
// recordings fit better than `chosen`'s (pooled least squares' pick) by the most, where they do
// by more than kCrossSignificance standard deviations of that difference and its lobe does too
// (against itself with ks 0); else `chosen`. Pooled least squares counts the recordings'
// variance, which a lobe the recordings sample poorly (a faint broad one, recorded for a sharp
// start) adds more of than it removes of squared error; the cross products leave it out, but are
// noisy at few paths a pixel, and a better fit than the pick's can be a better kd alone
// (docs/design/fitter.md, "A faint lobe the start's paths sample poorly").
template <int P>
std::vector<double> crossSignificant(Objective<P>& objective,
                                     const std::vector<std::vector<double>>& trials,
                                     const std::vector<double>& chosen, std::size_t at,
                                     double margin) {
    using L = BlockLayout<P>;
    // A (sum of d, sum of d^2) over the pixels that is negative by more than kCrossSignificance
    // standard deviations: the cross products fit better.
    const auto significant = [](const Eigen::Vector2d& d) {
        return -d[0] > kCrossSignificance * std::sqrt(d[1]);
    };
    double most = margin;
    std::vector<double> winner = chosen;
    for (const std::vector<double>& trial : trials) {
        const Eigen::Vector2d pick = objective.crossDifference(trial.data(), chosen.data());
        if (!significant(pick) || -pick[0] <= most) continue;
        std::vector<double> bare = trial;
        for (int g = 0; g < L::kGroups; ++g) bare[at + std::size_t(L::specular(g))] = 0;
        if (significant(objective.crossDifference(trial.data(), bare.data())))
            most = -pick[0], winner = trial;
    }
    return winner;
}

// One Gauss-Newton step of pooled least squares in the free kd and ks (`reflectances`) of the
// material at `at` in `y`, kept in range.
template <int P>
void stepReflectances(Objective<P>& objective, const HeldParams& held,
                      const std::vector<int>& reflectances, std::size_t at,
                      std::vector<double>& y) {
    if (reflectances.empty()) return;
    double squares = 0;
    Eigen::VectorXd gradient;
    Eigen::MatrixXd gramian;
    objective.leastSquaresSums(y.data(), {}, false, squares, &gradient, &gramian);
    Eigen::MatrixXd h = gramian(reflectances, reflectances);
    h.diagonal().array() += 1e-12 * (h.diagonal().maxCoeff() + 1e-300);
    const Eigen::VectorXd step = h.ldlt().solve(-gradient(reflectances));
    for (std::size_t k = 0; k < reflectances.size(); ++k)
        if (std::isfinite(step[Eigen::Index(k)]))
            y[std::size_t(reflectances[k])] += step[Eigen::Index(k)];
    clampReflectances<P>(y.data() + at, held);
}

// The largest ks over the channels of the material at `at` in `y`.
template <int P>
double lobeOf(const std::vector<double>& y, std::size_t at) {
    using L = BlockLayout<P>;
    double ks = 0;
    for (int g = 0; g < L::kGroups; ++g) ks = std::max(ks, y[at + std::size_t(L::specular(g))]);
    return ks;
}

// Material s's exponent from `grid` (with its own first) by the cost after one Gauss-Newton step
// of its free kd and ks; `y` (natural coordinates) and `params` take the best. At the start the
// cost is pooled least squares, and the own exponent's step is taken where it stays best. In a
// `laterRound`, recorded at the estimate, it is the cross products of the two recordings (their
// noise, which favours the exponent they were recorded at, cancels) and only a grid exponent that
// wins moves the material. At the start, a candidate's lobe the cross products single out
// overrules the pick (crossSignificant).
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
    // At the start (recorded there, not exact), the candidates with a lobe of at least
    // kLeastOverrulingKs, which the cross products may prefer to pooled least squares' pick.
    const bool crossStart = !laterRound && !objective.exact();
    std::vector<std::vector<double>> crossTrials;
    for (std::size_t c = 0; c < candidates.size(); ++c) {
        trial = y;
        trial[at + L::kLogN] = candidates[c];
        stepReflectances(objective, held, reflectances, at, trial);
        if (crossStart && lobeOf<P>(trial, at) >= kLeastOverrulingKs) crossTrials.push_back(trial);
        double cost = 0;
        objective.leastSquaresSums(trial.data(), {}, laterRound, cost, nullptr, nullptr);
        if (cost < bestCost - margin) bestCost = cost, best = trial, gridWins = c > 0;
    }
    if (laterRound && !gridWins) return;
    if (crossStart) best = crossSignificant(objective, crossTrials, best, at, margin);
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
