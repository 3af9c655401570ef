// phongfit fit --capture DIR [--lights 1-48] [--holdout 49-96] ... -o OUTDIR: the fit command on a
// photometric-stereo capture (capture.h, capture_fit.h) instead of a scene.
#pragma once

#include <CLI/CLI.hpp>
#include <optional>
#include <string>

#include "fit_command.h"
#include "fitter.h"

namespace phongfit {

struct CaptureArgs {
    std::string dir;
    std::string lights, holdout;  // 1-based light lists such as "1-10,20"; empty: see --lights
    double minCos = 0.05;
    std::string mask, output;
    std::optional<double> saturation, gamma;
    bool srgb = false, linear = false;
    bool grey = false;
    std::string loss = "l2";
    int threads = 0;
    bool quiet = false, verbose = false;
};

// Reads and checks the capture, fits Phong on the fitted lights (with --holdout also
// Lambertian-only, and predicts the held-out lights with both), writes OUTDIR/fit.json and
// compare.png, and prints the recovered parameters and the hold-out errors. Throws Error (nothing
// written) on bad input.
FitResult runCaptureFit(const CaptureArgs& args);

// Adds --capture, --lights, --holdout and --min-cos to the fit subcommand.
void addCaptureOptions(CLI::App& fit, CaptureArgs& args);

// The fit subcommand's dispatch. Throws Error unless exactly one of --view and --capture was
// given. With --capture: runs runCaptureFit on `capture` completed with the options both kinds of
// fit share (output, mask, loss, grey, decoding, saturation, threads, quiet, verbose) from
// `shared`, and returns true; throws Error if an option only scene fits take was given. With
// --view: throws Error if an option only capture fits take was given, else returns false.
bool runCaptureFitIfGiven(const CLI::App& fit, const CaptureArgs& capture, const FitArgs& shared);

}  // namespace phongfit
