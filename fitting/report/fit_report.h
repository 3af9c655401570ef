// fit.json: the fitted parameters, their standard errors, what the images leave unconstrained,
// and the per-round history (DESIGN.md, "Command line").
#pragma once

#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "fitter.h"

namespace phongfit {

// {"materials": {"<id>": {"kd", "ks", "n", "kd_std", "ks_std", "n_std", "unconstrained"}},
//  "rmse", "converged", "rounds": [{"round", "time_s", "record_time_s", "rmse", "iterations",
//  "time_per_iteration_s", "recorded_bytes", "peak_memory_bytes", "materials"}], "time_s",
//  "pixels_used", "pixels_left_out": {reason: n}}, with FitOptions::fitExposure also "exposure":
//  {"value", "std", "unconstrained"} at the top and in each round.
// `materialIds` names the slots in order; throws Error if the counts differ.
nlohmann::json toJson(const FitResult& result, const std::vector<std::string>& materialIds);

// Writes toJson(result, materialIds) to `path` atomically (a failure leaves no partial file).
void writeFitReport(const std::filesystem::path& path, const FitResult& result,
                    const std::vector<std::string>& materialIds);

}  // namespace phongfit
