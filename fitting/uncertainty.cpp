#include "uncertainty.h"

#include <Eigen/QR>
#include <cmath>

namespace phongfit {

std::vector<double> sandwichVariances(const Eigen::MatrixXd& fisher, const Eigen::MatrixXd& scores,
                                      const std::vector<bool>& held) {
    std::vector<Eigen::Index> free;
    for (Eigen::Index j = 0; j < fisher.rows(); ++j)
        if (!held[j] && fisher(j, j) > 0) free.push_back(j);
    std::vector<double> variance(fisher.rows(), 0.0);
    if (free.empty()) return variance;
    const Eigen::Index k = Eigen::Index(free.size());
    // Unit-diagonal scaling, so the pseudo-inverse's rank decision is relative per parameter.
    Eigen::VectorXd scale(k);
    Eigen::MatrixXd f(k, k), b(k, k);
    for (Eigen::Index i = 0; i < k; ++i) scale[i] = 1 / std::sqrt(fisher(free[i], free[i]));
    for (Eigen::Index i = 0; i < k; ++i)
        for (Eigen::Index j = 0; j < k; ++j) {
            f(i, j) = fisher(free[i], free[j]) * scale[i] * scale[j];
            b(i, j) = scores(free[i], free[j]) * scale[i] * scale[j];
        }
    const Eigen::MatrixXd inverse = f.completeOrthogonalDecomposition().pseudoInverse();
    const Eigen::MatrixXd sandwich = inverse * b * inverse;
    for (Eigen::Index i = 0; i < k; ++i) {
        const double v = sandwich(i, i) * scale[i] * scale[i];
        variance[free[i]] = std::isfinite(v) && v > 0 ? v : 0;
    }
    return variance;
}

}  // namespace phongfit
