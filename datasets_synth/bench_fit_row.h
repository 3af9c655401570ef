// One fit of `phongfit bench fit`: a dataset sample at one spp per round, what came back, how far
// from the truth, and the estimate after each round. Saved as JSON beside the fit's outputs once
// the fit is done, so an interrupted run or a shard resumes without refitting, and the tables are
// always made from the saved rows (a run on one machine and a merge of shards write the same).
#pragma once

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "fitter.h"
#include "synth_dataset.h"

namespace phongfit {

// Relative errors: of a colour, the RGB distance over the true colour's length (absolute where the
// truth is 0, no lobe).
struct Errors {
    double kd = 0, ks = 0, n = 0;
};

Errors errorsOf(const MaterialFit& m, const PhongMaterial& truth);

// The reported standard errors relative to the truth, as errorsOf measures the errors: what the
// fit says its error is, to set beside what it is.
Errors relativeStdOf(const MaterialFit& m, const PhongMaterial& truth);

bool isFinite(const MaterialFit& m);

// Against the recovery target: see judge() in bench_fit.cpp.
struct Verdict {
    bool withinTolerance = true, pass = true;
};

struct RoundPoint {
    double seconds = 0;  // cumulative, over the rounds so far
    Errors errors;
    Errors stds;  // reported standard errors, relative (relativeStdOf)
};

struct FitRow {
    const DatasetSample* sample = nullptr;
    int spp = 0;
    bool returned = false;  // false: the fit threw (see `error`)
    MaterialFit fit;
    int rounds = 0;
    bool converged = false;
    double seconds = 0;  // wall time of the whole fit command
    double rmse = 0;
    Errors errors;
    bool withinErrors = false;
    Verdict verdict{false, false};
    bool failed = false;
    std::string error;
    std::vector<RoundPoint> history;
};

// Every number as written (doubles exactly, non-finite ones as strings); `run` says which run
// made it (bench_fit.cpp's run key).
nlohmann::json toJson(const FitRow& row, const std::string& run);

// The row of `sample` saved by toJson; throws Error naming `file` when it is malformed.
FitRow fitRowFromJson(const nlohmann::json& j, const DatasetSample& sample,
                      const std::string& file);

}  // namespace phongfit
