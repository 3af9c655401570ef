// The Ceres calls, in the steps of Ceres' bundle_adjuster example: the problem's parameter blocks
// (buildProblem), the solver options (solverOptions) and the solve (solveProblem), for the
// least-squares and the moment residual (one small dense block each, whose pixel sums run in
// parallel).
#pragma once

#include <ceres/problem.h>
#include <ceres/solver.h>

#include <cstdint>
#include <vector>

#include "fitter.h"
#include "instruments.h"
#include "objective.h"
#include "parameter_state.h"

namespace phongfit {

// Ceres' relative function tolerance for the moment equations, whose cost is 0 at the root.
inline constexpr double kMomentTolerance = 1e-10;
// Ceres iterations a moment solve may take: near a root Gauss-Newton reaches it in under ten; one
// that has not by then crawls (no root in reach, or a bound), and the next pass goes on from there
// with the instruments moved (docs/design/fitter.md, "A round").
inline constexpr int kMomentIterations = 25;

struct Minimized {
    int iterations = 0;
    double seconds = 0;
    bool converged = true;  // Ceres stopped on a tolerance (nothing to solve counts)
    bool onBound = false;   // some coordinate not held ended on a bound of the box
};

// Adds the blocks some used pixel sees (`seen`, per block), with their bounds and held
// coordinates, and holds the coordinates `pinned` says (slot * P + i; empty: none) too;
// `blockSlots` and `blocks` get each block's index and data. Returns the number of free
// coordinates.
template <int P>
int buildProblem(ceres::Problem& problem, ParameterState<P>& params, const std::vector<bool>& seen,
                 const std::vector<bool>& pinned, std::vector<std::uint32_t>& blockSlots,
                 std::vector<double*>& blocks);

// The flat coordinates of the blocks in `blockSlots` that are not held.
template <int P>
std::vector<int> freeIndices(const ParameterState<P>& params,
                             const std::vector<std::uint32_t>& blockSlots);

// `initialRadius`: Ceres' initial trust region radius, in its Jacobi-scaled coordinates;
// `functionTolerance`: the relative cost change it stops at; `maxIterations`: its iteration cap.
ceres::Solver::Options solverOptions(const FitOptions& options, double initialRadius,
                                     double functionTolerance, int maxIterations);

// Solves, stopping early when FitOptions::stopRequested says so (keeping the last accepted point).
// Throws Error when Ceres has no usable solution.
Minimized solveProblem(ceres::Problem& problem, const FitOptions& options, double initialRadius,
                       double functionTolerance, int maxIterations);

// Least squares (Objective::leastSquaresSums with these weights, or cross products) from
// `params`, which ends at the solution.
template <int P>
Minimized minimizeLeastSquares(Objective<P>& objective, ParameterState<P>& params,
                               const std::vector<double>& weights, bool cross,
                               const FitOptions& options);

// The moment equations g = 0 with `instruments`, from `params`. Unconverged and on a bound: no root
// in the box within reach.
template <int P>
Minimized minimizeMoments(Objective<P>& objective, ParameterState<P>& params,
                          const Instruments<P>& instruments, const FitOptions& options);

}  // namespace phongfit
