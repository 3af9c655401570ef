#include "rounds.h"

#include <fmt/format.h>
#include <malloc.h>

#include <algorithm>
#include <chrono>
#include <numeric>
#include <optional>
#include <thread>
#include <utility>

#include "broad_stride.h"
#include "convergence.h"
#include "error.h"
#include "fit_input.h"
#include "identifiability.h"
#include "image_noise.h"
#include "lost_lobe.h"
#include "memory_info.h"
#include "memory_plan.h"
#include "parameter_state.h"
#include "path_growth.h"
#include "path_importance.h"
#include "pooled_rounds.h"
#include "precision_target.h"
#include "resident_peak.h"
#include "round_paths.h"
#include "round_scatter.h"
#include "round_solver.h"
#include "sharper_probe.h"
#include "time_budget.h"

namespace phongfit {

namespace {

// The most paths, relative to the first round's, that rounds which do not settle grow to (the
// default 4 paths a pixel become 256). Cells of the recovery matrix that flipped between two states
// at 4 paths settled by 64 (docs/design/fitter.md, "Rounds that do not settle").
constexpr double kUnsettledPaths = 64;

double secondsSince(std::chrono::steady_clock::time_point start) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

std::size_t tracedPaths(const std::vector<PathSet>& sets) {
    std::size_t paths = 0;
    for (const PathSet& set : sets)
        paths +=
            set.pixelPaths.empty()
                ? std::size_t(set.spp) * std::size_t(set.width) * std::size_t(set.height)
                : std::accumulate(set.pixelPaths.begin(), set.pixelPaths.end(), std::size_t(0));
    return paths;
}

// The estimate `out` ends at; the exposure stays `before`'s where it is not fitted. An n held
// for want of a lobe (not with its ks: a lobe no pixel sees stays where it is) goes back to its
// `start`, where the next round records and is judged from: one held broader, where kd and ks were
// fitted (and reported), would leave a second diffuse term for the next round to fit.
Estimate estimateOf(const RoundOutcome& out, const Estimate& before, bool fitExposure,
                    const std::vector<PhongMaterial>& start) {
    Estimate e = before;
    for (std::size_t s = 0; s < e.materials.size(); ++s) {
        const MaterialFit& fit = out.materials[s];
        e.materials[s] = fit.material();
        if (fit.isUnconstrained("n") && !fit.ksUnconstrained())
            e.materials[s].n = std::clamp(start[s].n, kMinExponent, kMaxExponent);
    }
    if (fitExposure) e.exposure = out.exposure.value;
    return e;
}

// Per material and ks group (a channel, or the grey one): the rounds' scatter of ks; empty
// without a scatter.
template <int P>
std::vector<std::vector<double>> ksScatterFloor(const std::vector<MaterialScatter>& scatter,
                                                int materials) {
    if (scatter.empty()) return {};
    constexpr int kGroups = BlockLayout<P>::kGroups;
    std::vector<std::vector<double>> least(static_cast<std::size_t>(materials),
                                           std::vector<double>(kGroups, 0.0));
    for (int s = 0; s < materials; ++s)
        for (int g = 0; g < kGroups; ++g)
            least[std::size_t(s)][std::size_t(g)] = kGroups == 1
                                                        ? scatter[std::size_t(s)].ks.maxCoeff()
                                                        : scatter[std::size_t(s)].ks[g];
    return least;
}

// Whether the next round, recording `growth` times the last round's paths, fits: its paths and
// the state of the pixels the last round used.
bool fitsMemory(const FitResult& result, double growth, std::size_t limit) {
    const std::optional<std::size_t> available = fitMemoryAvailable(limit);
    const double need =
        nextRoundBytes(result.rounds.back().recordedBytes, growth, result.pixelsUsed);
    return !available || need <= double(*available);
}

// Growth of FitOptions::precision's paths after a round that did not settle: twice as many, up to
// kUnsettledPaths times the first round's, as far as memory allows (a round that would not fit is
// not grown, rather than not started; the time budget shrinks it as it starts). `next`: the next
// round's paths against the last one's before this growth.
double unsettledGrowth(const FitResult& result, const FitOptions& options, double pathFactor,
                       double next) {
    double growth = std::max(1.0, std::min(2.0, kUnsettledPaths / pathFactor));
    while (growth > 1 && !fitsMemory(result, next * growth, options.memoryLimit))
        growth = std::max(1.0, growth / 2);
    return growth;
}

// Per material, whether `fits` (a round's) has a lobe worth a broader scan in the next round: n
// free, ks at least kReflectanceFloor in some channel and kLobeConfirmation standard errors
// from 0. A spurious lobe of the recordings' noise (ks 4e-4 where there is none) is left alone:
// where every exponent fits alike a broader one can win by noise and unsettle the rounds.
std::vector<bool> lobesToScan(const std::vector<MaterialFit>& fits) {
    std::vector<bool> scan;
    for (const MaterialFit& m : fits) scan.push_back(!m.isUnconstrained("n") && lobeConfirmed(m));
    return scan;
}

bool allResolved(const std::vector<MaterialFit>& materials) {
    return std::all_of(materials.begin(), materials.end(),
                       [](const MaterialFit& m) { return unresolvedParameters(m).empty(); });
}

void checkRoundSets(const RoundSets& sets, const std::vector<Observation>& observations,
                    int slots) {
    for (const std::vector<PathSet>* paths : {sets.first, sets.second}) {
        if (paths->size() != observations.size())
            throw Error(fmt::format("the recorder returned {} path sets for {} views",
                                    paths->size(), observations.size()));
        for (std::size_t v = 0; v < observations.size(); ++v)
            checkPathSet((*paths)[v], observations[v], int(v), slots);
    }
}

// What fit.json and the progress line report of a round.
FitRound roundReport(int round, double pathFactor, bool probe, const RoundSets& sets,
                     const RoundOutcome& out, ResidentPeak& peak) {
    const bool exact = sets.first == sets.second;
    FitRound r;
    r.round = round;
    r.pathFactor = pathFactor;
    r.probe = probe;
    r.paths = tracedPaths(*sets.first) + (exact ? 0 : tracedPaths(*sets.second));
    r.rmse = out.rmse;
    r.iterations = out.iterations;
    r.secondsPerIteration = out.minimizerSeconds / std::max(out.iterations, 1);
    r.materials = out.materials;
    r.exposure = out.exposure;
    r.recordedBytes = recordedBytes(*sets.first) + (exact ? 0 : recordedBytes(*sets.second));
    r.peakMemoryBytes = peak.bytes();
    return r;
}

// Per view and pixel, what a path is worth to the estimate `theta` with the round's standard
// errors (path_importance.h); material blocks only: the exposure is global, no pixel's paths
// inform it more.
template <int P>
std::vector<std::vector<float>> nextImportance(const std::vector<Observation>& observations,
                                               const RoundSets& sets,
                                               const ParameterState<P>& params,
                                               const Estimate& theta, const RoundOutcome& out,
                                               int threads) {
    std::vector<double> natural, std;
    const std::vector<typename ParameterState<P>::NaturalVector> y = params.naturalBlocks(theta);
    for (int b = 0; b < params.materialCount(); ++b)
        for (int i = 0; i < P; ++i) {
            natural.push_back(y[std::size_t(b)][i]);
            std.push_back(out.naturalStd[std::size_t(b)][std::size_t(i)]);
        }
    return pathImportance<P>(observations, *sets.first, *sets.second, natural, std, threads);
}

// What follows a round whose estimate stopped moving.
struct Settled {
    bool stop = false;                   // the fit ends with `result` as settle() left it
    std::vector<PhongMaterial> sharper;  // else, if not empty, the next round probes here
    double pathGrowth = 1;               // else the precision target asks this many more paths
};

// Whether some material's n is still climbing: the last round moved it sharper by at least its
// standard error (the image's noise as its floor), after a round that moved it sharper too (probe
// rounds left out). A converged estimate's moves do that about one time in ten (independent
// rounds); the 40-degree sphere at 128 x 128 (n 30000) had "converged" in its last round at 237,
// 1127, 1318, 3821, 6524 +- 1945, 5.3 standard errors short (docs/design/fitter.md).
bool climbing(const std::vector<FitRound>& rounds) {
    std::vector<const FitRound*> recorded;
    for (const FitRound& r : rounds)
        if (!r.probe) recorded.push_back(&r);
    if (recorded.size() < 3) return false;
    const auto& a = recorded[recorded.size() - 3]->materials;
    const auto& b = recorded[recorded.size() - 2]->materials;
    const auto& c = recorded.back()->materials;
    for (std::size_t s = 0; s < c.size() && s < a.size() && s < b.size(); ++s)
        if (const double std = std::max(c[s].nStd, c[s].n * c[s].logNImageStd);
            b[s].n > a[s].n && c[s].n - b[s].n >= std && std > 0)
            return true;
    return false;
}

// `result` holds the round's estimate `out`, which stopped moving. Its stop reason and whether it
// is converged: resolved and as precise as FitOptions::precision asks (if `planned`: the sets are
// recorded, so more paths can be asked for) or at the image's noise floor; a converged lobe is
// then probed (if `probes`) in a next round, which the last round does not have, from `at`
// (where the next round would record).
template <int P>
Settled settle(FitResult& result, const RoundOutcome& out, const ParameterState<P>& params,
               const FitOptions& options, double recordFactor, bool planned, bool probes,
               bool lastRound, const std::vector<PhongMaterial>& at) {
    // Stopped moving, but not at a solution the recordings resolve: say so.
    const bool resolved = allResolved(out.materials);
    planned = planned && options.precision > 0;
    const PrecisionPlan plan = planned ? planPrecision<P>(params, out.naturalStd, out.pathShare,
                                                          options.precision, recordFactor)
                                       : PrecisionPlan{true, false, 1};
    Settled next;
    if (!plan.met && !plan.floor) {
        // More paths where the estimate is not yet as precise as asked.
        result.converged = false;
        result.stopReason = "precision not met";
        next.pathGrowth = plan.pathGrowth;
        return next;
    }
    result.converged = resolved;
    result.stopReason = !resolved  ? "unresolved"
                        : !planned ? "converged"
                        : plan.met ? "precision"
                                   : "noise floor";
    if (probes && resolved) next.sharper = sharperProbe(out.materials, at);
    if (!next.sharper.empty() && lastRound) {
        // No round left to probe. A probe round in the history did not come back (one that did
        // ends the fit): then only a probe that does ends it converged. Nor does a lobe that is
        // still climbing towards the side the recordings are blind to.
        if (std::any_of(result.rounds.begin(), result.rounds.end(),
                        [](const FitRound& r) { return r.probe; }) ||
            climbing(result.rounds)) {
            result.converged = false;
            result.stopReason = "sharper lobe";
        }
        next.sharper.clear();
    }
    next.stop = next.sharper.empty();
    return next;
}

}  // namespace

template <int P>
FitResult runRounds(const std::vector<Observation>& observations, const RecordAll& recordAll,
                    const std::vector<PhongMaterial>& start, const FitOptions& options,
                    int maxRounds, bool rerecords) {
    const auto begin = std::chrono::steady_clock::now();
    // Started before the start is read: its thread's pages are the process's, not the fit's.
    ResidentPeak peak;
    // Counted from what the process holds, not what its heap kept of what it freed (as after
    // each round below).
    malloc_trim(0);
    residentProgram();
    peak.reset();
    const std::size_t residentAtStart = residentBytes(), filesAtStart = fileResidentBytes();
    const int threads = options.threads > 0 ? options.threads
                                            : std::max(1, int(std::thread::hardware_concurrency()));
    FitResult result;
    // A solve under way stops at the time budget as at an interrupt; which one it was is told
    // apart afterwards.
    const auto budgetSpent = [&] {
        return options.timeBudget > 0 && secondsSince(begin) >= options.timeBudget;
    };
    FitOptions solveOptions = options;
    solveOptions.stopRequested = [&] {
        return budgetSpent() || (options.stopRequested && options.stopRequested());
    };
    ParameterState<P> params(start, options.fitExposure);
    Estimate theta{start, 1.0};
    std::vector<std::vector<float>> importance;  // per view, for the next round's recording
    std::vector<PixelPaths> firstPaths;          // per view, the first round's paths per pixel
    double pathFactor = 1, growth = 1;           // FitOptions::precision's paths, and their change
    // A probe round's paths, and a second probe's from the same start (`probeStart`) where the
    // first could not tell the converged n from it (probePaths); the converged round's paths, a
    // second probe's where the first was pulled broader (pulledBroader).
    double probePathFactor = kProbePaths, retryPathFactor = kProbePaths;
    double probedPathFactor = kProbePaths;
    std::vector<PhongMaterial> probeStart;
    // Per material, the sharpest n a round recorded at; and whether the last round probes an
    // estimate that had not settled.
    std::vector<double> sharpestRecorded(start.size(), 0.0);
    bool unsettledProbe = false;
    bool exact = false;  // the recorder returned one exact set: every round is the same problem
    // Each round records at the last estimate, so what it sees depends on it (scans of the
    // broader side, strides and probes apply).
    const bool followsEstimate = rerecords && options.recordingFollowsEstimate;
    // Lobes are probed sharper only where some light is seen over a solid angle: a delta light's
    // direct highlight is replayed at any lobe (FitOptions::extendedLights).
    const bool probesSharper = followsEstimate && options.extendedLights;
    std::optional<FitResult> probed;  // a converged estimate awaiting its probe round
    // The converged estimate the last round's probe did not come back to, widened to the probe:
    // what the fit reports if it ends before another round.
    std::optional<FitResult> unvouched;
    // The last probe round that did not come back, and the converged estimate it probed: the
    // sharper lobe it stayed at fitted the images, and later rounds rule it out only by coming
    // back to that estimate as a probe would (sharper_probe.h, probeReturned).
    struct Unreturned {
        std::vector<MaterialFit> converged, probe;
    };
    std::optional<Unreturned> unreturned;
    // A broad stride is taken once a fit: after it, the rounds near the truth are left to the
    // paths (a second stride at 2 paths a pixel left 0128 out of its tolerance when the rounds ran
    // out). `atStride`: the next round records at it.
    bool strided = false, atStride = false;
    bool lobeRecovered = false;    // a lobe lost was recorded again where it was seen (once a fit)
    bool vouched = false;          // the fit ends at a converged estimate its probe came back to
    RoundPathNoise previousRound;  // the last round's path noise, where its recordings resolve it
    // The rounds that settled at the estimate since it last moved (pooled_rounds.h), if any.
    std::optional<PooledRounds<P>> pool;
    if (rerecords)
        requireMemory(leastFirstRoundBytes(observations), options.memoryLimit,
                      fmt::format("the fit's first round ({} bytes of fit state and two "
                                  "recordings of at least {} bytes for each pixel)",
                                  kStateBytesPerPixel, kLeastRecordedBytesPerPixel));
    for (int round = 0; round < maxRounds; ++round) {
        result.stopReason = "rounds";
        const char* cut = nullptr;  // what stops the rounds before this one
        if (round > 0) {
            const BudgetedRound next =
                budgetedRound(options.timeBudget, secondsSince(begin),
                              result.rounds.back().timeSeconds, growth, !probed);
            pathFactor *= next.growth / growth;
            growth = next.growth;
            if (!next.starts) cut = "time budget";
        }
        if (cut == nullptr && round > 0 && rerecords &&
            !fitsMemory(result, growth, options.memoryLimit))
            cut = "memory";
        if (cut != nullptr) {
            if (unvouched) {
                unvouched->rounds = std::move(result.rounds);
                result = std::move(*unvouched);
            }
            result.stopReason = cut;
            break;
        }
        const auto roundBegin = std::chrono::steady_clock::now();
        const std::size_t files = fileResidentBytes();
        const std::size_t programBytes = files - std::min(files, filesAtStart);
        const double recordFactor = probed ? probePathFactor : pathFactor;
        const RoundSets sets = recordAll(theta.materials, round, importance, recordFactor);
        importance = {};  // spent: the next round's is made after the solve, which peaks above it
        const double recordSeconds = secondsSince(roundBegin);
        for (std::size_t s = 0; s < sharpestRecorded.size(); ++s)
            sharpestRecorded[s] = std::max(sharpestRecorded[s], theta.materials[s].n);
        exact = sets.first == sets.second;
        checkRoundSets(sets, observations, int(start.size()));
        if (round == 0 && !exact) firstPaths = pathsPerPixel(*sets.first);
        // A round recorded at the estimate, once the estimate has travelled from the start
        // (rounds 0 and 1, whose lobes can be the start's), also tries the broader side of its
        // confirmed lobes.
        std::vector<bool> scanBroader;
        if (round >= 2 && followsEstimate && options.scanStart && !exact && !probed)
            scanBroader = lobesToScan(result.rounds.back().materials);
        // Later rounds start where the last one ended, near enough for the instruments.
        // Its per-pixel state is freed once the round is solved, before the next importance and
        // recording (docs/design/fitter.md, "Memory").
        std::optional<RoundSolver<P>> solver;
        solver.emplace(observations, *sets.first, *sets.second, params, solveOptions, threads,
                       round == 0, std::move(scanBroader));
        const Estimate recorded = theta;
        RoundOutcome out = solver->solve(theta);
        // Round 0 recorded at the start, not at an estimate: its move is no difference between
        // two estimates, and its standard errors, of a replay far from where its paths were
        // recorded, are the least telling. Only the tolerance applies there.
        std::vector<std::vector<double>> noise = out.naturalStd;
        if (round == 0)
            for (std::vector<double>& block : noise) std::fill(block.begin(), block.end(), 0.0);
        // Recorded with the last round's paths: the move from its estimate has both rounds' path
        // noise, the image's being common to both (docs/design/fitter.md, "At equal paths").
        else if (!probed && recordFactor <= previousRound.pathFactor)
            addPathNoise(noise, previousRound.pathNoise);
        const Estimate solved = estimateOf(out, theta, options.fitExposure, start);
        // Exact sets (the same list as both recordings) give the same problem every round: the
        // solver's own convergence is the answer.
        const auto before = params.naturalBlocks(recorded), after = params.naturalBlocks(solved);
        // Recorded at a pool's estimate (pooled_rounds.h) and moved by less than the noise of
        // the two (poolingNoise): at the same point, and so settled. Whether it joins the pool is
        // decided once lobe confirmation is done (below).
        const bool poolsRound = round > 0 && !probed && !exact && rerecords;
        bool nearPool = false;
        if (poolsRound && pool) {
            const PooledRounds<P> own = poolOfRound<P>(out, params, recordFactor);
            nearPool = poolable<P>(*pool, own) &&
                       withinTolerance<P>(before, after, poolingNoise<P>(*pool, own), options);
        }
        // A probe round recorded at a sharper lobe: the converged estimate stands if it came back
        // (judged before lobe confirmation, which the probe's jump would put in the scatter) from
        // a solve not cut short, and not only by its few paths' pull.
        const bool pulled = probed && recordFactor < probedPathFactor &&
                            pulledBroader(probed->materials, out.materials, probedPathFactor);
        const bool probeBack = probed && !solveOptions.stopRequested() && !pulled &&
                               probeReturned(probed->materials, out.materials);
        // A probe that did not come back settles nothing: the rounds go on from its estimate
        // (sharper_probe.h), its own move from the sharper lobe it was recorded at aside.
        const bool settled =
            (!probed || probeBack) &&
            (withinTolerance<P>(before, after, noise, options) || (exact && out.solverConverged) ||
             (!probed && settledAgain<P>(before, after, noise, previousRound, out, params, options,
                                         recordFactor)) ||
             nearPool);
        // A round that did not settle by more than the precision target tolerates.
        const bool movedPast =
            options.precision > 0 &&
            movedPastTarget<P>(params, out.naturalStd, before, after, options.precision);
        // A probe that did not come back, with no round after it, leaves the converged estimate
        // standing, unvouched.
        const bool probeLeft =
            probed && !probeBack && (round + 1 == maxRounds || solveOptions.stopRequested());
        // The final estimate reports only the lobes its recordings confirm, and that stand out of
        // the rounds' scatter.
        if ((settled || round + 1 == maxRounds) && !probeBack && !probeLeft &&
            !solveOptions.stopRequested()) {
            const std::vector<std::vector<double>> ksFloor =
                exact ? std::vector<std::vector<double>>{}
                      : ksScatterFloor<P>(roundScatter(result.rounds, &out.materials),
                                          params.materialCount());
            solver->confirmLobes(out, ksFloor.empty() ? nullptr : &ksFloor);
            if (!exact) solver->takeSharperNoise(out);
        }
        solver.reset();
        malloc_trim(0);  // the solver's many small blocks leave the resident set

        FitRound r = roundReport(round, recordFactor, probed.has_value(), sets, out, peak);
        r.broadStride = std::exchange(atStride, false);
        // A round that settled at the pool's estimate joins it; one that moved, or the first
        // round recorded at an estimate, starts a pool of its own. Both as lobe confirmation left
        // the round: it may have held a parameter the pool has free.
        if (poolsRound && allResolved(out.materials)) {
            PooledRounds<P> own = poolOfRound<P>(out, params, recordFactor);
            if (nearPool && poolable<P>(*pool, own)) {
                pool = pooled<P>(*pool, own);
                adoptPool<P>(*pool, params, out);
            } else {
                pool = std::move(own);
            }
        } else {
            pool.reset();
        }
        r.pooledRounds = pool ? pool->rounds : 1;
        // The pool the next round may join, if any: its paths are what that round adds to.
        const PooledRounds<P>* joinable = pool && preciseEnoughToPool<P>(*pool) ? &*pool : nullptr;
        r.recordSeconds = recordSeconds;
        r.programBytes = programBytes;
        r.timeSeconds = secondsSince(roundBegin);
        result.rounds.push_back(r);
        if (options.onRound) options.onRound(r);
        theta = estimateOf(out, theta, options.fitExposure, start);
        result.converged = settled;
        result.materials = out.materials;
        if (options.fitExposure) result.exposure = out.exposure;
        result.rmse = out.rmse;
        result.pixelsUsed = out.pixelsUsed;
        result.pixelsLeftOut = out.leftOut;
        previousRound = round > 0 && !probed && !exact && allResolved(out.materials)
                            ? RoundPathNoise{pathNoise(out.naturalStd, out.pathShare),
                                             joinable ? joinable->pathFactor : recordFactor}
                            : RoundPathNoise{};
        const bool stop = solveOptions.stopRequested();
        // A probe that could not tell, or was pulled broader, is probed again, once: after the
        // second probe recordFactor is at least retryPathFactor, and probedPathFactor if pulled.
        const bool retry = probed && !probeBack && !probeLeft && !stop &&
                           (pulled || (recordFactor < retryPathFactor &&
                                       !probeTold(probed->materials, out.materials)));
        if (probeBack) {
            probed->rounds = std::move(result.rounds);
            result = std::move(*probed);
            vouched = true;
            break;
        }
        unvouched.reset();
        if (probed) {
            unreturned = Unreturned{probed->materials, out.materials};
            unvouched = *probed;
            unvouched->converged = false;
            widenToProbe(unvouched->materials, out.materials);
        } else if (unreturned && probeReturned(unreturned->converged, out.materials)) {
            unreturned.reset();
        }
        if (probeLeft) {
            unvouched->rounds = std::move(result.rounds);
            result = std::move(*unvouched);
            unvouched.reset();
            result.stopReason = "sharper lobe";
        }
        if (stop) {
            // The round's solves may have been cut short: not a converged estimate.
            result.interrupted = !budgetSpent();
            result.stopReason = result.interrupted ? "interrupted" : "time budget";
            result.converged = false;
            break;
        }
        if (probeLeft) break;
        if (retry) {
            probePathFactor =
                pulled ? std::max(probedPathFactor, retryPathFactor) : retryPathFactor;
            growth = probePathFactor / recordFactor;
            theta.materials = probeStart;
            importance = nextImportance<P>(observations, sets, params, theta, out, threads);
            continue;
        }
        probed.reset();
        growth = pathFactor / recordFactor;  // the next round's paths against this one's
        std::vector<PhongMaterial> sharper;  // where the next round probes (sharper_probe.h)
        bool importanceTaken = false;        // the next round's importance, already at theta
        // Recordings that cannot see the broader lobe their estimate went towards: the next round
        // records broader, with the same paths, rather than more of them.
        if (!strided && !r.probe && followsEstimate && !exact && round + 1 < maxRounds)
            if (std::optional<std::vector<PhongMaterial>> stride =
                    broadStride(out.materials, recorded.materials, theta.materials)) {
                theta.materials = std::move(*stride);
                strided = atStride = true;
                result.converged = false;
            }
        const double pooledFactor = joinable ? joinable->pathFactor : recordFactor;
        // A lobe the round before showed and this one lost, its ks held with its n: the next
        // round records again where it was seen, with more paths, its ks and n free (lost_lobe.h).
        const std::vector<int> lost =
            !lobeRecovered && !r.probe && followsEstimate && !exact && round + 1 < maxRounds &&
                    result.rounds.size() >= 2
                ? lostLobes(result.rounds[result.rounds.size() - 2].materials, out.materials)
                : std::vector<int>{};
        if (!lost.empty()) {
            for (int s : lost) {
                theta.materials[std::size_t(s)] = recorded.materials[std::size_t(s)];
                params.releaseLobe(s);
            }
            lobeRecovered = true;
            result.converged = false;
            pathFactor *= kLostLobePaths;
            growth = pathFactor / recordFactor;
        } else if (result.converged) {
            const Settled next =
                settle<P>(result, out, params, options, pooledFactor, !exact,
                          probesSharper && !exact, round + 1 == maxRounds, theta.materials);
            if (next.stop) break;
            sharper = next.sharper;
            if (sharper.empty() && round + 1 < maxRounds) {
                // More paths asked for. Where the pixels that inform the estimate are near their
                // cap, more paths inform little: the estimate is as settled as paths make it, and
                // a resolved one is probed as a converged one is.
                importance = nextImportance<P>(observations, sets, params, theta, out, threads);
                importanceTaken = true;
                if (mostPathGain(importance, firstPaths, recordFactor) < kLeastPathGain) {
                    result.stopReason = "path cap";
                    if (probesSharper && allResolved(out.materials))
                        sharper = sharperProbe(out.materials, theta.materials);
                    if (sharper.empty()) break;
                    importanceTaken = false;
                }
            }
            if (sharper.empty()) {
                // A pool needs only the paths it lacks.
                growth = joinable ? pathsThePoolLacks(pooledFactor, next.pathGrowth) / recordFactor
                                  : next.pathGrowth;
                // Never fewer paths than before a probe that did not come back.
                pathFactor =
                    joinable ? recordFactor * growth : std::max(pathFactor, recordFactor * growth);
                growth = pathFactor / recordFactor;
            }
        } else if (round >= 2 && round + 2 == maxRounds && probesSharper && !exact && !r.probe &&
                   !atStride && allResolved(out.materials) &&
                   sharperSideUntested(out.materials, sharpestRecorded)) {
            // The rounds end next round with an estimate that has not settled, once it has
            // travelled from the start, its lobe's sharper side untested: the last round probes it
            // rather than add paths, so that a lobe the recordings are blind to is not reported
            // as bounded (docs/design/fitter.md, "The last round's probe").
            sharper = sharperProbe(out.materials, theta.materials);
            unsettledProbe = true;
        } else if (!atStride && !r.probe && round >= 2 && !exact && movedPast) {
            // Not settled, by more than the precision target allows, once the estimate has
            // travelled from the start (rounds 0 and 1, as for the rounds' scatter); not a probe's
            // move from the sharper lobe it was sent to, nor a round a stride follows: recordings
            // this sparse may keep it jumping between states they cannot tell apart
            // (docs/design/fitter.md, "Rounds that do not settle").
            pathFactor *= unsettledGrowth(result, options, pathFactor, growth);
            growth = pathFactor / recordFactor;
        }
        // The probe round records, and starts its solve, at the sharper lobe, and spends its
        // extra paths where that lobe's parameters are informed.
        if (!sharper.empty()) {
            probed = result;
            result.converged = false;
            result.stopReason = "rounds";
            probePathFactor = firstProbePaths(out.materials, pooledFactor, round + 2 == maxRounds);
            retryPathFactor = probePaths(out.materials, pooledFactor);
            probedPathFactor = pooledFactor;
            probeStart = sharper;
            growth = probePathFactor / recordFactor;
            theta.materials = sharper;
        }
        if (!exact && round + 1 < maxRounds && !importanceTaken)
            importance = nextImportance<P>(observations, sets, params, theta, out, threads);
    }
    if (!exact) {
        // A probe that did not come back, with no later one that did: the final estimate's n
        // reaches the lobe it stayed at.
        if (unreturned && !vouched) widenToProbe(result.materials, unreturned->probe);
        // Nor could a lobe within a probe's factor of the bound be probed sharper.
        if (followsEstimate) widenToBound(result.materials);
        widenToRoundScatter(result);
        // Stopped before showing where the estimate stops (a probe left unvouched has its own
        // widening): while it still moved, or settled round by round but not as precise as asked,
        // which a climb does as well.
        const std::string& why = result.stopReason;
        if (!result.converged && !result.rounds.empty() &&
            (!result.rounds.back().probe || unsettledProbe) &&
            (why == "rounds" || why == "time budget" || why == "memory" || why == "interrupted" ||
             why == "sharper lobe" || why == "precision not met" || why == "path cap"))
            widenToDrift(result);
    }
    // The image's own noise, which the sandwich misses where one pixel holds a parameter; a
    // precision it does not allow was the noise floor's.
    if (result.stopReason == "precision" &&
        !meetsPrecision(result.materials, options.precision, PrecisionOf::ImageNoise))
        result.stopReason = "noise floor";
    const bool preciseWithoutImageNoise =
        meetsPrecision(result.materials, options.precision, PrecisionOf::Reported);
    for (MaterialFit& m : result.materials) applyImageNoise(m);
    for (MaterialFit& m : result.materials) finishExponentUncertainty(m);
    if (!exact) {
        // A converged estimate whose rounds scatter by as much as a parameter is not resolved.
        const bool resolved = allResolved(result.materials);
        if (result.converged && !resolved) {
            result.converged = false;
            result.stopReason = "unresolved";
        }
    }
    // The last round met the precision, but the standard errors reported are wider. Where only
    // the image's noise added to them makes them so, the noise floor stopped the fit. Otherwise
    // the rounds' estimates scatter by more (a move between rounds, or recordings noisier than
    // their round's standard errors said): the precision asked for is not what the fit can claim.
    if (result.stopReason == "precision" &&
        !meetsPrecision(result.materials, options.precision, PrecisionOf::Reported)) {
        if (preciseWithoutImageNoise) {
            result.stopReason = "noise floor";
        } else {
            result.converged = false;
            result.stopReason = "rounds disagree";
        }
    }
    result.timeSeconds = secondsSince(begin);
    result.residentAtStartBytes = residentAtStart;
    return result;
}

template FitResult runRounds<kRgbBlock>(const std::vector<Observation>&, const RecordAll&,
                                        const std::vector<PhongMaterial>&, const FitOptions&, int,
                                        bool);
template FitResult runRounds<kGreyBlock>(const std::vector<Observation>&, const RecordAll&,
                                         const std::vector<PhongMaterial>&, const FitOptions&, int,
                                         bool);

}  // namespace phongfit
