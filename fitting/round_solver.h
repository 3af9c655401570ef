// Solves one round on fixed path sets: from the round's start (with, in the first round, the
// exposure matched and the exponents scanned) the estimator's solves, then what the images leave
// unconstrained is held and the problem solved again, until nothing more is held.
#pragma once

#include <optional>
#include <vector>

#include "analysis.h"
#include "ceres_solve.h"
#include "fitter.h"
#include "instruments.h"
#include "objective.h"
#include "parameter_state.h"
#include "round_outcome.h"
#include "standard_errors.h"

namespace phongfit {

template <int P>
class RoundSolver {
public:
    // `params` persists across rounds: the held parameters and the exposure's start. The path
    // sets must outlive the solver. `firstRound`: match the exposure and scan the exponents
    // (FitOptions::scanStart); else the materials flagged in `scanBroader` (per material, may be
    // empty) scan the exponents broader than where they start (scanBroaderExponents).
    RoundSolver(const std::vector<Observation>& observations, const std::vector<PathSet>& first,
                const std::vector<PathSet>& second, ParameterState<P>& params,
                const FitOptions& options, int threads, bool firstRound,
                std::vector<bool> scanBroader = {});

    // From `theta`; held parameters stay at their start.
    RoundOutcome solve(const Estimate& theta);

    // At the rounds' final estimate: holds the exponents whose lobe falls short of
    // kLobeConfirmation (ks's standard errors at least `ksStdFloor`, per material and ks group, if
    // given) and, if any, solves again into `out`, unless that raises the images' squared error
    // (crossSquares) by more than kSeenLobeCost mean squared residuals: then the round's solution
    // stands. True if anything was held.
    bool confirmLobes(RoundOutcome& out,
                      const std::vector<std::vector<double>>* ksStdFloor = nullptr);

    // For a round whose estimate may end the fit (recorded at an estimate, not the first): each
    // lobe's log n standard error from the image's noise where it is sharper (sharperLogNStd),
    // into `out`'s materials. Taken only there: it renders and replays at up to four sharper lobes.
    void takeSharperNoise(RoundOutcome& out);

private:
    // A solution with its exponents free: the parameters and their standard errors.
    struct FreeExponents {
        ParameterState<P> params;
        std::vector<std::vector<double>> std;
    };

    // The estimator's solves from the parameters' present values, holding what the images leave
    // unconstrained and solving again until nothing more is held; fills `out`. kd's and ks's
    // standard errors with an exponent held are as if n were known: for an exponent held since
    // `free` (lobe confirmation's), they are at least what they were with n free there. (Not for
    // the rounds' own holds: at ks = 0, which they test, n free counts a trade-off only a lobe
    // has; widened by it, 4 lobeless cells of the recovery matrix no longer converged.)
    void solveHolding(RoundOutcome& out, const FreeExponents* free = nullptr);

    // The estimators (estimators.cpp): least squares, reweighted for a robust loss, and the
    // cross-product anchor followed by the instrumental-variables moments.
    Analysis solveLeastSquares(RoundOutcome& out);
    Analysis solveInstrumental(RoundOutcome& out);

    // Where the solution is on kd + ks = 1 (face_projection.h); true if it moved.
    bool projectOntoFace(bool cross);
    Analysis analyse();
    // The images' squared error at `at`, free of the recordings' noise: the cross products of the
    // two sets (instrumental variables), else `squares` (Analysis::squares taken at `at`).
    double crossSquares(const ParameterState<P>& at, double squares);
    std::vector<std::vector<double>> naturalStd(const Eigen::MatrixXd& jacobian,
                                                const Eigen::MatrixXd& scores) const;
    void account(RoundOutcome& out, const Minimized& m) const;
    bool stopping() const { return options_.stopRequested && options_.stopRequested(); }

    ParameterState<P>& params_;
    const FitOptions& options_;
    bool instrumental_;
    bool firstRound_;
    std::vector<bool> scanBroader_;
    Objective<P> objective_;
    Analysis analysis_;    // at the last solution
    Linearization<P> at_;  // at the last analysis
    Instruments<P> instruments_;
    std::vector<double> leastSquaresWeights_;  // per pixel; empty: all 1
    // Where the last solve kept an anchor of the moments: which, and its recordings' part.
    std::optional<AnchorSandwich> anchor_;
};

extern template class RoundSolver<kRgbBlock>;
extern template class RoundSolver<kGreyBlock>;

}  // namespace phongfit
