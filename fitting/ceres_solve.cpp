#include "ceres_solve.h"

#include <fmt/format.h>

#include <algorithm>
#include <cstdio>
#include <functional>

#include "box_manifold.h"
#include "error.h"
#include "least_squares_residual.h"
#include "moment_residual.h"

namespace phongfit {

namespace {

// Ends a Ceres solve, keeping its last accepted point, once FitOptions::stopRequested says so.
class StopCallback final : public ceres::IterationCallback {
public:
    explicit StopCallback(const std::function<bool()>& stop) : stop_(stop) {}
    ceres::CallbackReturnType operator()(const ceres::IterationSummary&) override {
        return stop_ && stop_() ? ceres::SOLVER_TERMINATE_SUCCESSFULLY : ceres::SOLVER_CONTINUE;
    }

private:
    const std::function<bool()>& stop_;
};

}  // namespace

template <int P>
int buildProblem(ceres::Problem& problem, ParameterState<P>& params, const std::vector<bool>& seen,
                 const std::vector<bool>& pinned, std::vector<std::uint32_t>& blockSlots,
                 std::vector<double*>& blocks) {
    int freeCount = 0;
    for (int s = 0; s < params.blockCount(); ++s) {
        if (!seen[s]) continue;
        double* x = params.block(s);
        problem.AddParameterBlock(x, P);
        blockSlots.push_back(std::uint32_t(s));
        blocks.push_back(x);
        std::vector<bool> fixed(P, false);
        for (int i : heldCoordinates<P>(params.held(s))) fixed[i] = true;
        for (int i = 0; i < P && !pinned.empty(); ++i)
            if (pinned[std::size_t(s) * P + i]) fixed[i] = true;
        const int constant = int(std::count(fixed.begin(), fixed.end(), true));
        if (constant == P) {
            problem.SetParameterBlockConstant(x);
        } else {
            std::vector<double> lower(P), upper(P);
            internalBounds<P>(params.held(s), x, lower.data(), upper.data());
            problem.SetManifold(x, new BoxManifold(lower, upper, fixed));
        }
        freeCount += P - constant;
    }
    return freeCount;
}

template <int P>
std::vector<int> freeIndices(const ParameterState<P>& params,
                             const std::vector<std::uint32_t>& blockSlots) {
    std::vector<int> free;
    for (std::uint32_t s : blockSlots)
        for (int i = 0; i < P; ++i)
            if (!params.isHeld(int(s), i)) free.push_back(int(s) * P + i);
    return free;
}

ceres::Solver::Options solverOptions(const FitOptions& options, double initialRadius,
                                     double functionTolerance, int maxIterations) {
    ceres::Solver::Options solverOptions;
    solverOptions.linear_solver_type = ceres::DENSE_QR;
    // Dogleg reuses one factorization across rejected steps, which far starts produce several of
    // (measured: 2x fewer Jacobian evaluations than Levenberg-Marquardt).
    solverOptions.trust_region_strategy_type = ceres::DOGLEG;
    solverOptions.initial_trust_region_radius = initialRadius;
    solverOptions.max_num_iterations = maxIterations;
    solverOptions.function_tolerance = functionTolerance;
    solverOptions.parameter_tolerance = 1e-10;
    solverOptions.logging_type = options.verbose ? ceres::PER_MINIMIZER_ITERATION : ceres::SILENT;
    solverOptions.minimizer_progress_to_stdout = options.verbose;
    return solverOptions;
}

Minimized solveProblem(ceres::Problem& problem, const FitOptions& options, double initialRadius,
                       double functionTolerance, int maxIterations) {
    ceres::Solver::Options solverOptions =
        phongfit::solverOptions(options, initialRadius, functionTolerance, maxIterations);
    StopCallback stop(options.stopRequested);
    if (options.stopRequested) solverOptions.callbacks.push_back(&stop);
    ceres::Solver::Summary summary;
    ceres::Solve(solverOptions, &problem, &summary);
    if (options.verbose) fmt::print(stderr, "{}\n", summary.BriefReport());
    if (!summary.IsSolutionUsable())
        throw Error(fmt::format("the fit failed: {}", summary.message));
    return {summary.num_successful_steps + summary.num_unsuccessful_steps,
            summary.minimizer_time_in_seconds, summary.termination_type == ceres::CONVERGENCE};
}

namespace {

// Solves in a row that one minimization may take, each with the coordinates the last left on a
// bound and pushing outward held there (minimizeInBox).
constexpr int kMaxActiveSets = 4;

// Adds the residual block to a problem that buildProblem has the parameter blocks of.
using AddResidual =
    std::function<void(ceres::Problem&, const std::vector<std::uint32_t>& blockSlots,
                       const std::vector<double*>& blocks)>;

struct OnBound {
    std::size_t coordinate;  // slot * P + i
    int tangent;             // its index among the free coordinates (Ceres' tangent space)
    bool lower;
};

// The coordinates of `blocks` (buildProblem's) that `params` does not hold and that are on a bound
// of the box.
template <int P>
std::vector<OnBound> freeOnBounds(const ParameterState<P>& params,
                                  const std::vector<std::uint32_t>& blockSlots,
                                  const std::vector<double*>& blocks) {
    std::vector<OnBound> onBounds;
    int tangent = 0;
    for (std::size_t b = 0; b < blocks.size(); ++b) {
        const int s = int(blockSlots[b]);
        const double* x = blocks[b];
        double lower[P], upper[P];
        internalBounds<P>(params.held(s), x, lower, upper);
        for (int i = 0; i < P; ++i) {
            if (params.isHeld(s, i)) continue;
            if (x[i] <= lower[i] || x[i] >= upper[i])
                onBounds.push_back(
                    {std::size_t(s) * P + std::size_t(i), tangent, x[i] <= lower[i]});
            ++tangent;
        }
    }
    return onBounds;
}

// Per coordinate (slot * P + i), whether it is free, on a bound of the box and the cost's
// gradient there points out of it; empty when none is. Evaluates the gradient only when some free
// coordinate is on a bound.
template <int P>
std::vector<bool> outwardOnBounds(ParameterState<P>& params, const std::vector<bool>& seen,
                                  const AddResidual& add) {
    ceres::Problem problem;
    std::vector<std::uint32_t> blockSlots;
    std::vector<double*> blocks;
    if (buildProblem(problem, params, seen, {}, blockSlots, blocks) == 0) return {};
    const std::vector<OnBound> onBounds = freeOnBounds(params, blockSlots, blocks);
    if (onBounds.empty()) return {};
    add(problem, blockSlots, blocks);
    ceres::Problem::EvaluateOptions evaluate;
    for (double* x : blocks)
        if (!problem.IsParameterBlockConstant(x)) evaluate.parameter_blocks.push_back(x);
    std::vector<double> gradient;
    if (!problem.Evaluate(evaluate, nullptr, nullptr, &gradient, nullptr)) return {};
    std::vector<bool> outward(std::size_t(params.blockCount()) * P, false);
    bool any = false;
    for (const OnBound& o : onBounds) {
        const double g = gradient[std::size_t(o.tangent)];
        if (o.lower ? g > 0 : g < 0) outward[o.coordinate] = any = true;
    }
    return any ? outward : std::vector<bool>{};
}

// One solve from `params`, holding `pinned` (buildProblem) besides what `params` holds.
template <int P>
Minimized solveOnce(ParameterState<P>& params, const std::vector<bool>& seen,
                    const std::vector<bool>& pinned, const AddResidual& add,
                    const FitOptions& options, double initialRadius, double functionTolerance,
                    int maxIterations) {
    ceres::Problem problem;
    std::vector<std::uint32_t> blockSlots;
    std::vector<double*> blocks;
    if (buildProblem(problem, params, seen, pinned, blockSlots, blocks) == 0) return {};
    add(problem, blockSlots, blocks);
    Minimized m = solveProblem(problem, options, initialRadius, functionTolerance, maxIterations);
    m.onBound = !freeOnBounds(params, blockSlots, blocks).empty();
    return m;
}

// Minimizes a least-squares cost over the box by active sets: Ceres' steps are clamped into the
// box (box_manifold.h), and a step that pushes a coordinate on a bound outward is cut back to the
// trust region's shrinking radius in every coordinate, so a minimum on a bound (ks = 0 without a
// lobe) was stopped short of, as converged, or crawled towards to the iteration cap. Each solve
// here holds the coordinates on a bound that the gradient pushes outward, until a solution's are
// the ones it held (docs/design/fitter.md, "Bounds").
template <int P>
Minimized minimizeInBox(ParameterState<P>& params, const std::vector<bool>& seen,
                        const AddResidual& add, const FitOptions& options, double initialRadius,
                        double functionTolerance, int maxIterations) {
    Minimized total;
    std::vector<bool> held = outwardOnBounds(params, seen, add);
    for (int set = 1;; ++set) {
        const Minimized m = solveOnce(params, seen, held, add, options, initialRadius,
                                      functionTolerance, maxIterations - total.iterations);
        total.iterations += m.iterations;
        total.seconds += m.seconds;
        total.converged = m.converged;
        total.onBound = m.onBound;
        if (total.iterations >= maxIterations || (options.stopRequested && options.stopRequested()))
            return total;
        std::vector<bool> outward = outwardOnBounds(params, seen, add);
        if (outward == held) return total;
        if (set == kMaxActiveSets) {
            total.converged = false;
            return total;
        }
        held = std::move(outward);
    }
}

}  // namespace

template <int P>
Minimized minimizeLeastSquares(Objective<P>& objective, ParameterState<P>& params,
                               const std::vector<double>& weights, bool cross,
                               const FitOptions& options) {
    // Ceres sees a cost |r|^2 / 2 >= 0, and the sum of cross products goes below 0 wherever the
    // recordings' noise outweighs the model's error: a constant offset, the noise's scale at the
    // start, keeps it positive without moving its minimum.
    const double offset =
        cross ? objective.crossScale(params.naturalCoordinates().data(), weights) : 0.0;
    const auto sums = [&objective, &weights, cross, offset](const double* y, double& squares,
                                                            Eigen::VectorXd* gradient,
                                                            Eigen::MatrixXd* gramian) {
        objective.leastSquaresSums(y, weights, cross, squares, gradient, gramian);
        squares += offset;
    };
    const auto add = [&params, &sums](ceres::Problem& problem,
                                      const std::vector<std::uint32_t>& blockSlots,
                                      const std::vector<double*>& blocks) {
        problem.AddResidualBlock(new LeastSquaresResidual<P>(sums, blockSlots, params.held(),
                                                             freeIndices(params, blockSlots)),
                                 nullptr, blocks);
    };
    // A far start's first Gauss-Newton step can jump log n to its bound, a dead end where the
    // lobe is invisible: start with steps that change log n by about 1 at most. Stop once a step
    // changes the cost by less than moving a tenth of a standard error does: with cost C at the
    // minimum over N residuals, k standard errors cost about k^2 C / N more.
    const double residuals = 3.0 * double(objective.pixels().seeingMaterial);
    return minimizeInBox(params, objective.pixels().slotSeen, add, options, 1.0,
                         std::max(kMomentTolerance, 0.01 / residuals), options.maxIterations);
}

template <int P>
Minimized minimizeMoments(Objective<P>& objective, ParameterState<P>& params,
                          const Instruments<P>& instruments, const FitOptions& options) {
    const auto moments = [&objective, &instruments](const double* y, Eigen::VectorXd& g,
                                                    Eigen::MatrixXd* dg) {
        instruments.momentSums(objective, y, g, dg);
    };
    const auto add = [&params, &instruments, &moments](ceres::Problem& problem,
                                                       const std::vector<std::uint32_t>& blockSlots,
                                                       const std::vector<double*>& blocks) {
        const std::vector<int> free = freeIndices(params, blockSlots);
        problem.AddResidualBlock(new MomentResidual<P>(moments, blockSlots, params.held(), free,
                                                       instruments.whitening(free)),
                                 nullptr, blocks);
    };
    // A root of the moment equations is no minimum that a bound can hold: where none lies in the
    // box the passes give up (estimators.cpp), and the active sets of minimizeInBox cycled there.
    return solveOnce(params, objective.pixels().slotSeen, {}, add, options,
                     ceres::Solver::Options().initial_trust_region_radius, kMomentTolerance,
                     std::min(options.maxIterations, kMomentIterations));
}

template Minimized minimizeLeastSquares<kRgbBlock>(Objective<kRgbBlock>&,
                                                   ParameterState<kRgbBlock>&,
                                                   const std::vector<double>&, bool,
                                                   const FitOptions&);
template Minimized minimizeLeastSquares<kGreyBlock>(Objective<kGreyBlock>&,
                                                    ParameterState<kGreyBlock>&,
                                                    const std::vector<double>&, bool,
                                                    const FitOptions&);
template Minimized minimizeMoments<kRgbBlock>(Objective<kRgbBlock>&, ParameterState<kRgbBlock>&,
                                              const Instruments<kRgbBlock>&, const FitOptions&);
template Minimized minimizeMoments<kGreyBlock>(Objective<kGreyBlock>&, ParameterState<kGreyBlock>&,
                                               const Instruments<kGreyBlock>&, const FitOptions&);

}  // namespace phongfit
