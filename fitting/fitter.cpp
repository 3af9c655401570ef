#include "fitter.h"

#include <ceres/ceres.h>
#include <fmt/format.h>
#include <sys/resource.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>
#include <tbb/task_arena.h>

#include <Eigen/Cholesky>
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <span>
#include <thread>

#include "box_manifold.h"
#include "convergence.h"
#include "error.h"
#include "exposure_block.h"
#include "fit_input.h"
#include "identifiability.h"
#include "least_squares_residual.h"
#include "material_params.h"
#include "moment_residual.h"
#include "pixel_sums.h"
#include "replay.h"
#include "replay_jacobian.h"
#include "round_paths.h"
#include "uncertainty.h"
#include "used_pixels.h"

namespace phongfit {

LossKind parseLoss(const std::string& name) {
    if (name == "l2") return LossKind::L2;
    if (name == "huber") return LossKind::Huber;
    if (name == "cauchy") return LossKind::Cauchy;
    throw Error(fmt::format("loss '{}' is unknown (allowed: l2, huber, cauchy)", name));
}

PhongMaterial MaterialFit::material() const {
    PhongMaterial m;
    m.kd = kd;
    m.ks = ks;
    m.n = n;
    return m;
}

namespace {

// Solves per round with the instruments (or least squares' robust weights) moved to the last
// solution (FitOptions::tolerance); a far start needs 3 or 4, the robust losses' weights a few
// more.
constexpr int kMaxPasses = 8;
// The moment solution is kept unless its precision (RoundSolver::precision) is below this
// fraction of the cross-product solution's: near-equal ones (exact data, where both are the least-
// squares solution) must not flip from one to the other on rounding.
constexpr double kCrossPreference = 0.5;
// Ceres' relative function tolerance for the moment equations, whose cost is 0 at the root.
constexpr double kMomentTolerance = 1e-10;
// Instruments are averaged over this many pixels on each side (RoundSolver::smoothed).
constexpr int kInstrumentRadius = 2;

double secondsSince(std::chrono::steady_clock::time_point start) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

std::size_t peakResidentBytes() {
    rusage usage{};
    getrusage(RUSAGE_SELF, &usage);
    return std::size_t(usage.ru_maxrss) * 1024;  // kilobytes on Linux
}

std::unique_ptr<ceres::LossFunction> makeLoss(const FitOptions& options, double meanObserved) {
    // Ceres' losses act on the squared norm of a pixel's RGB residual; `a` is in residual units.
    const double a = std::max(options.lossScale * meanObserved, 1e-12);
    switch (options.loss) {
        case LossKind::Huber:
            return std::make_unique<ceres::HuberLoss>(a);
        case LossKind::Cauchy:
            return std::make_unique<ceres::CauchyLoss>(a);
        case LossKind::L2:
            break;
    }
    return nullptr;
}

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

// The outcome of one round: the solution with its uncertainty and what the round cost.
struct RoundOutcome {
    std::vector<MaterialFit> materials;
    ExposureFit exposure;                         // with FitOptions::fitExposure
    std::vector<std::vector<double>> naturalStd;  // per slot, in natural coordinates
    double rmse = 0;
    int iterations = 0;
    double minimizerSeconds = 0;
    bool solverConverged = false;  // the round's last solve
    std::size_t pixelsUsed = 0;
    std::map<std::string, std::size_t> leftOut;
};

// Sums over pixels at one point in natural coordinates (per slot: kd, ks per colour group, log n).
// J is a pixel's weighted residual Jacobian in one set, rho' the robust loss' weight there, m the
// pixel's term of the estimating equations (W Z^T r summed over the two sets for instrumental
// variables, rho' J^T r for least squares).
struct Analysis {
    Eigen::MatrixXd gram;      // sum of rho' J^T J, averaged over the sets
    Eigen::MatrixXd jacobian;  // of the estimating equations: sum of W Z^T J (or the gram)
    Eigen::MatrixXd scores;    // sum of m m^T (uncertainty.h)
    // Sum of l l^T, l = rho' J^T r averaged over the sets: least squares' scores, which with the
    // gram give the standard errors that decide what is unconstrained.
    Eigen::MatrixXd leastSquaresScores;
    // With two sets A and B, the cross-product least squares' (RoundSolver::solveInstrumental)
    // sum of (J_A^T J_B + J_B^T J_A) / 2 and of c c^T, c = (J_A^T r_B + J_B^T r_A) / 2.
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

// Least squares' sum of squares and (if sized) its gradient and Gauss-Newton matrix, over pixels.
struct NormalSums {
    double squares = 0;
    Eigen::VectorXd gradient;
    Eigen::MatrixXd gramian;

    NormalSums& operator+=(const NormalSums& other) {
        squares += other.squares;
        gradient += other.gradient;
        gramian += other.gramian;
        return *this;
    }
};

// The estimating equations g and (if sized) dg/dy, summed over pixels.
struct MomentSums {
    Eigen::VectorXd g;
    Eigen::MatrixXd jacobian;

    MomentSums& operator+=(const MomentSums& other) {
        g += other.g;
        jacobian += other.jacobian;
        return *this;
    }
};

// The instruments' Gram matrix (sum of W Z^T Z, averaged over the sets), and the moments of the
// pixels that see no material, which do not depend on the parameters.
struct InstrumentSums {
    Eigen::MatrixXd gram;
    Eigen::VectorXd constantMoments;

    InstrumentSums& operator+=(const InstrumentSums& other) {
        gram += other.gram;
        constantMoments += other.constantMoments;
        return *this;
    }
};

struct Minimized {
    int iterations = 0;
    double seconds = 0;
    bool converged = true;  // Ceres stopped on a tolerance (nothing to solve counts)
};

// Solves one round on fixed path sets. P is the block size (RGB or grey).
template <int P>
class RoundSolver {
    using L = BlockLayout<P>;
    using NaturalVector = Eigen::Matrix<double, P, 1>;
    using Jacobian = Eigen::Matrix<double, 3, P>;

    // Per block of pixels: what replaying them needs.
    struct Scratch {
        std::vector<PhongParams<PackedJet>> jets;
        std::vector<PhongMaterial> plain;
        std::array<std::vector<Jacobian>, 2> jacobians;  // per set, per slot of the pixel
        Eigen::VectorXd moment;                          // P per slot of the pixel
        Eigen::MatrixXd momentJacobian;
        std::vector<Eigen::Index> indices;  // of the pixel's natural coordinates
        Eigen::VectorXd cross;
    };

public:
    // `start` holds the materials and, with FitOptions::fitExposure, the exposure as one more
    // slot (exposureSlot), whose start the first round sets (matchExposure). `firstRound`: match
    // the exposure and scan the exponents (FitOptions::scanStart).
    RoundSolver(const std::vector<Observation>& observations, const std::vector<PathSet>& first,
                const std::vector<PathSet>& second, std::vector<PhongMaterial>& start,
                const FitOptions& options, int threads, bool firstRound)
        : start_(start),
          options_(options),
          slots_(int(start.size())),
          exposureSlot_(options.fitExposure ? slots_ - 1 : -1),
          instrumental_(options.estimator == Estimator::InstrumentalVariables),
          firstRound_(firstRound),
          first_(&first),
          second_(&second),
          sets_(instrumental_ ? SetLists{&first, &second} : SetLists{&leastSquaresSets()}),
          prep_(selectUsedPixels(
              observations, sets_, slots_, instrumental_ ? kInstrumentRadius : 0,
              exposureSlot_ >= 0 ? ExposureBlock(exposureSlot_) : ExposureBlock())),
          loss_(makeLoss(options, prep_.meanObserved)),
          arena_(threads) {}

    // `theta` is the estimate to start from; `held` persists across rounds: the held kd and ks
    // stay held, a held n is tested again (see below).
    RoundOutcome solve(const std::vector<PhongMaterial>& theta, std::vector<HeldParams>& held) {
        RoundOutcome out;
        // Whether the images show a lobe is decided anew at each round's solution: an n held at
        // a start far off (100 for a true 10) leaves ks small there, but the next round, recorded
        // nearer the truth, can show the lobe.
        if (!firstRound_)
            for (int s = 0; s < materialSlots(); ++s) held[s].n = false;
        for (int s = 0; s < slots_; ++s)
            if (!prep_.slotSeen[s]) holdAll(held[s]);
        x_.assign(std::size_t(slots_) * P, 0.0);
        for (int s = 0; s < slots_; ++s) {
            NaturalVector y = naturalFromPhong<P>(theta[s]);
            const NaturalVector y0 = naturalFromPhong<P>(start_[s]);
            for (int i = 0; i < P; ++i)
                if (isHeld(held[s], i)) y[i] = y0[i];
            toInternal<P>(y.data(), held[s], block(s));
        }
        if (firstRound_ && exposureSlot_ >= 0 && !held[exposureSlot_].n) matchExposure(held);
        if (firstRound_ && options_.scanStart) scanExponents(held);
        Analysis analysis;
        do {
            analysis = instrumental_ ? solveInstrumental(held, out) : solveLeastSquares(held, out);
            // What the images leave unconstrained is decided at the solution, not on the way;
            // holding a parameter changes the problem, which is solved again.
        } while (hold(findUnconstrained(analysis.gram, 3.0 * double(prep_.seeingMaterial),
                                        prep_.rmsObserved, heldFlags(held)),
                      held) ||
                 holdUnseenExponents(analysis, held));
        for (int s = 0; s < materialSlots(); ++s)
            out.materials.push_back(materialFit(s, held[s], out.naturalStd[s]));
        if (exposureSlot_ >= 0) {
            const NaturalVector y = naturalBlocks(held)[exposureSlot_];
            out.exposure.value = std::exp(y[L::kLogN]) / kExposureCentre;
            out.exposure.std = out.exposure.value * out.naturalStd[exposureSlot_][L::kLogN];
            out.exposure.unconstrained = held[exposureSlot_].n;
        }
        out.rmse = std::sqrt(analysis.squares / (3.0 * double(prep_.seeingMaterial)));
        out.pixelsUsed = prep_.pixels.size();
        out.leftOut = prep_.leftOut;
        return out;
    }

private:
    void account(RoundOutcome& out, const Minimized& m) const {
        out.iterations += m.iterations;
        out.minimizerSeconds += m.seconds;
        out.solverConverged = m.converged;
    }

    // Least squares, or with a robust loss iteratively reweighted least squares: the first pass
    // is plain least squares (from a far start most of a highlight would look like outliers),
    // each next one weights the pixels by the loss at the last solution, until the solution stays
    // put; the fixed point solves the robust estimating equations.
    Analysis solveLeastSquares(const std::vector<HeldParams>& held, RoundOutcome& out) {
        leastSquaresWeights_.clear();
        std::vector<NaturalVector> weightPoint;  // where the weights were taken; empty: all 1
        for (int pass = 1;; ++pass) {
            account(out, minimizeLeastSquares(held));
            Analysis analysis = analyse(held);
            out.naturalStd = naturalStd(analysis.jacobian, analysis.scores, held);
            if (!loss_ || pass >= kMaxPasses || stopping() ||
                (!weightPoint.empty() &&
                 withinTolerance<P>(weightPoint, naturalBlocks(held), noStd(), options_)))
                return analysis;
            leastSquaresWeights_ = weights_[0];
            weightPoint = naturalBlocks(held);
        }
    }

    // The cross-product least squares first: sum over pixels of r_A . r_B, whose expectation is
    // the least-squares objective without the recordings' noise (E r_A . r_B = |E r|^2 for
    // independent sets), so unlike least squares on either set or their mean it is not biased
    // towards 0, and it is a minimisation: from the scan's basin it finds the minimum, where the
    // moment equations can have spurious roots. Its stationary point is the moment solution with
    // each set's own noisy Jacobian as the other's instruments, which costs precision at few
    // samples per pixel. Then the instrumental-variables solve from there, instruments moved to
    // each solution until it stays put (the estimate is consistent whatever the instruments;
    // instruments at the estimate make it efficient and robust weights there robust). Both
    // estimates are consistent: the round keeps the moment solution unless the cross-product one
    // is clearly more precise (kCrossPreference) or the moment solutions do not settle. The moments
    // win on large images at few samples (the Cornell demo at 4 paths per pixel: 2x smaller
    // errors); on small ones their smoothed instruments blur the highlight and the solutions wander
    // (the Cornell box at 64 x 64: n from 30 to 142 in one round) while the cross products hold.
    Analysis solveInstrumental(const std::vector<HeldParams>& held, RoundOutcome& out) {
        const std::vector<double> before = x_;
        cross_ = true;
        account(out, minimizeLeastSquares(held));
        const std::vector<double> y = naturalCoordinates(held);
        double crossSum = 0;
        leastSquaresSums(y.data(), crossSum, nullptr, nullptr);
        cross_ = false;
        // Where the two sets' noise outweighs the model's error (a thin crescent of partly
        // covered pixels at 4 paths) the sum of cross products can be driven below 0: no longer
        // an objective, its minimum is noise (kd 0.95 for a true 0.31 was seen). Least squares on
        // the pooled sets is the anchor then: biased towards 0 at few samples, but bounded.
        const bool cross = crossSum > 0;
        if (!cross) {
            x_ = before;
            account(out, minimizeLeastSquares(held));
        }
        const std::vector<double> anchorX = x_;
        Analysis analysis = analyse(held);
        const std::vector<std::vector<double>> anchorStd =
            cross ? naturalStd(analysis.crossGram, analysis.crossScores, held)
                  : naturalStd(analysis.gram, analysis.leastSquaresScores, held);
        adoptInstruments();
        std::vector<NaturalVector> instrumentPoint = naturalBlocks(held);
        for (int pass = 1;; ++pass) {
            account(out, minimizeMoments(held));
            analysis = analyse(held);
            out.naturalStd = naturalStd(analysis.jacobian, analysis.scores, held);
            const bool settled =
                withinTolerance<P>(instrumentPoint, naturalBlocks(held), noStd(), options_);
            if (!settled && pass < kMaxPasses && !stopping()) {
                adoptInstruments();
                instrumentPoint = naturalBlocks(held);
                continue;
            }
            if (settled &&
                precision(out.naturalStd, held) >= kCrossPreference * precision(anchorStd, held))
                return analysis;
            x_ = anchorX;
            out.naturalStd = anchorStd;
            return analyse(held);
        }
    }

    std::vector<std::vector<double>> noStd() const {
        return std::vector<std::vector<double>>(slots_, std::vector<double>(P, 0.0));
    }

    // 1 / the sum of the free parameters' relative variances (log n absolute), 0 if one of them
    // has no finite positive standard error.
    double precision(const std::vector<std::vector<double>>& stdNatural,
                     const std::vector<HeldParams>& held) {
        double sum = 0;
        for (int s = 0; s < slots_; ++s) {
            NaturalVector y;
            toNatural<P>(block(s), held[s], y.data());
            for (int i = 0; i < P; ++i) {
                if (isHeld(held[s], i)) continue;
                const double sd = stdNatural[std::size_t(s)][std::size_t(i)];
                if (!(sd > 0) || !std::isfinite(sd)) return 0;
                const double scale =
                    i == L::kLogN ? 1.0 : std::max(std::abs(y[i]), kReflectanceFloor);
                sum += sd * sd / (scale * scale);
            }
        }
        return sum > 0 ? 1 / sum : 0;
    }

    // The sets least squares replays: exact sets (the same list passed twice) as they are, else
    // the two recordings pooled, built on first use: the instrumental-variables rounds need them
    // only for the exponent scan, the exposure match and the fallback anchor.
    const std::vector<PathSet>& leastSquaresSets() {
        if (first_ == second_) return *first_;
        if (pooled_.empty())
            for (std::size_t v = 0; v < first_->size(); ++v)
                pooled_.push_back(pool((*first_)[v], (*second_)[v]));
        return pooled_;
    }

    double* block(int s) { return x_.data() + std::size_t(s) * P; }

    int materialSlots() const { return exposureSlot_ >= 0 ? slots_ - 1 : slots_; }

    // Every slot's natural coordinates, P per slot, as the sums over pixels take them.
    std::vector<double> naturalCoordinates(const std::vector<HeldParams>& held) {
        std::vector<double> y(std::size_t(slots_) * P);
        for (int s = 0; s < slots_; ++s)
            toNatural<P>(block(s), held[s], y.data() + std::size_t(s) * P);
        return y;
    }

    // The exposure at natural coordinates y (1 when it is not fitted).
    double exposure(const double* y) const {
        if (exposureSlot_ < 0) return 1;
        return std::exp(y[std::size_t(exposureSlot_) * P + L::kLogN]) / kExposureCentre;
    }

    // The exposure s that fits the images best with the materials where they are: least squares
    // in s alone is linear, s = <I, y> / <I, I> over the weighted pixels (one Gauss-Newton step in
    // log s from anywhere lands there). It is also the value the exposure is held at if the images
    // do not constrain it (FitOptions::fitExposure).
    void matchExposure(const std::vector<HeldParams>& held) {
        std::vector<double> y = naturalCoordinates(held);
        double squares = 0;
        Eigen::VectorXd gradient;
        Eigen::MatrixXd gramian;
        leastSquaresSums(y.data(), squares, &gradient, &gramian);
        const Eigen::Index e = Eigen::Index(exposureSlot_) * P + L::kLogN;
        // With s I the weighted prediction: gradient = <sI, sI - y>, gramian = <sI, sI>.
        const double predicted = gramian(e, e), product = predicted - gradient[e];
        if (!(predicted > 0) || !(product > 0))
            throw Error(fmt::format(
                "--fit-exposure: the {} where a fitted material is seen (nothing to scale)",
                predicted > 0 ? "images are black" : "start materials render black"));
        const double s = exposure(y.data()) * product / predicted;
        if (!(s >= kMinExposure && s <= kMaxExposure))
            throw Error(fmt::format(
                "--fit-exposure: the images are {:.3g} times as bright as the scene renders them "
                "at the start (allowed: {:.3g} to {:.3g}; scale the emitters)",
                s, kMinExposure, kMaxExposure));
        start_[exposureSlot_].n = s * kExposureCentre;
        y[std::size_t(e)] = std::log(s * kExposureCentre);
        toInternal<P>(y.data() + std::size_t(exposureSlot_) * P, held[exposureSlot_],
                      block(exposureSlot_));
    }

    std::span<const std::uint32_t> pixelSlots(const UsedPixel& u) const {
        return {prep_.slots.data() + u.slotBegin, u.slotCount};
    }

    static bool isHeld(const HeldParams& h, int i) {
        if (i == L::kLogN) return h.n;
        return i < L::kGroups ? h.kd[i] : h.ks[i - L::kGroups];
    }

    static void holdAll(HeldParams& h) {
        h.kd.fill(true);
        h.ks.fill(true);
        h.n = true;
    }

    std::vector<bool> heldFlags(const std::vector<HeldParams>& held) const {
        std::vector<bool> flags(std::size_t(slots_) * P);
        for (int s = 0; s < slots_; ++s)
            for (int i = 0; i < P; ++i) flags[std::size_t(s) * P + i] = isHeld(held[s], i);
        return flags;
    }

    std::vector<NaturalVector> naturalBlocks(const std::vector<HeldParams>& held) {
        std::vector<NaturalVector> y(slots_);
        for (int s = 0; s < slots_; ++s) toNatural<P>(block(s), held[s], y[s].data());
        return y;
    }

    // Holds the natural parameters `indices` (slot * P + i) at their start values, keeping the
    // other parameters of the slot where they are. True if any was not held before.
    bool hold(const std::vector<int>& indices, std::vector<HeldParams>& held) {
        bool changed = false;
        for (int index : indices) {
            const int s = index / P, i = index % P;
            if (isHeld(held[s], i)) continue;
            changed = true;
            if (s == exposureSlot_) {
                holdExposure(held);
                continue;
            }
            NaturalVector y;
            toNatural<P>(block(s), held[s], y.data());
            y[i] = naturalFromPhong<P>(start_[s])[i];
            if (i == L::kLogN)
                held[s].n = true;
            else if (i < L::kGroups)
                held[s].kd[i] = true;
            else
                held[s].ks[i - L::kGroups] = true;
            toInternal<P>(y.data(), held[s], block(s));
        }
        return changed;
    }

    // An exposure the images do not constrain trades against the scale of every kd and ks: only
    // the products s kd and s ks are seen. It is held at the start (matchExposure), or higher where
    // kd + ks would otherwise exceed 1, and the materials are rescaled to keep the products.
    void holdExposure(std::vector<HeldParams>& held) {
        std::vector<NaturalVector> y = naturalBlocks(held);
        NaturalVector& e = y[exposureSlot_];
        const double current = std::exp(e[L::kLogN]) / kExposureCentre;
        double highest = 0;  // of kd + ks over the materials' colour groups
        for (int m = 0; m < materialSlots(); ++m)
            for (int g = 0; g < L::kGroups; ++g)
                highest = std::max(highest, y[m][L::diffuse(g)] + y[m][L::specular(g)]);
        const double s = std::max(start_[exposureSlot_].n / kExposureCentre, current * highest);
        for (int m = 0; m < materialSlots(); ++m) {
            for (int i = 0; i < L::kLogN; ++i)
                if (!isHeld(held[m], i)) y[m][i] *= current / s;
            toInternal<P>(y[m].data(), held[m], block(m));
        }
        held[exposureSlot_].n = true;
        start_[exposureSlot_].n = s * kExposureCentre;
        e[L::kLogN] = std::log(start_[exposureSlot_].n);
        toInternal<P>(e.data(), held[exposureSlot_], block(exposureSlot_));
    }

    // n only shapes the lobe: when no group's ks is significantly above 0 (or every ks is held),
    // the images do not constrain n. The standard errors are least squares' (weak instruments'
    // can be anything), with every material's n held: n has no effect at ks = 0, the hypothesis
    // tested, and with n free they would count the trade-off between ks and n that only a lobe
    // has. Where the lobe is seen through few pixels (a grazing crescent, a lobe narrower than a
    // pixel) ks and log n correlate to 0.98 and more: ks 0.49 was 1.7 standard errors with n free
    // and 13 with n held, and n was held for a lobe the images plainly show.
    bool holdUnseenExponents(const Analysis& analysis, std::vector<HeldParams>& held) {
        std::vector<HeldParams> exponentsHeld = held;
        for (int s = 0; s < materialSlots(); ++s) exponentsHeld[s].n = true;
        const std::vector<std::vector<double>> stdNatural =
            naturalStd(analysis.gram, analysis.leastSquaresScores, exponentsHeld);
        std::vector<int> indices;
        for (int s = 0; s < materialSlots(); ++s) {
            if (held[s].n) continue;
            NaturalVector y;
            toNatural<P>(block(s), held[s], y.data());
            std::vector<double> ks, ksStd;
            for (int g = 0; g < L::kGroups; ++g) {
                if (held[s].ks[g]) continue;
                ks.push_back(y[L::specular(g)]);
                ksStd.push_back(stdNatural[s][L::specular(g)]);
            }
            if (!lobeDetected(ks, ksStd)) indices.push_back(s * P + L::kLogN);
        }
        return hold(indices, held);
    }

    // Adds the blocks of the slots some pixel sees, with their bounds and held coordinates;
    // returns the number of free coordinates.
    int addParameterBlocks(ceres::Problem& problem, const std::vector<HeldParams>& held,
                           std::vector<std::uint32_t>& blockSlots, std::vector<double*>& blocks) {
        int freeCount = 0;
        for (int s = 0; s < slots_; ++s) {
            if (!prep_.slotSeen[s]) continue;
            double* x = block(s);
            problem.AddParameterBlock(x, P);
            blockSlots.push_back(std::uint32_t(s));
            blocks.push_back(x);
            const std::vector<int> constant = heldCoordinates<P>(held[s]);
            if (int(constant.size()) == P) {
                problem.SetParameterBlockConstant(x);
            } else {
                std::vector<double> lower(P), upper(P);
                internalBounds<P>(held[s], x, lower.data(), upper.data());
                std::vector<bool> fixed(P, false);
                for (int i : constant) fixed[i] = true;
                problem.SetManifold(x, new BoxManifold(lower, upper, fixed));
            }
            freeCount += P - int(constant.size());
        }
        return freeCount;
    }

    // FitOptions::scanStart, one slot after the other. For each exponent on the grid, kd and ks
    // take one Gauss-Newton step from where they are (with n there), then the least-squares cost
    // is compared. The step is exact where every recorded term has one vertex on the material,
    // as under direct light: I is then linear in kd and ks; bounds are then imposed by clamping.
    void scanExponents(const std::vector<HeldParams>& held) {
        std::vector<double> y = naturalCoordinates(held), trial, best;
        std::vector<double> grid;
        for (double n = 1; n < kMaxExponent; n *= 4) grid.push_back(std::log(n));
        grid.push_back(std::log(kMaxExponent));
        for (int s = 0; s < materialSlots(); ++s) {
            if (held[s].n || !prep_.slotSeen[s]) continue;
            const std::size_t at = std::size_t(s) * P;
            std::vector<int> reflectances;  // free kd and ks coordinates of the slot
            for (int i = 0; i < L::kLogN; ++i)
                if (!isHeld(held[s], i)) reflectances.push_back(int(at) + i);
            double bestCost = std::numeric_limits<double>::infinity();
            // The start competes first, and another exponent must do better by more than
            // rounding: where the images show no lobe (ks = 0) every exponent fits equally well,
            // and one whose lobe misses every pixel would leave ks unconstrained.
            grid.insert(grid.begin(), y[at + L::kLogN]);
            const double margin =
                1e-9 * 3.0 * double(prep_.seeingMaterial) * prep_.rmsObserved * prep_.rmsObserved;
            for (double logN : grid) {
                trial = y;
                trial[at + L::kLogN] = logN;
                if (!reflectances.empty()) {
                    double squares = 0;
                    Eigen::VectorXd gradient;
                    Eigen::MatrixXd gramian;
                    leastSquaresSums(trial.data(), squares, &gradient, &gramian);
                    Eigen::MatrixXd h = gramian(reflectances, reflectances);
                    h.diagonal().array() += 1e-12 * (h.diagonal().maxCoeff() + 1e-300);
                    const Eigen::VectorXd step = h.ldlt().solve(-gradient(reflectances));
                    for (std::size_t k = 0; k < reflectances.size(); ++k)
                        if (std::isfinite(step[Eigen::Index(k)]))
                            trial[std::size_t(reflectances[k])] += step[Eigen::Index(k)];
                    clampReflectances(trial.data() + at, held[s]);
                }
                double cost = 0;
                leastSquaresSums(trial.data(), cost, nullptr, nullptr);
                if (cost < bestCost - margin) bestCost = cost, best = trial;
            }
            grid.erase(grid.begin());
            y = best;
            toInternal<P>(y.data() + at, held[s], block(s));
        }
    }

    // kd, ks >= 0 and kd + ks <= 1 per colour group, by clamping natural coordinates; a held kd
    // stays and bounds ks instead.
    static void clampReflectances(double* y, const HeldParams& held) {
        for (int g = 0; g < L::kGroups; ++g) {
            double& kd = y[L::diffuse(g)];
            double& ks = y[L::specular(g)];
            ks = std::clamp(ks, 0.0, held.kd[g] ? 1.0 - kd : 1.0);
            if (!held.kd[g]) kd = std::clamp(kd, 0.0, 1.0 - ks);
        }
    }

    Minimized minimizeMoments(const std::vector<HeldParams>& held) {
        ceres::Problem problem;
        std::vector<std::uint32_t> blockSlots;
        std::vector<double*> blocks;
        if (addParameterBlocks(problem, held, blockSlots, blocks) == 0) return {};
        const std::vector<int> free = freeIndices(held, blockSlots);
        const auto moments = [this](const double* y, Eigen::VectorXd& g, Eigen::MatrixXd* dg) {
            momentSums(y, g, dg);
        };
        problem.AddResidualBlock(
            new MomentResidual<P>(moments, blockSlots, held, free, whitening(free)), nullptr,
            blocks);
        // One small dense block: the time is in the pixel sums, which run in parallel already.
        return run(problem, ceres::Solver::Options().initial_trust_region_radius, kMomentTolerance);
    }

    bool stopping() const { return options_.stopRequested && options_.stopRequested(); }

    // The natural coordinates slot * P + i of the blocks' slots that are not held.
    std::vector<int> freeIndices(const std::vector<HeldParams>& held,
                                 const std::vector<std::uint32_t>& blockSlots) const {
        std::vector<int> free;
        for (std::uint32_t s : blockSlots)
            for (int i = 0; i < P; ++i)
                if (!isHeld(held[s], i)) free.push_back(int(s) * P + i);
        return free;
    }

    Minimized minimizeLeastSquares(const std::vector<HeldParams>& held) {
        ceres::Problem problem;
        std::vector<std::uint32_t> blockSlots;
        std::vector<double*> blocks;
        if (addParameterBlocks(problem, held, blockSlots, blocks) == 0) return {};
        const auto sums = [this](const double* y, double& squares, Eigen::VectorXd* gradient,
                                 Eigen::MatrixXd* gramian) {
            leastSquaresSums(y, squares, gradient, gramian);
        };
        problem.AddResidualBlock(
            new LeastSquaresResidual<P>(sums, blockSlots, held, freeIndices(held, blockSlots)),
            nullptr, blocks);
        // A far start's first Gauss-Newton step can jump log n to its bound, where the lobe is
        // invisible and the diffuse part alone fits better than at the start: a dead end (n = 0.3
        // for a true 30 went to 1e6). Start with steps that change log n by about 1 at most.
        // Stop once a step changes the cost by less than moving a tenth of a standard error does:
        // with cost C at the minimum over N residuals, k standard errors cost about k^2 C / N
        // more. Where the model does not fit exactly (photographs) Gauss-Newton converges only
        // linearly, each step about half the last, and a fixed tolerance of 1e-10 took 12 steps
        // on the DiLiGenT ball where 8 reach that.
        const double residuals = 3.0 * double(prep_.seeingMaterial);
        return run(problem, 1.0, std::max(kMomentTolerance, 0.01 / residuals));
    }

    // One small dense residual block: the time is in its pixel sums, which run in parallel.
    // `initialRadius`: Ceres' initial trust region radius, in its Jacobi-scaled coordinates;
    // `functionTolerance`: the relative cost change it stops at.
    Minimized run(ceres::Problem& problem, double initialRadius, double functionTolerance) {
        ceres::Solver::Options solverOptions;
        solverOptions.linear_solver_type = ceres::DENSE_QR;
        // Dogleg reuses one factorization across rejected steps, which the far starts (n off by
        // 100x) produce several of; measured 2x fewer Jacobian evaluations than
        // Levenberg-Marquardt.
        solverOptions.trust_region_strategy_type = ceres::DOGLEG;
        solverOptions.initial_trust_region_radius = initialRadius;
        solverOptions.max_num_iterations = options_.maxIterations;
        solverOptions.function_tolerance = functionTolerance;
        solverOptions.parameter_tolerance = 1e-10;
        solverOptions.logging_type =
            options_.verbose ? ceres::PER_MINIMIZER_ITERATION : ceres::SILENT;
        solverOptions.minimizer_progress_to_stdout = options_.verbose;
        StopCallback stop(options_.stopRequested);
        if (options_.stopRequested) solverOptions.callbacks.push_back(&stop);
        ceres::Solver::Summary summary;
        ceres::Solve(solverOptions, &problem, &summary);
        if (options_.verbose) fmt::print(stderr, "{}\n", summary.BriefReport());
        if (!summary.IsSolutionUsable())
            throw Error(fmt::format("the fit failed: {}", summary.message));
        return {summary.num_successful_steps + summary.num_unsuccessful_steps,
                summary.minimizer_time_in_seconds, summary.termination_type == ceres::CONVERGENCE};
    }

    // L^-1 with L L^T the Gram matrix of the instruments over the free natural coordinates.
    Eigen::MatrixXd whitening(const std::vector<int>& free) const {
        Eigen::MatrixXd gram = instrumentGram_(free, free);
        const Eigen::Index n = gram.rows();
        // An instrument that is 0 at every pixel makes its equation 0 everywhere; any scale does.
        for (Eigen::Index i = 0; i < n; ++i)
            if (!(gram(i, i) > 0)) gram(i, i) = 1;
        const Eigen::VectorXd scale = gram.diagonal().cwiseSqrt().cwiseInverse();
        Eigen::MatrixXd correlation = scale.asDiagonal() * gram * scale.asDiagonal();
        // Collinear instruments: found unconstrained and held after this solve.
        correlation.diagonal().array() += 1e-12;
        const Eigen::LLT<Eigen::MatrixXd> llt(correlation);
        return llt.matrixL().solve(Eigen::MatrixXd(scale.asDiagonal()));
    }

    double lossWeight(double squaredNorm) const {
        double rho[3] = {0, 1, 0};
        if (loss_) loss_->Evaluate(squaredNorm, rho);
        return rho[1];
    }

    // The weighted residual weight (I(y) - observed) of pixel u in set k; with `jacobians`, also
    // its weighted Jacobians per slot of the pixel, in scratch.jacobians[k].
    Eigen::Vector3d residual(int k, const UsedPixel& u, const double* y, Scratch& scratch,
                             bool jacobians) const {
        return residual((*sets_[k])[u.view], u, y, scratch,
                        jacobians ? &scratch.jacobians[k] : nullptr);
    }

    // The exposure slot, the last of a pixel's slots when it is fitted, is not replayed: the
    // prediction is s I and its derivative with respect to log s is s I.
    Eigen::Vector3d residual(const PathSet& paths, const UsedPixel& u, const double* y,
                             Scratch& scratch, std::vector<Jacobian>* jacobians) const {
        const std::span<const std::uint32_t> slots = pixelSlots(u);
        const bool exposed =
            exposureSlot_ >= 0 && !slots.empty() && slots.back() == std::uint32_t(exposureSlot_);
        const std::span<const std::uint32_t> materials = slots.first(slots.size() - exposed);
        const double s = exposure(y);
        Color3 predicted = Color3::Zero();
        if (jacobians != nullptr) jacobians->resize(u.slotCount);
        if (jacobians != nullptr && !materials.empty()) {
            std::vector<Jacobian>& j = *jacobians;
            for (std::size_t b = 0; b < materials.size(); ++b) {
                predicted = replayNaturalJacobian<P>(paths, u.pixel, materials, y, materials[b],
                                                     scratch.jets, j[b]);
                j[b] *= u.weight * s;
            }
        } else {
            for (std::uint32_t m : materials)
                scratch.plain[m] = naturalToPhong<P>(y + std::size_t(m) * P);
            predicted = replayPixel(paths, u.pixel, scratch.plain.data());
        }
        if (jacobians != nullptr && exposed) {
            Jacobian& j = (*jacobians)[u.slotCount - 1];
            j.setZero();
            j.col(L::kLogN) = u.weight * s * predicted.matrix();
        }
        return (u.weight * (s * predicted - u.observed)).matrix();
    }

    // Sum over the first `count` used pixels of body(pixel index, sum, scratch), in parallel,
    // deterministically.
    template <typename Value, typename Body>
    Value sumOverPixels(std::size_t count, const Value& zero, const Body& body) {
        return phongfit::sumOverPixels(
            arena_, count, zero,
            [this] {
                Scratch scratch;
                scratch.jets.resize(slots_);
                scratch.plain.resize(slots_);
                return scratch;
            },
            body);
    }

    // Sum over the pixels that see a material (the others' residuals do not depend on y) of
    // w |r|^2, with w the robust weights of the last reweighting (1 before any), and of w J^T r
    // and w J^T J if asked.
    void leastSquaresSums(const double* y, double& squares, Eigen::VectorXd* gradient,
                          Eigen::MatrixXd* gramian) {
        const Eigen::Index size = Eigen::Index(slots_) * P;
        const bool withJacobian = gradient != nullptr;
        const NormalSums zero{0.0, withJacobian ? Eigen::VectorXd::Zero(size) : Eigen::VectorXd(),
                              withJacobian ? Eigen::MatrixXd::Zero(size, size) : Eigen::MatrixXd()};
        const std::vector<PathSet>& replayed = cross_ ? *first_ : leastSquaresSets();
        NormalSums sums = sumOverPixels(
            prep_.seeingMaterial, zero, [&](std::size_t i, NormalSums& sum, Scratch& scratch) {
                const UsedPixel& u = prep_.pixels[i];
                const double w = leastSquaresWeights_.empty() ? 1.0 : leastSquaresWeights_[i];
                if (cross_) {
                    const Eigen::Vector3d ra = residual(0, u, y, scratch, withJacobian);
                    const Eigen::Vector3d rb = residual(1, u, y, scratch, withJacobian);
                    sum.squares += w * ra.dot(rb);
                    if (!withJacobian) return;
                    const std::span<const std::uint32_t> slots = pixelSlots(u);
                    const std::vector<Jacobian>& ja = scratch.jacobians[0];
                    const std::vector<Jacobian>& jb = scratch.jacobians[1];
                    for (std::uint32_t a = 0; a < u.slotCount; ++a) {
                        const Eigen::Index row = Eigen::Index(slots[a]) * P;
                        addPackedGradient<P>(sum.gradient.template segment<P>(row), 0.5 * w, ja[a],
                                             rb);
                        addPackedGradient<P>(sum.gradient.template segment<P>(row), 0.5 * w, jb[a],
                                             ra);
                        for (std::uint32_t b = 0; b < u.slotCount; ++b) {
                            addPackedGram<P>(
                                sum.gramian.template block<P, P>(row, Eigen::Index(slots[b]) * P),
                                0.5 * w, ja[a], jb[b]);
                            addPackedGram<P>(
                                sum.gramian.template block<P, P>(row, Eigen::Index(slots[b]) * P),
                                0.5 * w, jb[a], ja[b]);
                        }
                    }
                    return;
                }
                std::vector<Jacobian>& j = scratch.jacobians[0];
                const Eigen::Vector3d r =
                    residual(replayed[u.view], u, y, scratch, withJacobian ? &j : nullptr);
                sum.squares += w * r.squaredNorm();
                if (!withJacobian) return;
                const std::span<const std::uint32_t> slots = pixelSlots(u);
                for (std::uint32_t a = 0; a < u.slotCount; ++a) {
                    const Eigen::Index row = Eigen::Index(slots[a]) * P;
                    addPackedGradient<P>(sum.gradient.template segment<P>(row), w, j[a], r);
                    for (std::uint32_t b = 0; b < u.slotCount; ++b)
                        addPackedGram<P>(
                            sum.gramian.template block<P, P>(row, Eigen::Index(slots[b]) * P), w,
                            j[a], j[b]);
                }
            });
        squares = sums.squares;
        if (!withJacobian) return;
        *gradient = std::move(sums.gradient);
        *gramian = std::move(sums.gramian);
    }

    // g(y) = sum over pixels and sets k of W_other Z_other^T r_k(y), and dg/dy if asked.
    void momentSums(const double* y, Eigen::VectorXd& g, Eigen::MatrixXd* jacobian) {
        const Eigen::Index size = Eigen::Index(slots_) * P;
        const bool withJacobian = jacobian != nullptr;
        const MomentSums zero{Eigen::VectorXd::Zero(size),
                              withJacobian ? Eigen::MatrixXd::Zero(size, size) : Eigen::MatrixXd()};
        MomentSums sums = sumOverPixels(
            prep_.seeingMaterial, zero, [&](std::size_t i, MomentSums& sum, Scratch& scratch) {
                const UsedPixel& u = prep_.pixels[i];
                const std::span<const std::uint32_t> slots = pixelSlots(u);
                for (int k = 0; k < 2; ++k) {
                    const int other = 1 - k;
                    const Eigen::Vector3d r = residual(k, u, y, scratch, withJacobian);
                    const double w = lossWeights_[other][i];
                    for (std::uint32_t a = 0; a < u.slotCount; ++a) {
                        const Jacobian z = w * instruments_[other][u.slotBegin + a];
                        const Eigen::Index row = Eigen::Index(slots[a]) * P;
                        addPackedGradient<P>(sum.g.template segment<P>(row), 1.0, z, r);
                        if (!withJacobian) continue;
                        for (std::uint32_t b = 0; b < u.slotCount; ++b)
                            addPackedGram<P>(
                                sum.jacobian.template block<P, P>(row, Eigen::Index(slots[b]) * P),
                                1.0, z, scratch.jacobians[k][b]);
                    }
                }
            });
        g = sums.g + constantMoments_;
        if (withJacobian) *jacobian = std::move(sums.jacobian);
    }

    // The sums at the current estimate (see Analysis). Keeps each set's Jacobians, residuals and
    // loss weights there: the next instruments, and what the scores are computed from.
    Analysis analyse(const std::vector<HeldParams>& held) {
        const std::vector<double> y = naturalCoordinates(held);
        const int sets = int(sets_.size());
        const bool moments = !instrumental_ || !instruments_[0].empty();
        for (int k = 0; k < sets; ++k) {
            jacobians_[k].resize(prep_.slots.size());
            residuals_[k].resize(prep_.pixels.size());
            weights_[k].resize(prep_.pixels.size());
        }
        const Eigen::Index size = Eigen::Index(slots_) * P;
        const Eigen::MatrixXd zeros = Eigen::MatrixXd::Zero(size, size);
        const Analysis zero{zeros, zeros, Eigen::MatrixXd(), zeros, zeros, zeros, 0.0};
        Analysis result = sumOverPixels(
            prep_.pixels.size(), zero, [&](std::size_t i, Analysis& sum, Scratch& scratch) {
                const UsedPixel& u = prep_.pixels[i];
                const std::span<const std::uint32_t> slots = pixelSlots(u);
                const auto at = [&](std::uint32_t a) { return Eigen::Index(slots[a]) * P; };
                Eigen::Vector3d mean = Eigen::Vector3d::Zero();
                Eigen::VectorXd& l = scratch.moment;
                l.setZero(Eigen::Index(u.slotCount) * P);
                for (int k = 0; k < sets; ++k) {
                    const Eigen::Vector3d r = residual(k, u, y.data(), scratch, true);
                    const std::vector<Jacobian>& j = scratch.jacobians[k];
                    const double rho = lossWeight(r.squaredNorm());
                    residuals_[k][i] = r;
                    weights_[k][i] = rho;
                    mean += r / sets;
                    for (std::uint32_t a = 0; a < u.slotCount; ++a) {
                        jacobians_[k][u.slotBegin + a] = j[a];
                        addPackedGradient<P>(l.segment<P>(Eigen::Index(a) * P), rho / sets, j[a],
                                             r);
                        for (std::uint32_t b = 0; u.seesMaterial && b < u.slotCount; ++b)
                            addPackedGram<P>(sum.gram.block<P, P>(at(a), at(b)), rho / sets, j[a],
                                             j[b]);
                    }
                }
                if (!u.seesMaterial) return;
                sum.squares += mean.squaredNorm() / (u.weight * u.weight);
                for (std::uint32_t a = 0; a < u.slotCount; ++a)
                    for (std::uint32_t b = 0; b < u.slotCount; ++b)
                        sum.leastSquaresScores.block<P, P>(at(a), at(b)) +=
                            l.segment<P>(Eigen::Index(a) * P) *
                            l.segment<P>(Eigen::Index(b) * P).transpose();
                if (sets == 2) {
                    Eigen::VectorXd& c = scratch.cross;
                    c.setZero(Eigen::Index(u.slotCount) * P);
                    for (std::uint32_t a = 0; a < u.slotCount; ++a) {
                        const Jacobian& ja = jacobians_[0][u.slotBegin + a];
                        const Jacobian& jb = jacobians_[1][u.slotBegin + a];
                        addPackedGradient<P>(c.segment<P>(Eigen::Index(a) * P), 0.5, ja,
                                             residuals_[1][i]);
                        addPackedGradient<P>(c.segment<P>(Eigen::Index(a) * P), 0.5, jb,
                                             residuals_[0][i]);
                        for (std::uint32_t b = 0; b < u.slotCount; ++b) {
                            addPackedGram<P>(sum.crossGram.block<P, P>(at(a), at(b)), 0.5, ja,
                                             jacobians_[1][u.slotBegin + b]);
                            addPackedGram<P>(sum.crossGram.block<P, P>(at(a), at(b)), 0.5, jb,
                                             jacobians_[0][u.slotBegin + b]);
                        }
                    }
                    for (std::uint32_t a = 0; a < u.slotCount; ++a)
                        for (std::uint32_t b = 0; b < u.slotCount; ++b)
                            sum.crossScores.block<P, P>(at(a), at(b)) +=
                                c.segment<P>(Eigen::Index(a) * P) *
                                c.segment<P>(Eigen::Index(b) * P).transpose();
                }
                if (!moments) return;
                pixelMoment(i, u, scratch.moment, &scratch.momentJacobian);
                for (std::uint32_t a = 0; a < u.slotCount; ++a)
                    for (std::uint32_t b = 0; b < u.slotCount; ++b)
                        sum.jacobian.block<P, P>(at(a), at(b)) +=
                            scratch.momentJacobian.template block<P, P>(Eigen::Index(a) * P,
                                                                        Eigen::Index(b) * P);
            });
        if (moments) result.scores = scores(result.jacobian, held);
        return result;
    }

    // Pixel i's term m of the estimating equations and, if asked, its Jacobian, over the pixel's
    // slots, from what the last analysis kept. Least squares' instruments are its own Jacobians.
    void pixelMoment(std::size_t i, const UsedPixel& u, Eigen::VectorXd& m,
                     Eigen::MatrixXd* jacobian) const {
        const Eigen::Index n = Eigen::Index(u.slotCount) * P;
        m.setZero(n);
        if (jacobian != nullptr) jacobian->setZero(n, n);
        for (int k = 0; k < int(sets_.size()); ++k) {
            const int other = instrumental_ ? 1 - k : k;
            const std::vector<Jacobian>& z = instrumental_ ? instruments_[other] : jacobians_[k];
            const double w = instrumental_ ? lossWeights_[other][i] : weights_[k][i];
            for (std::uint32_t a = 0; a < u.slotCount; ++a) {
                const Jacobian& za = z[u.slotBegin + a];
                addPackedGradient<P>(m.segment<P>(Eigen::Index(a) * P), w, za, residuals_[k][i]);
                for (std::uint32_t b = 0; jacobian != nullptr && b < u.slotCount; ++b)
                    addPackedGram<P>(
                        jacobian->block<P, P>(Eigen::Index(a) * P, Eigen::Index(b) * P), w, za,
                        jacobians_[k][u.slotBegin + b]);
            }
        }
    }

    // S = sum of m m^T over pixels, each m with its own pull on the estimate undone
    // (uncertainty.h).
    Eigen::MatrixXd scores(const Eigen::MatrixXd& jacobian, const std::vector<HeldParams>& held) {
        const Eigen::MatrixXd inverse = freeInverse(jacobian, heldFlags(held));
        const Eigen::Index size = jacobian.rows();
        return sumOverPixels(
            prep_.pixels.size(), Eigen::MatrixXd(Eigen::MatrixXd::Zero(size, size)),
            [&](std::size_t i, Eigen::MatrixXd& sum, Scratch& scratch) {
                const UsedPixel& u = prep_.pixels[i];
                const std::span<const std::uint32_t> slots = pixelSlots(u);
                std::vector<Eigen::Index>& indices = scratch.indices;
                indices.clear();
                for (std::uint32_t s : slots)
                    for (int k = 0; k < P; ++k) indices.push_back(Eigen::Index(s) * P + k);
                // A pixel that sees no material does not pull on the estimate.
                pixelMoment(i, u, scratch.moment,
                            u.seesMaterial ? &scratch.momentJacobian : nullptr);
                const Eigen::VectorXd m =
                    u.seesMaterial ? leaveOneOutScore(scratch.momentJacobian,
                                                      inverse(indices, indices), scratch.moment)
                                   : scratch.moment;
                sum(indices, indices) += m * m.transpose();
            });
    }

    // Makes the Jacobians and loss weights the last analysis kept the instruments; also their Gram
    // matrix, for the whitening, and the constant part of the moments.
    void adoptInstruments() {
        const int sets = int(sets_.size());
        for (int k = 0; k < sets; ++k) instruments_[k] = smoothed(jacobians_[k]);
        lossWeights_ = weights_;
        const std::vector<double> precision = precisions();
        for (int k = 0; k < sets; ++k)
            for (std::size_t i = 0; i < precision.size(); ++i) lossWeights_[k][i] *= precision[i];
        const Eigen::Index size = Eigen::Index(slots_) * P;
        const InstrumentSums zero{Eigen::MatrixXd::Zero(size, size), Eigen::VectorXd::Zero(size)};
        InstrumentSums sums = sumOverPixels(
            prep_.pixels.size(), zero, [&](std::size_t i, InstrumentSums& sum, Scratch& scratch) {
                const UsedPixel& u = prep_.pixels[i];
                const std::span<const std::uint32_t> slots = pixelSlots(u);
                for (int k = 0; k < sets; ++k)
                    for (std::uint32_t a = 0; a < u.slotCount; ++a)
                        for (std::uint32_t b = 0; b < u.slotCount; ++b)
                            sum.gram.block<P, P>(Eigen::Index(slots[a]) * P,
                                                 Eigen::Index(slots[b]) * P) +=
                                lossWeights_[k][i] / sets *
                                instruments_[k][u.slotBegin + a].transpose() *
                                instruments_[k][u.slotBegin + b];
                if (u.seesMaterial) return;
                pixelMoment(i, u, scratch.moment, nullptr);
                for (std::uint32_t a = 0; a < u.slotCount; ++a)
                    sum.constantMoments.segment<P>(Eigen::Index(slots[a]) * P) +=
                        scratch.moment.template segment<P>(Eigen::Index(a) * P);
            });
        instrumentGram_ = std::move(sums.gram);
        constantMoments_ = std::move(sums.constantMoments);
    }

    // 1 / the variance of each pixel's residual, estimated from the two sets' difference at its
    // neighbours (not the pixel itself, so the weight is independent of the residual it weights).
    std::vector<double> precisions() {
        const std::size_t count = prep_.pixels.size();
        std::vector<double> d(count), precision(count);
        double mean = 0;
        for (std::size_t i = 0; i < count; ++i) {
            d[i] = 0.5 * (residuals_[0][i] - residuals_[1][i]).squaredNorm();
            mean += d[i] / double(count);
        }
        const double floor = std::max(1e-2 * mean, 1e-12 * prep_.rmsObserved * prep_.rmsObserved);
        for (std::size_t i = 0; i < count; ++i) {
            const UsedPixel& u = prep_.pixels[i];
            const int width = prep_.widths[u.view], height = prep_.heights[u.view];
            const int x = int(u.pixel) % width, y = int(u.pixel) / width;
            double sum = 0;
            int n = 0;
            for (int yy = std::max(y - kInstrumentRadius, 0);
                 yy <= std::min(y + kInstrumentRadius, height - 1); ++yy)
                for (int xx = std::max(x - kInstrumentRadius, 0);
                     xx <= std::min(x + kInstrumentRadius, width - 1); ++xx) {
                    const std::int32_t q =
                        prep_.index[u.view][std::size_t(yy) * std::size_t(width) + xx];
                    if (q < 0 || std::size_t(q) == i) continue;
                    sum += d[std::size_t(q)];
                    ++n;
                }
            precision[i] = 1 / ((n > 0 ? sum / n : mean) + floor);
        }
        return precision;
    }

    // Jacobians averaged over the (2 kInstrumentRadius + 1)^2 pixels around each pixel (pixels
    // not used count as 0). A few samples per pixel make a pixel's Jacobian as noisy as its
    // value; instruments that noisy cost the estimate precision (its variance falls like
    // 1 / spp^2 instead of 1 / spp), and any function of the other set is a valid instrument.
    std::vector<Jacobian> smoothed(const std::vector<Jacobian>& jacobians) {
        std::vector<Jacobian> out(jacobians.size(), Jacobian::Zero());
        for (std::size_t view = 0; view < prep_.widths.size(); ++view) {
            const int width = prep_.widths[view], height = prep_.heights[view];
            const std::size_t pixels = std::size_t(width) * std::size_t(height);
            std::vector<Jacobian> image, rows(pixels);
            for (int s = 0; s < slots_; ++s) {
                if (!prep_.slotSeen[s]) continue;
                image.assign(pixels, Jacobian::Zero());
                forEachEntry(view, s, [&](std::size_t entry, std::size_t p, const UsedPixel& u) {
                    if (u.seesMaterial) image[p] = jacobians[entry];
                });
                // A separable box filter: rows, then columns.
                arena_.execute([&] {
                    tbb::parallel_for(0, height, [&](int y) {
                        for (int x = 0; x < width; ++x) {
                            Jacobian sum = Jacobian::Zero();
                            for (int xx = std::max(x - kInstrumentRadius, 0);
                                 xx <= std::min(x + kInstrumentRadius, width - 1); ++xx)
                                sum += image[std::size_t(y) * width + xx];
                            rows[std::size_t(y) * width + x] = sum;
                        }
                    });
                    tbb::parallel_for(0, width, [&](int x) {
                        for (int y = 0; y < height; ++y) {
                            Jacobian sum = Jacobian::Zero();
                            for (int yy = std::max(y - kInstrumentRadius, 0);
                                 yy <= std::min(y + kInstrumentRadius, height - 1); ++yy)
                                sum += rows[std::size_t(yy) * width + x];
                            image[std::size_t(y) * width + x] = sum;
                        }
                    });
                });
                forEachEntry(view, s, [&](std::size_t entry, std::size_t p, const UsedPixel&) {
                    const int x = int(p % std::size_t(width)), y = int(p / std::size_t(width));
                    const int count = (std::min(x + kInstrumentRadius, width - 1) -
                                       std::max(x - kInstrumentRadius, 0) + 1) *
                                      (std::min(y + kInstrumentRadius, height - 1) -
                                       std::max(y - kInstrumentRadius, 0) + 1);
                    out[entry] = image[p] / count;
                });
            }
        }
        return out;
    }

    // body(entry in UsedPixels::slots, pixel, used pixel) for the used pixels of `view` that list
    // `slot`.
    template <typename Body>
    void forEachEntry(std::size_t view, int slot, const Body& body) const {
        for (const UsedPixel& u : prep_.pixels) {
            if (u.view != view) continue;
            for (std::uint32_t a = 0; a < u.slotCount; ++a)
                if (prep_.slots[u.slotBegin + a] == std::uint32_t(slot))
                    body(u.slotBegin + a, std::size_t(u.pixel), u);
        }
    }

    // Standard errors of the natural parameters per slot from the sandwich with these sums
    // (uncertainty.h); 0 for the held ones.
    std::vector<std::vector<double>> naturalStd(const Eigen::MatrixXd& jacobian,
                                                const Eigen::MatrixXd& scores,
                                                const std::vector<HeldParams>& held) const {
        const std::vector<double> variance = sandwichVariances(jacobian, scores, heldFlags(held));
        std::vector<std::vector<double>> result(slots_, std::vector<double>(P, 0.0));
        for (int s = 0; s < slots_; ++s)
            for (int i = 0; i < P; ++i) {
                const double v = variance[std::size_t(s) * P + i];
                result[s][i] = isHeld(held[s], i) || !(v > 0) ? 0 : std::sqrt(v);
            }
        return result;
    }

    MaterialFit materialFit(int s, const HeldParams& held, const std::vector<double>& stdNatural) {
        NaturalVector y;
        toNatural<P>(block(s), held, y.data());
        MaterialFit m;
        const PhongMaterial p = naturalToPhong<P>(y.data());
        m.kd = p.kd;
        m.ks = p.ks;
        m.n = p.n;
        for (int c = 0; c < 3; ++c) {
            m.kdStd[c] = stdNatural[L::diffuse(L::group(c))];
            m.ksStd[c] = stdNatural[L::specular(L::group(c))];
        }
        // exp(log n) need not round-trip: a held n is reported exactly as it started.
        if (held.n) m.n = std::clamp(start_[s].n, kMinExponent, kMaxExponent);
        m.nStd = m.n * stdNatural[L::kLogN];
        static constexpr const char* kChannel[3] = {"r", "g", "b"};
        for (const char* name : {"kd", "ks"}) {
            const bool diffuse = name[1] == 'd';
            const auto& flags = diffuse ? held.kd : held.ks;
            const int count = int(std::count(flags.begin(), flags.begin() + L::kGroups, true));
            if (count == L::kGroups) {
                m.unconstrained.push_back(name);
            } else {
                for (int g = 0; g < L::kGroups; ++g)
                    if (flags[g])
                        m.unconstrained.push_back(fmt::format("{}.{}", name, kChannel[g]));
            }
        }
        if (held.n) m.unconstrained.push_back("n");
        return m;
    }

    std::vector<PhongMaterial>& start_;
    const FitOptions& options_;
    int slots_;
    int exposureSlot_;  // -1 when the exposure is not fitted
    bool instrumental_;
    bool firstRound_;
    const std::vector<PathSet>* first_;
    const std::vector<PathSet>* second_;
    std::vector<PathSet> pooled_;  // leastSquaresSets(), once built
    SetLists sets_;
    UsedPixels prep_;
    std::unique_ptr<ceres::LossFunction> loss_;
    tbb::task_arena arena_;
    std::vector<double> x_;  // internal coordinates, P per slot
    // Per set, at the last analysis: weighted Jacobians (per pixel slot, in UsedPixels::slots'
    // order), residuals and loss weights (per pixel).
    std::array<std::vector<Jacobian>, 2> jacobians_;
    std::array<std::vector<Eigen::Vector3d>, 2> residuals_;
    std::array<std::vector<double>, 2> weights_;
    // The same at the instrument point, and the instruments' Gram matrix (instrumental variables).
    std::array<std::vector<Jacobian>, 2> instruments_;
    std::array<std::vector<double>, 2> lossWeights_;
    std::vector<double> leastSquaresWeights_;  // per pixel; empty: all 1
    bool cross_ = false;
    Eigen::MatrixXd instrumentGram_;
    Eigen::VectorXd constantMoments_;  // g's terms from the pixels that see no material
};

// The two path-set lists of a round, one set per view each.
struct RoundSets {
    const std::vector<PathSet>* first;
    const std::vector<PathSet>* second;
};

using RecordAll = std::function<RoundSets(const std::vector<PhongMaterial>&, int round)>;

template <int P>
FitResult runRounds(const std::vector<Observation>& observations, const RecordAll& recordAll,
                    const std::vector<PhongMaterial>& start, const FitOptions& options,
                    int maxRounds) {
    const auto begin = std::chrono::steady_clock::now();
    const int threads = options.threads > 0 ? options.threads
                                            : std::max(1, int(std::thread::hardware_concurrency()));
    FitResult result;
    // The fitted exposure is one more slot (RoundSolver::exposure), a "material" whose kd and ks
    // are held at 0 and whose exponent is s * kExposureCentre; matchExposure starts it.
    const std::size_t materials = start.size();
    std::vector<PhongMaterial> slotStart = start;
    std::vector<HeldParams> held(materials);
    if (options.fitExposure) {
        PhongMaterial exposure;
        exposure.n = kExposureCentre;
        slotStart.push_back(exposure);
        held.emplace_back().kd.fill(true);
        held.back().ks.fill(true);
    }
    std::vector<PhongMaterial> theta = slotStart;
    for (int round = 0; round < maxRounds; ++round) {
        const auto roundBegin = std::chrono::steady_clock::now();
        const RoundSets sets =
            recordAll(std::vector<PhongMaterial>(theta.begin(), theta.begin() + materials), round);
        const double recordSeconds = secondsSince(roundBegin);
        for (const std::vector<PathSet>* paths : {sets.first, sets.second}) {
            if (paths->size() != observations.size())
                throw Error(fmt::format("the recorder returned {} path sets for {} views",
                                        paths->size(), observations.size()));
            for (std::size_t v = 0; v < observations.size(); ++v)
                checkPathSet((*paths)[v], observations[v], int(v), int(materials));
        }
        // Later rounds start where the last one ended, near enough for the instruments.
        RoundSolver<P> solver(observations, *sets.first, *sets.second, slotStart, options, threads,
                              round == 0);
        const std::vector<PhongMaterial> recorded = theta;
        RoundOutcome out = solver.solve(theta, held);

        FitRound r;
        r.round = round;
        r.recordSeconds = recordSeconds;
        r.timeSeconds = secondsSince(roundBegin);
        r.rmse = out.rmse;
        r.iterations = out.iterations;
        r.secondsPerIteration = out.minimizerSeconds / std::max(out.iterations, 1);
        r.materials = out.materials;
        r.exposure = out.exposure;
        r.recordedBytes = recordedBytes(*sets.first) +
                          (sets.first == sets.second ? 0 : recordedBytes(*sets.second));
        r.peakMemoryBytes = peakResidentBytes();
        result.rounds.push_back(r);
        if (options.onRound) options.onRound(r);
        for (std::size_t s = 0; s < materials; ++s) theta[s] = out.materials[s].material();
        if (options.fitExposure) theta.back().n = out.exposure.value * kExposureCentre;
        std::vector<Eigen::Matrix<double, P, 1>> before, after;
        for (std::size_t s = 0; s < theta.size(); ++s) {
            before.push_back(naturalFromPhong<P>(recorded[s]));
            after.push_back(naturalFromPhong<P>(theta[s]));
        }
        // Round 0 recorded at the start, not at an estimate: the move from there is no difference
        // between two estimates, and its standard errors, of a replay far from where its paths
        // were recorded, are the least telling (kd +- 0.3-0.5 on grazing study samples, ks +- 2-4
        // on sharp ones, which then passed for converged). Only the tolerance applies there.
        std::vector<std::vector<double>> noise = out.naturalStd;
        if (round == 0)
            for (std::vector<double>& slot : noise) std::fill(slot.begin(), slot.end(), 0.0);
        // Exact sets (the same list as both recordings) give the same problem every round: the
        // solver's own convergence is the answer.
        result.converged = withinTolerance<P>(before, after, noise, options) ||
                           (sets.first == sets.second && out.solverConverged);
        result.materials = out.materials;
        if (options.fitExposure) result.exposure = out.exposure;
        result.rmse = out.rmse;
        result.pixelsUsed = out.pixelsUsed;
        result.pixelsLeftOut = out.leftOut;
        if (options.stopRequested && options.stopRequested()) {
            // The round's solves may have been cut short: not a converged estimate.
            result.interrupted = true;
            result.converged = false;
            break;
        }
        if (result.converged) break;
    }
    result.timeSeconds = secondsSince(begin);
    return result;
}

FitResult fit(const std::vector<Observation>& observations, const RecordAll& recordAll,
              const std::vector<PhongMaterial>& start, const FitOptions& options, int maxRounds) {
    if (observations.empty()) throw Error("the fit needs at least one view");
    if (start.empty()) throw Error("the fit needs at least one material");
    if (maxRounds < 1 || options.maxIterations < 1 || !(options.tolerance > 0) ||
        !(options.stdTolerance >= 0) || !(options.lossScale > 0))
        throw Error(
            fmt::format("fit options: rounds {} and iterations {} must be >= 1, tolerance "
                        "{} and loss scale {} > 0, std tolerance {} >= 0",
                        maxRounds, options.maxIterations, options.tolerance, options.lossScale,
                        options.stdTolerance));
    for (std::size_t s = 0; s < start.size(); ++s)
        validatePhong(start[s], fmt::format("start value of material {}", s));
    for (std::size_t v = 0; v < observations.size(); ++v) checkObservation(observations[v], int(v));
    return options.grey ? runRounds<kGreyBlock>(observations, recordAll, start, options, maxRounds)
                        : runRounds<kRgbBlock>(observations, recordAll, start, options, maxRounds);
}

}  // namespace

FitResult fitMaterials(const std::vector<Observation>& observations, const PathRecorder& record,
                       const std::vector<PhongMaterial>& start, const FitOptions& options) {
    std::array<std::vector<PathSet>, 2> paths;
    const RecordAll recordAll = [&](const std::vector<PhongMaterial>& theta, int round) {
        for (int k = 0; k < 2; ++k) {
            paths[k].clear();
            for (std::size_t v = 0; v < observations.size(); ++v)
                paths[k].push_back(record(int(v), theta, 2 * round + k));
        }
        return RoundSets{&paths[0], &paths[1]};
    };
    return fit(observations, recordAll, start, options, options.maxRounds);
}

FitResult fitPathSets(const std::vector<Observation>& observations,
                      const std::vector<PathSet>& first, const std::vector<PathSet>& second,
                      const std::vector<PhongMaterial>& start, const FitOptions& options,
                      int rounds) {
    const RecordAll recordAll = [&](const std::vector<PhongMaterial>&, int) {
        return RoundSets{&first, &second};
    };
    return fit(observations, recordAll, start, options, rounds);
}

}  // namespace phongfit
