// Which parameters the images do not constrain, decided from the Gauss-Newton information matrix
// F = J^T W J of the residuals with respect to the natural parameters (per slot: kd per colour
// group, ks per colour group, log n; see material_params.h), so the decision does not depend on
// how the solver parameterizes them.
#pragma once

#include <Eigen/Core>
#include <vector>

namespace phongfit {

// Parameters whose whole effect on the images is below this fraction of the observed intensity:
// RMS over residuals of dI/dy_j (per unit of kd, ks or log n) <= kInvisible * RMS observation.
inline constexpr double kInvisible = 1e-6;
// Parameters whose column of J is this close to the span of the columns before it: the fraction
// of F_jj that the earlier, kept parameters do not explain (1 / variance inflation factor).
inline constexpr double kCollinear = 1e-9;
// The specular lobe is pursued, round after round, while some colour group's ks exceeds this many
// standard errors; otherwise n is not constrained by the images.
inline constexpr double kLobeSignificance = 2;
// ... and reported only when it exceeds this many at the final estimate. The lobe's n is fitted:
// the most significant of many lobe shapes is kept, and 2 standard errors are often reached
// by the noise alone (a look-elsewhere effect; docs/design/fitter.md).
inline constexpr double kLobeConfirmation = 3;
// A lobe short of kLobeConfirmation whose n, held at its start, raises the images' squared error
// by more than this many mean squared residuals (one parameter's chi-square at 5 standard errors)
// is seen after all.
inline constexpr double kSeenLobeCost = 25;

// Indices of the parameters not yet `held` that are invisible or collinear with earlier ones.
// Parameters are tried in index order (per slot kd, then ks, then log n), so of two parameters the
// images cannot tell apart, the later one is reported: ks rather than kd, n rather than ks.
// `residualCount` is the number of scalar residuals, `rmsObserved` the RMS of the weighted
// observations.
std::vector<int> findUnconstrained(const Eigen::MatrixXd& information, double residualCount,
                                   double rmsObserved, const std::vector<bool>& held);

// A material's free ks groups and their standard errors, as lobeDetected and lobeConfirmed read
// them.
struct SpecularGroups {
    std::vector<double> ks, std;
};

// True when some group's ks exceeds `significance` standard errors (ks and ksStd per colour group).
bool lobeDetected(const std::vector<double>& ks, const std::vector<double>& ksStd,
                  double significance = kLobeSignificance);

// Whether the images show a lobe: some group's ks at least kReflectanceFloor and kLobeConfirmation
// standard errors above 0.
bool lobeConfirmed(const std::vector<double>& ks, const std::vector<double>& ksStd);

}  // namespace phongfit
