// Fits Modified Phong parameters to observed images by replaying recorded path sets (DESIGN.md,
// "Path replay"), round after round: record two independent path sets per view at the current
// estimate, solve (all views jointly), hold what the images do not constrain, standard errors,
// repeat until the parameters stop moving.
//
// Two sets, because least squares on one noisy set is biased towards 0; the default estimator
// solves instrumental-variables moment equations with each set's instruments taken from the
// other, which is consistent at any number of samples per pixel. docs/design/fitter.md gives the
// reasoning and the measurements; the files it names hold the pieces.
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "observation.h"
#include "path_set.h"
#include "phong_brdf.h"
#include "scene.h"

namespace phongfit {

// The range of a fitted exposure: 4.5 decades either side of 1 (exposure_block.h lays s out as
// an exponent, s * kExposureCentre, whose range is 1e-3 to 1e6).
inline constexpr double kExposureCentre = 31.622776601683793;
inline constexpr double kMinExposure = 1e-3 / kExposureCentre;
inline constexpr double kMaxExposure = 1e6 / kExposureCentre;

enum class LossKind { L2, Huber, Cauchy };

// A pixel of images rendered as the observed one was (its scene's sampler and samples per pixel):
// the mean over `renders` renders and the covariance over channels of one render.
struct RenderedPixel {
    Eigen::Vector3d mean;
    Eigen::Matrix3d covariance;
    int renders = 1;
};

// Each of `pixels` (indices into view `view`'s observation) rendered as the observed image was
// with the materials `theta`; empty where the observed images have no noise. What a pixel's noise
// is where no other pixel can show it, and what it is expected to be (image_noise.h).
using RenderedNoise = std::function<std::vector<RenderedPixel>(
    int view, const std::vector<std::uint32_t>& pixels, const std::vector<PhongMaterial>& theta)>;

enum class Estimator {
    InstrumentalVariables,  // consistent at any spp (docs/design/fitter.md)
    LeastSquares,           // per-pixel least squares on the mean of the two sets: biased towards 0
};

// "l2", "huber" or "cauchy"; throws Error naming the allowed values otherwise.
LossKind parseLoss(const std::string& name);

struct MaterialFit {
    Color3 kd = Color3::Zero(), ks = Color3::Zero();
    double n = 0;
    // Standard errors; 0 for the parameters in `unconstrained`, which are held at their start, but
    // for an n listed there because no lobe holds it (lobeHoldsExponent), which keeps its own.
    // The fit works in log n: logNStd is the standard error s of log n (raised to the rounds'
    // scatter), a round's nStd n s; the result's nStd is at least the standard deviation of n
    // where log n is normal with s (logNormalStd), and what the widenings in n reached.
    Color3 kdStd = Color3::Zero(), ksStd = Color3::Zero();
    double nStd = 0;
    double logNStd = 0;
    // The standard errors the image's own noise gives, modelled from the paths (image_noise.h):
    // where one pixel holds a parameter the sandwich cannot see that pixel's noise. A fit's result
    // reports at least these (kd, ks and log n); its rounds keep them apart.
    Color3 kdImageStd = Color3::Zero(), ksImageStd = Color3::Zero();
    double logNImageStd = 0;
    // The part of the image's noise that the standard errors above already hold (the sandwich
    // reads the image's noise off the residuals, (1 - the recordings' share) of its variance):
    // the result adds the image's beyond it (applyImageNoise).
    Color3 kdCountedImageStd = Color3::Zero(), ksCountedImageStd = Color3::Zero();
    double logNCountedImageStd = 0;
    // The standard error s of log n whose 3 reach as far sharper as the image's noise there
    // allows (sharperLogNStd; taken in rounds whose estimate may end the fit): n's upper reach is
    // at least n e^(3 s) (finishExponentUncertainty).
    double logNSharperImageStd = 0;
    // "kd", "ks", "n", or per channel "kd.r", "ks.b", ... when only some channels are
    // unconstrained.
    std::vector<std::string> unconstrained;

    PhongMaterial material() const;
    // Whether `name` ("kd", "ks.g", "n") is listed in `unconstrained`.
    bool isUnconstrained(const std::string& name) const;
    // Whether channel c (0-2) of `name` ("kd", "ks") is listed there, whole or by channel.
    bool channelUnconstrained(const std::string& name, int c) const;
    // Whether ks, or one of its channels, is listed there.
    bool ksUnconstrained() const;
};

// The free parameters whose standard error is as large as the parameter itself (kd and ks:
// std >= max(value, 0.01) in some channel; n: std >= n, uncertain by a factor 2 or more), by
// name ("kd", "ks", "n"): what the round's recordings and the images do not resolve.
std::vector<std::string> unresolvedParameters(const MaterialFit& fit);

// Whether a fit's result lists n unconstrained because no lobe holds it (lobeHoldsExponent in
// round_outcome.h), not because the fit held it: a held n reports a standard error of 0, this one
// keeps its own.
bool exponentListedForNoLobe(const MaterialFit& fit);

// FitOptions::fitExposure: the global scale s of every prediction (observed = s * rendered).
struct ExposureFit {
    double value = 1, std = 0;
    // The images cannot tell s from the overall scale of kd and ks (one object under direct light
    // only, nothing of known reflectance in view): s is then held where the start materials match
    // the images' brightness, or as far above as kd + ks <= 1 needs, and kd and ks are relative
    // to it (only s kd and s ks are measured).
    bool unconstrained = false;
};

struct FitRound {
    int round = 0;
    std::size_t paths = 0;  // traced in the round's recordings, over all views
    // FitOptions::precision's paths where a fitted material is seen, relative to the first round's
    // (PathRecorder's pathFactor; kProbePaths in a sharper probe's round, probePaths in a second
    // one).
    double pathFactor = 1;
    double timeSeconds = 0;    // recording + solving
    double recordSeconds = 0;  // in the recorder
    // The two recorded path sets of all views: terms and vertices, in bytes.
    std::size_t recordedBytes = 0;
    // The most the process held from the rounds' start to the round's end (ResidentPeak).
    std::size_t peakMemoryBytes = 0;
    // Pages of the program's code and libraries (file-backed, fileResidentBytes) the process took
    // in since the rounds began, as the round began: code that first runs in the fit.
    std::size_t programBytes = 0;
    double rmse = 0;     // at this round's solution, of the mean prediction of its two path sets
    int iterations = 0;  // Ceres iterations, over all solves of the round
    double secondsPerIteration = 0;
    std::vector<MaterialFit> materials;
    ExposureFit exposure;  // with FitOptions::fitExposure
    // Recorded at a sharper lobe than the converged estimate before it (sharper_probe.h); if its
    // lobes came back, the result is that estimate's.
    bool probe = false;
    // Recorded at a broad stride from the round before's recording (broad_stride.h).
    bool broadStride = false;
    // The rounds, this one the last, whose estimates the estimate after it pools
    // (pooled_rounds.h): 1 where it is this round's own.
    int pooledRounds = 1;
};

// The command line's --precision (fit, bench fit, demo): recorded fits spend paths until every free
// parameter is known to 1%. Measured on the recovery matrix: sharp lobes (n >= 3000) that 4 paths
// per pixel and round leave 10-20% off come back within 1% (README, "The recovery matrix").
inline constexpr double kDefaultPrecision = 0.01;

struct FitOptions {
    Estimator estimator = Estimator::InstrumentalVariables;
    bool grey = false;  // kd and ks shared by the three channels
    // Fit an unknown global exposure s with the materials (observed = s * rendered, for
    // photographs of uncertain exposure or light power), s in [kMinExposure, kMaxExposure]. Its
    // start matches the start materials' brightness to the images'.
    bool fitExposure = false;
    LossKind loss = LossKind::L2;
    // Huber/Cauchy scale as a fraction of the mean observed intensity (over used pixels and
    // channels): a pixel whose RGB residual norm exceeds it counts as an outlier.
    double lossScale = 0.1;
    int maxRounds = 6;
    // Before the first solve, scan each material's exponent over its range (factors of 4) with kd
    // and ks at their best for each value, and start from the best: a start with n off by 10x or
    // more can otherwise end in a local minimum. Off for callers that scan themselves (captures).
    bool scanStart = true;
    // Whether the recorder draws paths by the estimate it records at (false: delta lights seen
    // directly, so no vertex on a fitted material samples a direction and a round replays any
    // lobe as well as another). Only such recordings can be blind to a sharper lobe: without,
    // no sharper probe (sharper_probe.h).
    bool recordingFollowsEstimate = true;
    // Whether some light is seen over a solid angle (an area light, an environment): a lobe's
    // direct highlight is then the light's image, which paths recorded at a broader lobe rarely
    // reach, where a delta light's is replayed at any lobe. Only then are lobes probed sharper
    // (sharper_probe.h): a converged one, and the untested sharper side of rounds that end
    // unsettled (sharperSideUntested).
    bool extendedLights = true;
    // Converged when, between the estimate a round recorded at and the one it solved for, every
    // free kd, ks changed by less than tolerance * max(|value|, 0.01) and log n by less than
    // tolerance, or the parameter moved less than stdTolerance standard errors (two rounds'
    // estimates differ by about 1.4 standard errors from noise alone; 3 passes that 97% of the
    // time). Round 0, which records at the start rather than at an estimate, and the instrument
    // updates within a round stop at `tolerance` alone.
    double tolerance = 1e-3;
    double stdTolerance = 3;
    int maxIterations = 100;  // Ceres iterations per solve (moment solves: kMomentIterations)
    // Seconds the fit may take, recording included (0: no limit). No round starts that the last
    // round's time says would end past it, and a solve under way at the limit stops there; the
    // first round always runs. The result then says "time budget".
    double timeBudget = 0;
    // Bytes the whole process may hold (0: what the machine has available). A recording fit
    // that cannot fit its first round fails before recording (Error); no later round starts
    // whose paths, forecast from the last round's, would not fit: the result then says "memory".
    std::size_t memoryLimit = 0;
    // Target relative standard error of every free parameter (kd, ks: std / max(value, 0.1); n:
    // std / n), 0 for none. Once the estimate has stopped moving and a parameter is less precise,
    // the next rounds record more paths (PathRecorder's pathFactor) until the target is met
    // ("precision"), more paths cannot meet it because the images' own noise dominates ("noise
    // floor"), or the rounds or the time budget are spent; only the first two are converged.
    double precision = 0;
    int threads = 0;       // 0 = all hardware threads
    bool verbose = false;  // Ceres' progress on stdout and its brief report on stderr
    std::function<void(const FitRound&)> onRound;  // called after each round, e.g. for progress
    RenderedNoise renderedNoise;  // unset: the image's noise modelled from the paths alone
    // Polled between solver iterations and rounds (e.g. interruptRequested): when it returns
    // true, the solve under way stops, its round is finished with the estimate so far, and no
    // further round starts. The result is then marked `interrupted`.
    std::function<bool()> stopRequested;
};

// Whether a view's image agrees with its scene where the geometry's edges cross pixels.
struct EdgeCheck {
    std::size_t pixels = 0;  // edge pixels compared (below kLeastEdgePixels: no verdict)
    // |image - render| over their noise, the median over those whose centre sees a fitted material
    double medianDeviation = 0;
    double misfit = 0;  // the sum of the squared deviations
    // Rendered with another pixel filter, or width, whose misfit is far below the scene's filter's:
    // that filter (edge_agreement.h), and its misfit.
    std::optional<PixelFilter> betterFilter;
    double betterMisfit = 0;
    // A filter of another kind that the edges fit about as well as betterFilter (within
    // kFilterEvidence): of one spread, their shapes are not told apart there. And its misfit.
    std::optional<PixelFilter> alikeFilter;
    double alikeMisfit = 0;
    bool disagrees = false;
};

struct FitResult {
    std::vector<MaterialFit> materials;   // indexed by slot
    std::optional<ExposureFit> exposure;  // with FitOptions::fitExposure
    // The estimate: the materials per slot, and the images' exposure (1 where it is not fitted).
    std::vector<PhongMaterial> fittedMaterials() const;
    double exposureValue() const { return exposure ? exposure->value : 1.0; }
    double rmse = 0;  // of the last round
    std::vector<FitRound> rounds;
    double timeSeconds = 0;
    // The parameters stopped moving between rounds or, on exact path sets (the same list passed
    // as both recordings), the solver converged; and every free parameter is resolved.
    bool converged = false;
    bool interrupted = false;  // FitOptions::stopRequested cut the fit short
    // Why the rounds stopped: "converged", "precision" or "noise floor" (FitOptions::precision),
    // "unresolved" (the estimate stopped moving, but some parameter's standard error is as large
    // as itself: unresolvedParameters), "rounds" (FitOptions::maxRounds spent), "precision not
    // met" (they were spent after the estimate had stopped moving), "path cap" (it stopped
    // moving short of the precision, and the pixels that inform it hold the most paths a
    // recording gives: path_growth.h), "sharper lobe" (they were
    // spent as a round recorded at a sharper lobe moved the estimate there, or the last round, a
    // probe, did not come back to the estimate reported: sharper_probe.h), "time budget"
    // (FitOptions::timeBudget), "memory" (FitOptions::memoryLimit), "interrupted", or (scene
    // fits) "images disagree": converged, but an image disagrees with its scene (edgeChecks), or
    // "pixel filter unresolved": converged, but the fits with two filters an unnamed film's edges
    // fit alike differ by more than their standard errors (holdBothFilters).
    std::string stopReason;
    // Last round, over all views: pixels that see a fitted material, and (instrumental variables)
    // the pixels within 2 of one, whose residuals enter the moments without depending on theta.
    std::size_t pixelsUsed = 0;
    std::map<std::string, std::size_t> pixelsLeftOut;  // last round, by reason
    // The process' resident bytes when the rounds began (scene, images and renderer loaded); the
    // rounds' peakMemoryBytes count from then on (earlier peaks are forgotten where Linux allows).
    std::size_t residentAtStartBytes = 0;
    // Scene fits, per view: the image against a render at the estimate where the scene's edges
    // cross pixels (edge_agreement.h). Empty: not checked.
    std::vector<EdgeCheck> edgeChecks;
};

// Records the path set of `view` at the estimate `theta0` (indexed by slot). It is called twice per
// view and round, with `recording` = 2 * round and 2 * round + 1, for the two sets the estimator
// needs; the two must be statistically independent, so the recorder must draw its random numbers
// from `recording` (e.g. seed it with it). `importance` (empty in the first round) says per pixel
// how much a path there is worth to the estimate (path_importance.h): a recorder that spends extra
// paths in proportion to it (fixed before tracing) gets more precision for its time.
// `pathFactor` (1 in the first round) is how many times the first round's paths the fitter asks
// for in the pixels that see a fitted material (FitOptions::precision), the extra ones spent by
// `importance` too; below 1 (the sharper probe's round, sharper_probe.h) in every pixel. The
// fitter plans as if the extra paths were shared by allocatePaths within kMostExtraPaths a pixel
// (path_growth.h), and stops asking for more where that cap leaves them little to give.
using PathRecorder =
    std::function<PathSet(int view, const std::vector<PhongMaterial>& theta0, int recording,
                          const std::vector<float>& importance, double pathFactor)>;

// The rounds loop. `start` (one material per slot, each valid) is the first estimate and the value
// unconstrained parameters are held at. Path sets must match their observation's size and have
// start.size() slots. Throws Error on inconsistent input.
FitResult fitMaterials(const std::vector<Observation>& observations, const PathRecorder& record,
                       const std::vector<PhongMaterial>& start, const FitOptions& options = {});

// Rounds on given path sets, without re-recording (a round after the first starts from the last
// solution): `first` and `second` hold one set per view, independent recordings of the same scene.
// Exact (noise-free) sets are passed as the same list twice, which least squares replays once.
FitResult fitPathSets(const std::vector<Observation>& observations,
                      const std::vector<PathSet>& first, const std::vector<PathSet>& second,
                      const std::vector<PhongMaterial>& start, const FitOptions& options = {},
                      int rounds = 1);

}  // namespace phongfit
