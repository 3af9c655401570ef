// The sums over pixels at one point that the estimators, the identifiability test and the
// standard errors need.
#pragma once

#include <Eigen/Core>
#include <cstdint>

#include "instruments.h"
#include "objective.h"
#include "parameter_state.h"

namespace phongfit {

// Over the flat natural coordinates. J is a pixel's weighted residual Jacobian in one set, rho'
// the robust loss' weight there, m the pixel's term of the estimating equations (W Z^T r summed
// over the two sets for instrumental variables, rho' J^T r for least squares).
struct Analysis {
    Eigen::MatrixXd gram;      // sum of rho' J^T J, averaged over the sets
    Eigen::MatrixXd jacobian;  // of the estimating equations: sum of W Z^T J (or the gram)
    Eigen::MatrixXd scores;    // sum of m m^T (uncertainty.h)
    // Sum of l l^T, l = rho' J^T r averaged over the sets: least squares' scores, which with the
    // gram give the standard errors that decide what is unconstrained.
    Eigen::MatrixXd leastSquaresScores;
    // With two sets A and B, the cross-product least squares' sum of (J_A^T J_B + J_B^T J_A) / 2
    // and of c c^T, c = (J_A^T r_B + J_B^T r_A) / 2.
    Eigen::MatrixXd crossGram, crossScores;
    double squares = 0;  // of the mean prediction's error, unweighted, where a material is seen

    Analysis& operator+=(const Analysis& other) {
        gram += other.gram;
        jacobian += other.jacobian;
        leastSquaresScores += other.leastSquaresScores;
        crossGram += other.crossGram;
        crossScores += other.crossScores;
        squares += other.squares;
        return *this;
    }
};

// A pixel's term of an anchor's estimating equations (estimators.cpp), over its slots, and the
// term's Jacobian: least squares' l = sum over the sets of rho'_k / sets J_k^T r_k, Jacobian
// sum rho'_k / sets J_k^T J_k, or (`cross`, two sets) the cross products' c = (J_A^T r_B + J_B^T
// r_A) / 2, Jacobian (J_A^T J_B + J_B^T J_A) / 2 (if `jacobian` is not null). `j` and `r`: the
// pixel's weighted Jacobians and residuals per set, `rho` their robust loss weights. `secondSign`
// -1 negates the second set's part of the term (not of its Jacobian), as pixelMoment's.
template <int P>
void anchorTerm(const PixelJacobians<P>& j, const Eigen::Vector3d (&r)[2], const double (&rho)[2],
                int sets, std::uint32_t slotCount, bool cross, Eigen::VectorXd& term,
                Eigen::MatrixXd* jacobian, double secondSign = 1);

// The sums at `params`' current point. Keeps each set's Jacobians, residuals and loss weights
// there in `at`: the next instruments, and what the scores are computed from. `instruments`:
// those of the moments (instrumental variables; the moment sums are left out while it is empty),
// or null for least squares.
template <int P>
Analysis analyse(Objective<P>& objective, const ParameterState<P>& params,
                 const Instruments<P>* instruments, Linearization<P>& at);

}  // namespace phongfit
