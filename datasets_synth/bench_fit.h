// phongfit bench fit: fits every sample of a synth dataset (through runFit, the code path of
// `phongfit fit`) from one start far from the truth, for several spp per round, and reports how
// well and how fast the parameters come back.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "fitter.h"
#include "math.h"
#include "shard.h"

namespace phongfit {

struct BenchFitOptions {
    std::string dataset, output;
    std::vector<int> sppPerRound = {4, 16};
    // The same start for every sample, so it is far from most truths.
    Color3 startKd = Color3::Constant(0.25), startKs = Color3::Constant(0.25);
    double startN = 100;
    // When > 0, each sample's start exponent is this factor off its truth instead of startN:
    // truth x factor, or truth / factor where that would pass kMaxStartN.
    double startNFactor = 0;
    // The recovery target: kd and ks per channel within kdKsTolerance (relative) or
    // toleranceFloor (absolute), n within nTolerance (relative).
    double kdKsTolerance = 0.02, toleranceFloor = 0.003, nTolerance = 0.05;
    int rounds = 6;
    int adaptiveSpp = 0;             // SceneRecording::adaptiveSpp (fit --adaptive-spp)
    bool sampledAreaLights = false;  // !SceneRecording::lightRings (fit --sampled-area-lights)
    double precision = kDefaultPrecision;  // FitOptions::precision (fit --precision)
    double timeBudget = 0;  // FitOptions::timeBudget of each fit (fit --time-budget); 0: none
    // A fit fails when it throws, returns a non-finite value, or misses a parameter by more than
    // this relative error.
    double failThreshold = 0.5;
    int threads = 0;
    bool quiet = false;
    Shard shard;  // the fits k (spp index x samples + sample index) with k mod N = I
};

// Writes DIR/recovery.csv (one row per sample and spp), DIR/rounds.csv (the estimate after each
// round), DIR/recovered_vs_true.png, DIR/error_vs_time_fit.png, DIR/summary.json, DIR/summary.md
// and DIR/machine.json, with each fit's own outputs in DIR/fits/spp<N>/<sample>/; prints the
// summary table. Stops after the current fit on SIGINT, writing what it has.
//
// Each fit's row is saved beside its outputs (fits/spp<N>/<sample>/bench_row.json) with the run's
// key (DIR/bench_run.json: settings, dataset index, build), so a rerun or a shard resumes without
// refitting; the tables are written from the saved rows by whichever shard finds them all.
void runBenchFit(const BenchFitOptions& options);

// `bench fit --merge DIR`: the tables from the rows the shards saved. Throws Error when fits are
// missing or the dataset or build changed since the run began.
void mergeBenchFit(const std::string& dir, int threads);

// The largest start exponent --start-n-factor picks by multiplying.
constexpr double kMaxStartN = 1e5;

}  // namespace phongfit
