#include "identifiability.h"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>

#include "convergence.h"

namespace phongfit {

std::vector<int> findUnconstrained(const Eigen::MatrixXd& information, double residualCount,
                                   double rmsObserved, const std::vector<bool>& held) {
    const Eigen::Index p = information.rows();
    std::vector<int> found;
    // Incremental Cholesky factor of the correlation matrix of the kept parameters.
    std::vector<Eigen::Index> kept;
    Eigen::MatrixXd factor = Eigen::MatrixXd::Zero(p, p);
    for (Eigen::Index j = 0; j < p; ++j) {
        if (held[j]) continue;
        const double fjj = std::max(information(j, j), 0.0);
        if (!(std::sqrt(fjj / residualCount) > kInvisible * rmsObserved)) {
            found.push_back(int(j));
            continue;
        }
        const Eigen::Index k = Eigen::Index(kept.size());
        Eigen::VectorXd correlation(k);
        for (Eigen::Index i = 0; i < k; ++i)
            correlation[i] =
                information(kept[i], j) / std::sqrt(information(kept[i], kept[i]) * fjj);
        const Eigen::VectorXd l =
            factor.topLeftCorner(k, k).triangularView<Eigen::Lower>().solve(correlation);
        const double unexplained = 1 - l.squaredNorm();
        if (!(unexplained > kCollinear)) {
            found.push_back(int(j));
            continue;
        }
        factor.row(k).head(k) = l.transpose();
        factor(k, k) = std::sqrt(unexplained);
        kept.push_back(j);
    }
    return found;
}

bool lobeDetected(const std::vector<double>& ks, const std::vector<double>& ksStd,
                  double significance) {
    for (std::size_t g = 0; g < ks.size(); ++g)
        if (ks[g] > 0 && ks[g] > significance * ksStd[g]) return true;
    return false;
}

bool lobeConfirmed(const std::vector<double>& ks, const std::vector<double>& ksStd) {
    return std::any_of(ks.begin(), ks.end(), [](double k) { return k >= kReflectanceFloor; }) &&
           lobeDetected(ks, ksStd, kLobeConfirmation);
}

}  // namespace phongfit
