// Heteroscedasticity-robust ("sandwich", White 1980) variances of fitted parameters.
//
// The textbook covariance sigma^2 (J^T J)^-1 assumes every residual has the same variance. Monte
// Carlo noise does not: it grows with the intensity, so the highlight pixels that determine n are
// the noisiest, and the textbook standard error of n comes out several times too small (measured
// about 8x on replayed path sets with 10% noise per term). The sandwich F^-1 B F^-1 uses each
// pixel's own residual instead of the average one.
#pragma once

#include <Eigen/Core>
#include <vector>

namespace phongfit {

// Diagonal of F^-1 B F^-1 over the parameters not `held` (0 for held ones), with
// F = sum over pixels of rho' J^T J and B = sum over pixels of rho'^2 J^T r r^T J.
std::vector<double> sandwichVariances(const Eigen::MatrixXd& fisher, const Eigen::MatrixXd& scores,
                                      const std::vector<bool>& held);

}  // namespace phongfit
