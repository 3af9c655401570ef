// Fits Modified Phong parameters to observed images by replaying recorded path sets (DESIGN.md,
// "Path replay"), round after round:
//
//   record a path set per view at the current estimate -> solve (Ceres, all views jointly) ->
//   find the parameters the images do not constrain, hold them at their start values, re-solve ->
//   standard errors -> repeat until the parameters stop moving.
#pragma once

#include <cstddef>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include "observation.h"
#include "path_set.h"
#include "phong_brdf.h"

namespace phongfit {

enum class LossKind { L2, Huber, Cauchy };

// "l2", "huber" or "cauchy"; throws Error naming the allowed values otherwise.
LossKind parseLoss(const std::string& name);

struct MaterialFit {
    Color3 kd = Color3::Zero(), ks = Color3::Zero();
    double n = 0;
    // Standard errors; 0 for the parameters in `unconstrained`, which are held at their start.
    Color3 kdStd = Color3::Zero(), ksStd = Color3::Zero();
    double nStd = 0;
    // "kd", "ks", "n", or per channel "kd.r", "ks.b", ... when only some channels are
    // unconstrained.
    std::vector<std::string> unconstrained;

    PhongMaterial material() const;
};

struct FitRound {
    int round = 0;
    double timeSeconds = 0;    // recording + solving
    double recordSeconds = 0;  // in the recorder
    double rmse = 0;           // at this round's solution, on this round's path sets
    int iterations = 0;        // Ceres iterations, over all solves of the round
    double secondsPerIteration = 0;
    std::vector<MaterialFit> materials;
};

struct FitOptions {
    bool grey = false;  // kd and ks shared by the three channels
    LossKind loss = LossKind::L2;
    // Huber/Cauchy scale as a fraction of the mean observed intensity (over used pixels and
    // channels): a pixel whose RGB residual norm exceeds it counts as an outlier.
    double lossScale = 0.1;
    int maxRounds = 6;
    // Converged when, between the estimate a round recorded at and the one it solved for, every
    // free kd, ks changed by less than tolerance * max(|value|, 0.01) and log n by less than
    // tolerance, or the parameter moved less than stdTolerance standard errors: with fresh random
    // numbers each round, two rounds' estimates differ by about 1.4 standard errors from noise
    // alone, and no tolerance below that is ever met.
    double tolerance = 1e-3;
    double stdTolerance = 2;
    int maxIterations = 100;  // Ceres iterations per solve
    int threads = 0;          // 0 = all hardware threads
    bool verbose = false;     // Ceres' progress on stdout and its brief report on stderr
    std::function<void(const FitRound&)> onRound;  // called after each round, e.g. for progress
};

struct FitResult {
    std::vector<MaterialFit> materials;  // indexed by slot
    double rmse = 0;                     // of the last round
    std::vector<FitRound> rounds;
    double timeSeconds = 0;
    bool converged = false;
    std::size_t pixelsUsed = 0;                        // last round, over all views
    std::map<std::string, std::size_t> pixelsLeftOut;  // last round, by reason
};

// Records the path set of `view` at the estimate `theta0` (indexed by slot). `round` counts from 0;
// the recorder draws fresh random numbers from it if it wants them.
using PathRecorder =
    std::function<PathSet(int view, const std::vector<PhongMaterial>& theta0, int round)>;

// The rounds loop. `start` (one material per slot, each valid) is the first estimate and the value
// unconstrained parameters are held at. Path sets must match their observation's size and have
// start.size() slots. Throws Error on inconsistent input.
FitResult fitMaterials(const std::vector<Observation>& observations, const PathRecorder& record,
                       const std::vector<PhongMaterial>& start, const FitOptions& options = {});

// One round on given path sets (no re-recording).
FitResult fitPathSets(const std::vector<Observation>& observations,
                      const std::vector<PathSet>& paths, const std::vector<PhongMaterial>& start,
                      const FitOptions& options = {});

}  // namespace phongfit
