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

template <int P>
void scanExponents(Objective<P>& objective, ParameterState<P>& params) {
    using L = BlockLayout<P>;
    const UsedPixels& prep = objective.pixels();
    std::vector<double> y = params.naturalCoordinates(), trial, best;
    std::vector<double> grid;
    for (double n = 1; n < kMaxExponent; n *= 4) grid.push_back(std::log(n));
    grid.push_back(std::log(kMaxExponent));
    for (int s = 0; s < params.materialCount(); ++s) {
        const HeldParams& held = params.held(s);
        if (held.n || !prep.slotSeen[s]) continue;
        const std::size_t at = std::size_t(s) * P;
        std::vector<int> reflectances;  // free kd and ks coordinates of the material
        for (int i = 0; i < L::kLogN; ++i)
            if (!params.isHeld(s, i)) reflectances.push_back(int(at) + i);
        double bestCost = std::numeric_limits<double>::infinity();
        grid.insert(grid.begin(), y[at + L::kLogN]);
        const double margin =
            1e-9 * 3.0 * double(prep.seeingMaterial) * prep.rmsObserved * prep.rmsObserved;
        for (double logN : grid) {
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
            objective.leastSquaresSums(trial.data(), {}, false, cost, nullptr, nullptr);
            if (cost < bestCost - margin) bestCost = cost, best = trial;
        }
        grid.erase(grid.begin());
        y = best;
        params.setNatural(s, y.data() + at);
    }
}

template void matchExposure<kRgbBlock>(Objective<kRgbBlock>&, ParameterState<kRgbBlock>&);
template void matchExposure<kGreyBlock>(Objective<kGreyBlock>&, ParameterState<kGreyBlock>&);
template void scanExponents<kRgbBlock>(Objective<kRgbBlock>&, ParameterState<kRgbBlock>&);
template void scanExponents<kGreyBlock>(Objective<kGreyBlock>&, ParameterState<kGreyBlock>&);

}  // namespace phongfit
