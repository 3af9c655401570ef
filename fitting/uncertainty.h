// Heteroscedasticity-robust ("sandwich", White 1980) variances of parameters estimated by solving
// estimating equations g(theta) = sum over pixels m_p(theta) = 0: least squares' normal equations
// (m = rho' J^T r) or the instrumental-variables moments (m = W Z^T r; fitter.h).
//
// The textbook covariance sigma^2 (J^T J)^-1 assumes every residual has the same variance. Monte
// Carlo noise does not: it grows with the intensity, so the highlight pixels that determine n are
// the noisiest, and the textbook standard error of n comes out several times too small (measured
// about 8x on replayed path sets with 10% noise per term). The sandwich G^-1 S G^-T uses each
// pixel's own residual instead of the average one.
#pragma once

#include <Eigen/Core>
#include <vector>

namespace phongfit {

// The pseudo-inverse of G = dg/dtheta over the parameters not `held`; rows and columns of held
// ones are 0.
Eigen::MatrixXd freeInverse(const Eigen::MatrixXd& jacobian, const std::vector<bool>& held);

// A pixel's score m_p as it would be at the estimate fitted without that pixel: a pixel pulls the
// estimate towards itself, which shrinks its own residual, m_fitted = (I - G_p G^-1) m; undoing
// that is the HC3 correction (the jackknife's approximation). Without it, parameters that few
// pixels determine, n from a small highlight, come out with standard errors 1.4x too small
// (measured). `pixelJacobian` is the pixel's term G_p of G and `inverse` the matching block of
// freeInverse(G), both over the pixel's parameters; where I - G_p G^-1 is singular (one pixel
// alone fixes a parameter) the fitted score is returned.
Eigen::VectorXd leaveOneOutScore(const Eigen::MatrixXd& pixelJacobian,
                                 const Eigen::MatrixXd& inverse, const Eigen::VectorXd& score);

// Diagonal of G^-1 S G^-T over the parameters not `held` (0 for held ones), with G = dg/dtheta
// (J^T J for least squares, not symmetric for instrumental variables) and S = sum of m_p m_p^T.
std::vector<double> sandwichVariances(const Eigen::MatrixXd& jacobian,
                                      const Eigen::MatrixXd& scores, const std::vector<bool>& held);

}  // namespace phongfit
