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

// An anchor of the moment solve (estimators.cpp): cross products' or (not `cross`) least squares'.
// `recordings` is the sum of its pixels' anchorTerm products with the second set's part negated
// (anchorRecordingScores), in which the image's noise cancels and which no fit absorbs.
struct AnchorSandwich {
    bool cross = false;
    Eigen::MatrixXd recordings;
};

// An anchor's S at y: the recordings' part of its pixels' terms (`size` square; 0 with one set).
template <int P>
Eigen::MatrixXd anchorRecordingScores(Objective<P>& objective, const std::vector<double>& y,
                                      Eigen::Index size, bool cross);

// An anchor's S from `fitted`, the sum of its pixels' anchorTerm products as fitted
// (Analysis::crossScores or leastSquaresScores), plus `recordings` along the directions where
// that is larger. Where a few pixels hold a parameter, as the pixels reflecting an environment's
// sun hold ks, each pulls the estimate towards itself and its fitted term shrinks (understating
// the variance several times); the recordings' part is in no fit and does not.
Eigen::MatrixXd anchorScores(const Eigen::MatrixXd& fitted, const Eigen::MatrixXd& recordings);

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
