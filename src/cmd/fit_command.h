// The fit command's arguments and its run, shared by `phongfit fit` and `phongfit demo`.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "fitter.h"

namespace phongfit {

struct FitArgs {
    std::vector<std::string> views, materials, defines;
    std::string mask, output;
    std::string kd, ks;  // start overrides: one number or R,G,B
    std::optional<double> n;
    int spp = 4;
    int directSpp = 0;    // RecordOptions::directSpp
    int compareSpp = 32;  // paths per pixel of compare.png's re-rendered column
    int rounds = 6;
    std::string loss = "l2";
    bool grey = false;
    bool fitExposure = false;
    std::optional<double> gamma;
    bool srgb = false, linear = false;
    std::optional<double> saturation;
    bool ignoreNonFinite = false;
    std::uint64_t seed = 0;
    int threads = 0;
    bool quiet = false, verbose = false;
};

// Reads and checks every input, fits, writes OUTDIR/fit.json, fitted.xml and compare.png, and
// prints the recovered parameters. Throws Error (nothing written) on bad input.
FitResult runFit(const FitArgs& args);

}  // namespace phongfit
