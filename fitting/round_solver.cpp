#include "round_solver.h"

#include <algorithm>
#include <cmath>
#include <utility>

#include "holding.h"
#include "image_noise.h"
#include "precision_target.h"
#include "standard_errors.h"
#include "start_scan.h"

namespace phongfit {

template <int P>
RoundSolver<P>::RoundSolver(const std::vector<Observation>& observations,
                            const std::vector<PathSet>& first, const std::vector<PathSet>& second,
                            ParameterState<P>& params, const FitOptions& options, int threads,
                            bool firstRound, std::vector<bool> scanBroader)
    : params_(params),
      options_(options),
      instrumental_(options.estimator == Estimator::InstrumentalVariables),
      firstRound_(firstRound),
      scanBroader_(std::move(scanBroader)),
      objective_(observations, first, second, instrumental_, instrumental_ ? kInstrumentRadius : 0,
                 params.blockCount(), params.exposure(), options, threads) {}

template <int P>
RoundOutcome RoundSolver<P>::solve(const Estimate& theta) {
    const UsedPixels& prep = objective_.pixels();
    RoundOutcome out;
    // An n held at a start far off (100 for a true 10) leaves ks small there, but the next
    // round, recorded nearer the truth, can show the lobe.
    if (!firstRound_) params_.releaseExponents();
    for (int b = 0; b < params_.blockCount(); ++b)
        if (!prep.slotSeen[b]) params_.holdAll(b);
    params_.startAt(theta);
    const ExposureBlock& exposure = params_.exposure();
    if (firstRound_ && exposure.fitted() && !params_.held(exposure.slot()).n)
        matchExposure(objective_, params_);
    if (firstRound_ && options_.scanStart) scanExponents(objective_, params_);
    if (!firstRound_ && !scanBroader_.empty())
        scanBroaderExponents(objective_, params_, scanBroader_);
    solveHolding(out);
    return out;
}

template <int P>
bool RoundSolver<P>::confirmLobes(RoundOutcome& out,
                                  const std::vector<std::vector<double>>* ksStdFloor) {
    const FreeExponents unconfirmed{params_, out.naturalStd};
    const double unconfirmedSquares = analysis_.squares;
    if (!holdUnseenExponents(analysis_, params_, kLobeConfirmation, ksStdFloor)) return false;
    solveHolding(out, &unconfirmed);
    // A lobe whose n, held at its start, fits the images far worse was seen after all: its ks's
    // standard error was the recordings' noise (replayed far from where they were recorded), not
    // the lobe's absence. The round's solution stands.
    const double meanSquare =
        unconfirmedSquares / (3.0 * double(objective_.pixels().seeingMaterial));
    if (crossSquares(params_, analysis_.squares) -
            crossSquares(unconfirmed.params, unconfirmedSquares) <=
        kSeenLobeCost * meanSquare)
        return true;
    params_ = unconfirmed.params;
    solveHolding(out);
    return false;
}

template <int P>
void RoundSolver<P>::takeSharperNoise(RoundOutcome& out) {
    if (firstRound_) return;
    std::vector<double> logNStd;
    for (const MaterialFit& m : out.materials)
        logNStd.push_back(std::max(m.logNStd, m.logNImageStd));
    const std::vector<double> sharper =
        sharperLogNStd(objective_, at_.y, params_.held(), options_.renderedNoise, logNStd);
    for (std::size_t m = 0; m < sharper.size() && m < out.materials.size(); ++m)
        out.materials[m].logNSharperImageStd = sharper[m];
}

template <int P>
double RoundSolver<P>::crossSquares(const ParameterState<P>& at, double squares) {
    if (!instrumental_) return squares;
    const std::vector<double> y = at.naturalCoordinates();
    double sum = 0;
    objective_.leastSquaresSums(y.data(), leastSquaresWeights_, true, sum, nullptr, nullptr);
    return sum;
}

template <int P>
void RoundSolver<P>::solveHolding(RoundOutcome& out, const FreeExponents* free) {
    using L = BlockLayout<P>;
    const UsedPixels& prep = objective_.pixels();
    do {
        analysis_ = instrumental_ ? solveInstrumental(out) : solveLeastSquares(out);
        // What the images leave unconstrained is decided at the solution, not on the way.
    } while (holdUnconstrained(analysis_, prep, params_));
    for (int m = 0; free != nullptr && m < params_.materialCount(); ++m) {
        if (!params_.held(m).n || free->params.held(m).n) continue;
        for (int i = 0; i < L::kLogN; ++i)
            if (!params_.isHeld(m, i))
                out.naturalStd[m][i] = std::max(out.naturalStd[m][i], free->std[m][i]);
    }
    if (options_.precision > 0)
        out.pathShare = recordingShare(objective_, at_, instrumental_ ? &instruments_ : nullptr,
                                       analysis_, params_.held(), anchor_ ? &*anchor_ : nullptr);
    // Each solve makes its own instruments (as the round's first does, from none): they are not
    // held through the image noise's sums.
    instruments_ = {};
    out.materials.clear();
    const std::vector<std::vector<double>> imageNoise =
        // The first round, recorded at the start, is judged by the tolerance alone: its
        // estimate's pixels are not rendered anew.
        imageNoiseStd(objective_, at_.y, params_.held(),
                      firstRound_ ? RenderedNoise{} : options_.renderedNoise);
    for (int m = 0; m < params_.materialCount(); ++m) {
        MaterialFit& fit = out.materials.emplace_back(materialFit(params_, m, out.naturalStd[m]));
        const MaterialFit image = materialFit(params_, m, imageNoise[m]);
        fit.kdImageStd = image.kdStd;
        fit.ksImageStd = image.ksStd;
        fit.logNImageStd = image.logNStd;
        countImageNoise(params_, m, out, fit);
    }
    const ExposureBlock& exposure = params_.exposure();
    if (exposure.fitted()) out.exposure = exposureFit(params_, out.naturalStd[exposure.slot()]);
    out.rmse = std::sqrt(analysis_.squares / (3.0 * double(prep.seeingMaterial)));
    out.pixelsUsed = prep.pixels.size();
    out.leftOut = prep.leftOut;
}

template <int P>
Analysis RoundSolver<P>::analyse() {
    return phongfit::analyse(objective_, params_, instrumental_ ? &instruments_ : nullptr, at_);
}

template <int P>
std::vector<std::vector<double>> RoundSolver<P>::naturalStd(const Eigen::MatrixXd& jacobian,
                                                            const Eigen::MatrixXd& scores) const {
    return phongfit::naturalStd<P>(jacobian, scores, params_.held());
}

template <int P>
void RoundSolver<P>::account(RoundOutcome& out, const Minimized& m) const {
    out.iterations += m.iterations;
    out.minimizerSeconds += m.seconds;
    out.solverConverged = m.converged;
}

template class RoundSolver<kRgbBlock>;
template class RoundSolver<kGreyBlock>;

}  // namespace phongfit
