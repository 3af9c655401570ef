// The two estimators of RoundSolver (docs/design/fitter.md explains why two sets, cross products
// and moments).
#include <Eigen/Eigenvalues>
#include <limits>

#include "convergence.h"
#include "face_projection.h"
#include "round_solver.h"
#include "standard_errors.h"
#include "uncertainty.h"

namespace phongfit {

namespace {

// Solves per round with the instruments (or least squares' robust weights) moved to the last
// solution (FitOptions::tolerance); a far start needs 3 or 4, the robust losses' weights a few
// more.
constexpr int kMaxPasses = 8;
// The moment solution is kept unless its precision is below this fraction of the cross-product
// solution's: near-equal ones (exact data, where both are the least-squares solution) must not
// flip from one to the other on rounding.
constexpr double kCrossPreference = 0.5;
// The passes give up, keeping the anchor, once two in a row end this far below the precision
// that keeps the moments, each having moved by less than kWalkingMove of its standard errors (a
// pass that moves further is walking from a poor anchor to a root, unless its standard errors are
// not finite): on the recovery matrix no round that kept the moments had (docs/design/fitter.md,
// "A round").
constexpr double kHopelessPrecision = 0.2 * kCrossPreference;
constexpr double kWalkingMove = 100;
// A moment solve is not started from an anchor where it is hopeless (below kHopelessPrecision of
// the anchor's precision) unless its Newton step there disagrees with the anchor: moves some
// coordinate by more than this many of the moment solution's standard errors, beyond what the
// two consistent estimates' difference can be by noise (docs/design/fitter.md, "A round").
constexpr double kMomentDisagreement = 10;

// Whether the cross products have a minimum here: their Gauss-Newton matrix is positive definite
// over the free coordinates. Their sum itself can be below 0 at a well-defined minimum (a Cornell
// box at 4 paths per pixel, in about one round of three), where pooled least squares would be
// biased towards 0.
bool positiveDefinite(const Eigen::MatrixXd& gram, const std::vector<bool>& held) {
    std::vector<Eigen::Index> free;
    for (std::size_t i = 0; i < held.size(); ++i)
        if (!held[i]) free.push_back(Eigen::Index(i));
    if (free.empty()) return true;
    const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eigen(gram(free, free),
                                                               Eigen::EigenvaluesOnly);
    const Eigen::VectorXd& d = eigen.eigenvalues();
    return d.minCoeff() >
           d.maxCoeff() * double(free.size()) * std::numeric_limits<double>::epsilon();
}

// Whether the Newton step of the moment equations from where `analysis` was taken moves some free
// coordinate by more than kMomentDisagreement of `std` (the moment solution's standard errors
// there, taken through the same inverse of their Jacobian). `g`: the moments there.
bool momentsDisagree(const Analysis& analysis, const Eigen::VectorXd& g,
                     const std::vector<std::vector<double>>& std, const std::vector<bool>& held) {
    const Eigen::VectorXd step = -(freeInverse(analysis.jacobian, held) * g);
    const std::size_t width = std.front().size();
    for (std::size_t i = 0; i < held.size(); ++i)
        if (!held[i] &&
            !(std::abs(step[Eigen::Index(i)]) <= kMomentDisagreement * std[i / width][i % width]))
            return true;
    return false;
}

}  // namespace

// A minimum over the box on kd + ks = 1, least squares' (or the cross products', `cross`), moved
// to the unconstrained minimum's projection along the estimate's covariance (face_projection.h).
template <int P>
bool RoundSolver<P>::projectOntoFace(bool cross) {
    if (!onEnergyFace(params_)) return false;
    Eigen::VectorXd gradient;
    Eigen::MatrixXd gram;
    double squares = 0;
    const std::vector<double> y = params_.naturalCoordinates();
    objective_.leastSquaresSums(y.data(), leastSquaresWeights_, cross, squares, &gradient, &gram);
    // The scores alone: with no instruments the moment sums are left out.
    const Instruments<P> none;
    const Analysis there = phongfit::analyse(objective_, params_, &none, at_);
    return projectOntoEnergyFace(params_, gram,
                                 cross ? there.crossScores : there.leastSquaresScores, gradient);
}

// Least squares, or with a robust loss iteratively reweighted least squares: the first pass is
// plain least squares (from a far start most of a highlight would look like outliers), each next
// one weights the pixels by the loss at the last solution, until the solution stays put; the
// fixed point solves the robust estimating equations.
template <int P>
Analysis RoundSolver<P>::solveLeastSquares(RoundOutcome& out) {
    leastSquaresWeights_.clear();
    std::vector<Eigen::Matrix<double, P, 1>> weightPoint;  // where the weights were taken
    for (int pass = 1;; ++pass) {
        account(out,
                minimizeLeastSquares(objective_, params_, leastSquaresWeights_, false, options_));
        Analysis analysis = analyse();
        out.naturalStd = naturalStd(analysis.jacobian, analysis.scores);
        if (!objective_.robust() || pass >= kMaxPasses || stopping() ||
            (!weightPoint.empty() &&
             withinTolerance<P>(weightPoint, params_.naturalBlocks(),
                                noStd(params_.blockCount(), P), options_))) {
            if (!projectOntoFace(false)) return analysis;
            analysis = analyse();
            out.naturalStd = naturalStd(analysis.jacobian, analysis.scores);
            return analysis;
        }
        leastSquaresWeights_.assign(at_.weights[0].begin(), at_.weights[0].end());
        weightPoint = params_.naturalBlocks();
    }
}

// First the cross-product least squares, sum over pixels of r_A . r_B: unbiased, and a
// minimisation, which from the scan's basin finds the minimum where the moment equations can have
// spurious roots. Where the sum is not positive (noise outweighs the model's error) and has no
// minimum either (a thin crescent of partly covered pixels), pooled least squares is the anchor
// instead. Then the moment equations from there, instruments moved to each solution until it
// stays put. The moment solution is kept unless it does not settle or is clearly less precise
// than the anchor (kCrossPreference).
template <int P>
Analysis RoundSolver<P>::solveInstrumental(RoundOutcome& out) {
    const std::vector<double> before = params_.internal();
    anchor_.reset();
    account(out, minimizeLeastSquares(objective_, params_, leastSquaresWeights_, true, options_));
    const std::vector<double> y = params_.naturalCoordinates();
    double crossSum = 0;
    objective_.leastSquaresSums(y.data(), leastSquaresWeights_, true, crossSum, nullptr, nullptr);
    bool cross = crossSum > 0;
    if (!cross) {
        // The sum alone does not tell; whether the cross products have a minimum here does.
        Eigen::VectorXd gradient;
        Eigen::MatrixXd crossGram;
        objective_.leastSquaresSums(y.data(), leastSquaresWeights_, true, crossSum, &gradient,
                                    &crossGram);
        cross = positiveDefinite(crossGram, params_.heldFlags());
    }
    if (!cross) {
        params_.setInternal(before);
        account(out,
                minimizeLeastSquares(objective_, params_, leastSquaresWeights_, false, options_));
    }
    projectOntoFace(cross);
    const std::vector<double> anchorX = params_.internal();
    Analysis analysis = analyse();
    AnchorSandwich anchor{cross, anchorRecordingScores<P>(objective_, params_.naturalCoordinates(),
                                                          analysis.gram.rows(), cross)};
    const std::vector<std::vector<double>> anchorStd =
        naturalStd(cross ? analysis.crossGram : analysis.gram,
                   anchorScores(cross ? analysis.crossScores : analysis.leastSquaresScores,
                                anchor.recordings));
    instruments_.adopt(objective_, at_);
    std::vector<Eigen::Matrix<double, P, 1>> instrumentPoint = params_.naturalBlocks();
    const bool anchorConverged = out.solverConverged;
    const double anchorPrecision = precision(params_, anchorStd);
    // Nor do the passes start where the moment equations, instruments taken at the anchor, are
    // hopeless there and agree with the anchor (kMomentDisagreement).
    analysis = analyse();
    const std::vector<std::vector<double>> startStd =
        naturalStd(analysis.jacobian, analysis.scores);
    if (precision(params_, startStd) < kHopelessPrecision * anchorPrecision) {
        Eigen::VectorXd g;
        instruments_.momentSums(objective_, at_.y.data(), g, nullptr);
        if (!momentsDisagree(analysis, g, startStd, params_.heldFlags())) {
            out.naturalStd = anchorStd;
            anchor_ = std::move(anchor);
            return analysis;
        }
    }
    FitOptions notWalking;
    notWalking.tolerance = 0;
    notWalking.stdTolerance = kWalkingMove;
    int hopeless = 0;  // passes in a row below kHopelessPrecision, not walking
    for (int pass = 1;; ++pass) {
        const Minimized solved = minimizeMoments(objective_, params_, instruments_, options_);
        account(out, solved);
        analysis = analyse();
        out.naturalStd = naturalStd(analysis.jacobian, analysis.scores);
        const double momentPrecision = precision(params_, out.naturalStd);
        // A pass with no finite standard errors (precision 0) has nothing to walk by.
        const bool hopelessPass =
            momentPrecision < kHopelessPrecision * anchorPrecision &&
            (momentPrecision == 0 || withinTolerance<P>(instrumentPoint, params_.naturalBlocks(),
                                                        out.naturalStd, notWalking));
        hopeless = hopelessPass ? hopeless + 1 : 0;
        const bool settled = withinTolerance<P>(instrumentPoint, params_.naturalBlocks(),
                                                noStd(params_.blockCount(), P), options_);
        // A solve that crawled along a bound has no root in the box within reach: the anchor,
        // least squares' minimum over the box, stands.
        const bool blocked = !solved.converged && solved.onBound;
        if (!settled && !blocked && pass < kMaxPasses && hopeless < 2 && !stopping()) {
            instruments_.adopt(objective_, at_);
            instrumentPoint = params_.naturalBlocks();
            continue;
        }
        if (settled && momentPrecision >= kCrossPreference * anchorPrecision) return analysis;
        params_.setInternal(anchorX);
        out.naturalStd = anchorStd;
        anchor_ = std::move(anchor);
        out.solverConverged = anchorConverged;
        return analyse();
    }
}

template bool RoundSolver<kRgbBlock>::projectOntoFace(bool);
template bool RoundSolver<kGreyBlock>::projectOntoFace(bool);
template Analysis RoundSolver<kRgbBlock>::solveLeastSquares(RoundOutcome&);
template Analysis RoundSolver<kGreyBlock>::solveLeastSquares(RoundOutcome&);
template Analysis RoundSolver<kRgbBlock>::solveInstrumental(RoundOutcome&);
template Analysis RoundSolver<kGreyBlock>::solveInstrumental(RoundOutcome&);

}  // namespace phongfit
