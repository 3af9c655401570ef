// The tables and plots of `phongfit bench fit`, made from its fit rows (bench_fit_row.h): one
// machine's run and a merge of shards write them alike.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "bench_fit.h"
#include "bench_fit_row.h"

namespace phongfit {

// Writes recovery.csv, rounds.csv, recovered_vs_true.png, error_vs_time_fit.png, machine.json,
// summary.json and summary.md into options.output from `rows` (spp-major, in dataset order) of a
// dataset of `samples` samples, and prints the summary table; `interrupted`: the rows are those
// done when the run was stopped.
void writeBenchFitReport(const std::vector<FitRow>& rows, const BenchFitOptions& options,
                         std::size_t samples, bool interrupted);

// A relative error as a percentage, "-" for NaN.
std::string percentText(double v);

}  // namespace phongfit
