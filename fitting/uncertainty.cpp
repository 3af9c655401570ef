#include "uncertainty.h"

#include <Eigen/LU>
#include <Eigen/QR>
#include <cmath>

namespace phongfit {

namespace {
// Infinity norm of a pixel's pull below which leaveOneOutScore sums the Neumann series.
constexpr double kNeumannLimit = 1e-3;
}  // namespace

Eigen::MatrixXd freeInverse(const Eigen::MatrixXd& jacobian, const std::vector<bool>& held) {
    std::vector<Eigen::Index> free;
    for (Eigen::Index j = 0; j < jacobian.rows(); ++j)
        if (!held[j]) free.push_back(j);
    const Eigen::Index k = Eigen::Index(free.size());
    Eigen::MatrixXd g = jacobian(free, free);
    // Rows (equations) and columns (parameters) scaled to unit norm, so the pseudo-inverse's rank
    // decision is relative per parameter; a parameter no equation sees gets 0.
    Eigen::VectorXd rowScale(k), colScale(k);
    for (Eigen::Index i = 0; i < k; ++i) {
        const double row = g.row(i).norm(), col = g.col(i).norm();
        rowScale[i] = row > 0 ? 1 / row : 0;
        colScale[i] = col > 0 ? 1 / col : 0;
    }
    g = rowScale.asDiagonal() * g * colScale.asDiagonal();
    const Eigen::MatrixXd scaled = colScale.asDiagonal() *
                                   g.completeOrthogonalDecomposition().pseudoInverse() *
                                   rowScale.asDiagonal();
    Eigen::MatrixXd inverse = Eigen::MatrixXd::Zero(jacobian.rows(), jacobian.cols());
    inverse(free, free) = scaled;
    return inverse;
}

Eigen::VectorXd leaveOneOutScore(const Eigen::MatrixXd& pixelJacobian,
                                 const Eigen::MatrixXd& inverse, const Eigen::VectorXd& score) {
    const Eigen::Index n = score.size();
    const Eigen::MatrixXd pull = pixelJacobian * inverse;
    // Among many pixels each pulls little (leverage ~1e-6 among a million): then the Neumann series
    // (I - A)^-1 = I + A + A^2 + ... to A^2 is exact to |A|^3 < 1e-9, without a factorization.
    if (pull.cwiseAbs().rowwise().sum().maxCoeff() < kNeumannLimit) {
        const Eigen::VectorXd once = pull * score;
        return score + once + pull * once;
    }
    const Eigen::MatrixXd shrink = Eigen::MatrixXd::Identity(n, n) - pull;
    const Eigen::FullPivLU<Eigen::MatrixXd> lu(shrink);
    if (!lu.isInvertible()) return score;
    const Eigen::VectorXd corrected = lu.solve(score);
    return corrected.allFinite() ? corrected : score;
}

std::vector<double> sandwichVariances(const Eigen::MatrixXd& jacobian,
                                      const Eigen::MatrixXd& scores,
                                      const std::vector<bool>& held) {
    const Eigen::MatrixXd inverse = freeInverse(jacobian, held);
    const Eigen::MatrixXd sandwich = inverse * scores * inverse.transpose();
    std::vector<double> variance(jacobian.rows(), 0.0);
    for (Eigen::Index i = 0; i < jacobian.rows(); ++i) {
        const double v = sandwich(i, i);
        variance[i] = !held[i] && std::isfinite(v) && v > 0 ? v : 0;
    }
    return variance;
}

}  // namespace phongfit
