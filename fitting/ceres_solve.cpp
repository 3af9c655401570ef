#include "ceres_solve.h"

#include <fmt/format.h>

#include <algorithm>
#include <cstdio>

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
                 std::vector<std::uint32_t>& blockSlots, std::vector<double*>& blocks) {
    int freeCount = 0;
    for (int s = 0; s < params.blockCount(); ++s) {
        if (!seen[s]) continue;
        double* x = params.block(s);
        problem.AddParameterBlock(x, P);
        blockSlots.push_back(std::uint32_t(s));
        blocks.push_back(x);
        const std::vector<int> constant = heldCoordinates<P>(params.held(s));
        if (int(constant.size()) == P) {
            problem.SetParameterBlockConstant(x);
        } else {
            std::vector<double> lower(P), upper(P);
            internalBounds<P>(params.held(s), x, lower.data(), upper.data());
            std::vector<bool> fixed(P, false);
            for (int i : constant) fixed[i] = true;
            problem.SetManifold(x, new BoxManifold(lower, upper, fixed));
        }
        freeCount += P - int(constant.size());
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

template <int P>
Minimized minimizeLeastSquares(Objective<P>& objective, ParameterState<P>& params,
                               const std::vector<double>& weights, bool cross,
                               const FitOptions& options) {
    ceres::Problem problem;
    std::vector<std::uint32_t> blockSlots;
    std::vector<double*> blocks;
    if (buildProblem(problem, params, objective.pixels().slotSeen, blockSlots, blocks) == 0)
        return {};
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
    problem.AddResidualBlock(new LeastSquaresResidual<P>(sums, blockSlots, params.held(),
                                                         freeIndices(params, blockSlots)),
                             nullptr, blocks);
    // A far start's first Gauss-Newton step can jump log n to its bound, a dead end where the
    // lobe is invisible: start with steps that change log n by about 1 at most. Stop once a step
    // changes the cost by less than moving a tenth of a standard error does: with cost C at the
    // minimum over N residuals, k standard errors cost about k^2 C / N more.
    const double residuals = 3.0 * double(objective.pixels().seeingMaterial);
    return solveProblem(problem, options, 1.0, std::max(kMomentTolerance, 0.01 / residuals),
                        options.maxIterations);
}

template <int P>
Minimized minimizeMoments(Objective<P>& objective, ParameterState<P>& params,
                          const Instruments<P>& instruments, const FitOptions& options) {
    ceres::Problem problem;
    std::vector<std::uint32_t> blockSlots;
    std::vector<double*> blocks;
    if (buildProblem(problem, params, objective.pixels().slotSeen, blockSlots, blocks) == 0)
        return {};
    const std::vector<int> free = freeIndices(params, blockSlots);
    const auto moments = [&objective, &instruments](const double* y, Eigen::VectorXd& g,
                                                    Eigen::MatrixXd* dg) {
        instruments.momentSums(objective, y, g, dg);
    };
    problem.AddResidualBlock(new MomentResidual<P>(moments, blockSlots, params.held(), free,
                                                   instruments.whitening(free)),
                             nullptr, blocks);
    return solveProblem(problem, options, ceres::Solver::Options().initial_trust_region_radius,
                        kMomentTolerance, std::min(options.maxIterations, kMomentIterations));
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
