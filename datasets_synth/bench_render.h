// phongfit bench render: error against wall time of every Phong sampler, with and without MIS, on
// independent and on Sobol pixel samples, and each one's efficiency relative to a baseline.
// Each strategy renders the scene at 1, 2, 4, ... spp (fresh renders with one seed, so each holds
// the samples of the one before) until its time budget is spent; each render is compared with a
// high-spp reference rendered with another seed.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "image_error.h"

namespace phongfit {

struct BenchRenderOptions {
    std::string scene;
    std::vector<std::string> defines;  // name=value, as -D
    std::string reference;             // EXR of the scene; empty: render one (the defaults)
    int referenceSpp = 4096;
    std::string output;  // directory
    double budget = 10;  // seconds per strategy
    int sppMax = 1 << 16;
    std::vector<std::string> strategies;     // names; empty: all
    std::string baseline = "lafortune+mis";  // efficiencies are relative to it
    std::uint64_t seed = 0;
    int threads = 0;  // 0: all
    bool quiet = false;
};

struct BenchRenderRow {
    std::string strategy;  // "sobol/" on Sobol samples, the Phong sampler, "+mis" when with MIS
    int spp = 0;
    double seconds = 0;  // wall time of the render (the scene is built once, outside)
    ImageError error;
};

// Writes DIR/error_vs_time.csv (strategy,spp,time_s,rmse,relmse,efficiency_vs_baseline),
// DIR/error_vs_time.png,
// DIR/machine.json and, when it rendered one, DIR/reference.exr; prints a table of each
// strategy's last point. Stops early (writing what it has) on SIGINT. Throws Error on bad input.
std::vector<BenchRenderRow> runBenchRender(const BenchRenderOptions& options);

}  // namespace phongfit
