// A least-squares minimum over the box that sits on the face kd + ks = 1 of some colour group:
// the unconstrained minimum it stands for, projected back onto the face in the metric of the
// estimate's own covariance (docs/design/fitter.md, "Bounds").
#pragma once

#include <Eigen/Core>

#include "parameter_state.h"

namespace phongfit {

// Whether some colour group of a material whose kd and ks are both free is on kd + ks = 1.
template <int P>
bool onEnergyFace(const ParameterState<P>& params);

// Moves `params`, a minimum over the box of a least-squares cost (flat natural coordinates: its
// Gauss-Newton matrix `gram`, half its gradient `gradient`, its scores `scores`), by the
// Gauss-Newton step to the unconstrained minimum and back onto the faces kd + ks = 1 it was on,
// along the estimate's covariance G^-1 S G^-1. Projected along the cost's own matrix instead, as
// the box's minimum is, an estimate whose truth is on the face comes out biased along the face
// (kd 3% low, 3 standard errors, on a probe-lit sphere at kd + ks = 1); along its covariance the
// part of the noise that crosses the face is regressed out of the rest, which is then unbiased.
// Left where it is when the step ends more than 5 standard errors beyond the face. True if it
// moved.
template <int P>
bool projectOntoEnergyFace(ParameterState<P>& params, const Eigen::MatrixXd& gram,
                           const Eigen::MatrixXd& scores, const Eigen::VectorXd& gradient);

}  // namespace phongfit
