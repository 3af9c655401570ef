// The standard errors of a round's estimate: the sandwich (uncertainty.h) over the flat natural
// coordinates, per block.
#pragma once

#include <Eigen/Core>
#include <vector>

#include "instruments.h"
#include "objective.h"
#include "parameter_state.h"

namespace phongfit {

// S = sum over pixels of m m^T, each pixel's m (pixelMoment) with its own pull on the estimate
// undone (leaveOneOutScore); `jacobian` is dg/dy and `held` per flat coordinate. `secondSign` as
// pixelMoment's.
template <int P>
Eigen::MatrixXd scores(Objective<P>& objective, const Linearization<P>& at,
                       const Instruments<P>* instruments, const Eigen::MatrixXd& jacobian,
                       const std::vector<bool>& held, double secondSign = 1);

// The same S for an anchor of the moment solve at y (estimators.cpp) from `fitted`, the sum of its
// pixels' anchorTerm products as fitted (Analysis::crossScores, or leastSquaresScores where not
// `cross`), and the recordings' part of those terms: the second set's part negated, in which the
// image's noise cancels. Where a few pixels hold a parameter, as the pixels reflecting an
// environment's sun hold ks, each pulls the estimate towards itself and its fitted term shrinks
// (understating the variance several times); the recordings' part is in no fit and does not.
// The result: `fitted` plus the recordings' sum along the directions where it is larger
// (`recordingsOnly`: that sum alone; with one set, `fitted` and 0).
template <int P>
Eigen::MatrixXd anchorScores(Objective<P>& objective, const std::vector<double>& y,
                             const Eigen::MatrixXd& fitted, bool cross,
                             bool recordingsOnly = false);

// Standard errors per block of its natural parameters from the sandwich with these sums; 0 for
// the `held` ones.
template <int P>
std::vector<std::vector<double>> naturalStd(const Eigen::MatrixXd& jacobian,
                                            const Eigen::MatrixXd& scores,
                                            const std::vector<HeldParams>& held);

// Standard errors of 0 for `blocks` blocks: for a tolerance test without them.
std::vector<std::vector<double>> noStd(int blocks, int p);

// 1 / the sum of the free parameters' relative variances (log n absolute), 0 if one of them has
// no finite positive standard error: how precise an estimate with these errors is.
template <int P>
double precision(const ParameterState<P>& params,
                 const std::vector<std::vector<double>>& stdNatural);

}  // namespace phongfit
