// phongfit fit --view SCENE.xml:IMAGE [--view ...] --material ID ... -o OUTDIR
// phongfit fit --capture DIR [--lights 1-48] [--holdout 49-96] ... -o OUTDIR
// Options only one kind of fit takes sit in that kind's option group: given to the other kind,
// any of them is an error, so none is silently ignored.
#include <fmt/format.h>
#include <fmt/ranges.h>

#include <chrono>
#include <cmath>
#include <optional>

#include "atomic_file.h"
#include "capture_run.h"
#include "color_option.h"
#include "commands.h"
#include "comparison_image.h"
#include "defines.h"
#include "error.h"
#include "filters_from_edges.h"
#include "fit_printing.h"
#include "interrupt.h"
#include "scene_fit.h"

namespace phongfit {
namespace {

struct FitCli {
    // Both kinds of fit.
    std::string output, mask, loss = "l2";
    bool grey = false;
    std::optional<double> gamma, saturation;
    bool srgb = false, linear = false;
    int threads = 0;
    bool quiet = false, verbose = false;
    // Scene fits.
    std::vector<std::string> views, materials, defines;
    std::string kd, ks;
    std::optional<double> n;
    double timeBudget = 0, precision = kDefaultPrecision, maxMemory = 0;
    int spp = 4, directSpp = 0, adaptiveSpp = 0, compareSpp = 32, rounds = 6, imageSpp = -1;
    bool fitExposure = false, ignoreNonFinite = false, keepIndirect = false;
    bool sampledAreaLights = false;
    std::uint64_t seed = 0;
    // Capture fits.
    std::string capture, lights, holdout, albedo = "uniform", intensities = "auto";
    int materialCount = 1;
    double minCos = 0.05;
};

ReadOptions decoding(const FitCli& a) {
    if (int(a.gamma.has_value()) + int(a.srgb) + int(a.linear) > 1)
        throw Error("--gamma, --srgb and --linear exclude each other");
    ReadOptions o;
    if (a.gamma) {
        if (!(*a.gamma > 0) || !std::isfinite(*a.gamma))
            throw Error(fmt::format("--gamma {}: must be a finite number > 0", *a.gamma));
        o.encoding = Encoding::Gamma;
        o.gamma = *a.gamma;
    }
    if (a.srgb) o.encoding = Encoding::Srgb;
    if (a.linear) o.encoding = Encoding::Linear;
    return o;
}

FitOptions fitOptions(const FitCli& a) {
    FitOptions o;
    o.loss = parseLoss(a.loss);
    o.grey = a.grey;
    o.threads = a.threads;
    o.stopRequested = interruptRequested;
    o.verbose = a.verbose;
    return o;
}

// Of the fits with the filters the edges named and those they fit alike, the one whose estimate
// renders closer to the images, its standard errors holding the other's estimate
// (filters_from_edges.h); `problem` and `result` hold the named one's and take the one kept.
void keepCloserFit(SceneFitProblem& problem, FitResult& result, SceneFitProblem&& otherProblem,
                   FitResult&& other, const std::vector<std::optional<PixelFilter>>& named,
                   const std::vector<std::optional<PixelFilter>>& alike,
                   const SceneRecording& recording) {
    const auto begin = std::chrono::steady_clock::now();
    const ImageResiduals residuals =
        imageResiduals(problem, result, otherProblem, other, recording);
    const double seconds =
        other.timeSeconds +
        std::chrono::duration<double>(std::chrono::steady_clock::now() - begin).count();
    printFilterChoice(problem, named, alike, residuals);
    if (residuals.secondBetter) {
        otherProblem.otherFilterFit = {named, residuals.first, residuals.second};
        holdBothFilters(other, result);
        problem = std::move(otherProblem);
        result = std::move(other);
    } else {
        problem.otherFilterFit = {alike, residuals.second, residuals.first};
        holdBothFilters(result, other);
    }
    result.timeSeconds = seconds;
}

void runSceneFit(const FitCli& a) {
    SceneFitInputs in;
    in.defines = parseDefines(a.defines);
    FitOptions options = fitOptions(a);
    options.fitExposure = a.fitExposure;
    options.maxRounds = a.rounds;
    options.timeBudget = a.timeBudget;
    options.memoryLimit = std::size_t(a.maxMemory * 1e9);
    options.precision = a.precision;
    requireOutputDirectory(a.output);
    for (const std::string& spec : a.views) {
        const auto colon = spec.rfind(':');
        if (colon == std::string::npos || colon == 0 || colon + 1 == spec.size())
            throw Error(fmt::format("--view '{}': expected SCENE.xml:IMAGE", spec));
        in.views.push_back({spec.substr(0, colon), spec.substr(colon + 1)});
    }
    in.materials = a.materials;
    in.maskPath = a.mask;
    in.decoding = decoding(a);
    in.saturation = a.saturation;
    in.ignoreNonFinite = a.ignoreNonFinite;
    in.keepIndirect = a.keepIndirect || a.fitExposure;
    if (!a.kd.empty()) in.kd = parseColorOption(a.kd, "--kd");
    if (!a.ks.empty()) in.ks = parseColorOption(a.ks, "--ks");
    in.n = a.n;
    SceneFitProblem problem = loadSceneFit(in);
    printSceneWarnings(problem);
    const SceneRecording recording{a.spp,         a.directSpp,          a.seed,    a.threads,
                                   a.adaptiveSpp, !a.sampledAreaLights, a.imageSpp};
    if (!a.quiet)
        options.onRound = [&](const FitRound& r) { printRound(r, problem, a.fitExposure); };
    FitResult result = fitScene(problem, recording, options);
    // A film that names no filter, whose image's edges show another than phongfit's box: fitted
    // again with that one; where they fit one of another kind as well, with that one too, keeping
    // the fit that holds the images better. Unless interrupted or what is left of the time budget
    // would not hold a first round (as long as the first fit's).
    const double firstRound = result.rounds.empty() ? 0 : result.rounds.front().timeSeconds;
    const auto room = [&] {
        return !result.interrupted &&
               (options.timeBudget <= 0 || options.timeBudget - result.timeSeconds > firstRound);
    };
    const auto fitWith = [&](const std::vector<std::optional<PixelFilter>>& filters) {
        in.edgeFilters = filters;
        std::pair<SceneFitProblem, FitResult> out;
        out.first = loadSceneFit(in);
        FitOptions o = options;
        if (o.timeBudget > 0) o.timeBudget -= result.timeSeconds;
        out.second = fitScene(out.first, recording, o);
        out.second.timeSeconds += result.timeSeconds;
        return out;
    };
    // Another fit with `filters`, the one that renders closer kept (`used`: the first fit's).
    const auto fitAlsoWith = [&](const std::vector<std::optional<PixelFilter>>& used,
                                 const std::vector<std::optional<PixelFilter>>& filters) {
        auto [otherProblem, other] = fitWith(filters);
        if (other.interrupted) {
            fmt::print("interrupted: the fit with the edges' filter stands\n");
            result.interrupted = true;
            result.timeSeconds = other.timeSeconds;
        } else {
            keepCloserFit(problem, result, std::move(otherProblem), std::move(other), used, filters,
                          recording);
        }
    };
    const auto named = edgeFilters(problem, result), alike = alikeFilters(problem, result),
               untold = untoldFilters(problem, result);
    if (!named.empty() && room()) {
        printEdgeFilters(problem, result, named);
        const std::vector<EdgeCheck> checks = result.edgeChecks;
        std::tie(problem, result) = fitWith(named);
        if (!alike.empty() && room()) {
            printAlikeFilters(problem, checks, named, alike);
            fitAlsoWith(named, alike);
        }
    } else if (!untold.empty() && room()) {
        printUntoldFilters(problem, untold);
        std::vector<std::optional<PixelFilter>> box(untold.size());
        for (std::size_t k = 0; k < untold.size(); ++k)
            if (untold[k]) box[k] = PixelFilter{};
        fitAlsoWith(box, untold);
    }
    writeSceneFit(problem, result, recording, a.compareSpp, a.output);
    printSceneFit(problem, result, a.grey, a.output);
}

void printLeftOut(const CaptureRun& run, const CaptureModel& model) {
    fmt::print(
        "left out {} pairs ({} below --min-cos, {} clipped, {} not finite, {} facing away)\n",
        model.pairs - model.used, model.leftOut.at("below_min_cos"), model.leftOut.at("clipped"),
        model.leftOut.at("non_finite"), model.leftOut.at("facing_away"));
    fmt::print("photographs: {}\n", run.images.front().decoding);
    if (const auto& check = run.decodingCheck; check && check->otherFitsBetter)
        fmt::print(
            "warning: the photographs look {0}, not {1}: read as {0}, {2:.0f}% of the pixels "
            "follow the model more closely; if they are {0}, fit with --{3}\n",
            curveName(check->other), curveName(check->used), 100 * check->otherBetterFraction,
            check->other == Encoding::Srgb ? "srgb" : "linear");
    fmt::print("light intensities: {}{}\n", run.intensities,
               run.intensities == "calibrated"
                   ? ""
                   : ": kd and ks in the images' units, no energy bound; n absolute");
    if (run.capture.badNormals > 0)
        fmt::print("left out {} pixel{} of the mask whose normal is zero, not unit or not finite\n",
                   run.capture.badNormals, run.capture.badNormals == 1 ? "" : "s");
}

void printHoldout(const CaptureRun& run, const HoldoutPrediction& holdout,
                  const std::string& baseline) {
    fmt::print(
        "held out {} lights ({} pairs): rmse {:.5g} (relative {:.3g}), {} {:.5g} (relative "
        "{:.3g})\n",
        run.holdout.size(), holdout.phong.pairs, holdout.phong.rmse, holdout.phong.relRmse,
        baseline, holdout.lambertian.rmse, holdout.lambertian.relRmse);
}

void printUniformFit(const FitCli& a, const CaptureRun& run) {
    const CaptureFit& fit = *run.fit;
    const MaterialFit& m = fit.phong.materials[0];
    fmt::print("capture: kd = {}, ks = {}, n = {:.5g} ± {:.2g}{}\n",
               formatColor(m.kd, m.kdStd, a.grey), formatColor(m.ks, m.ksStd, a.grey), m.n, m.nStd,
               unconstrainedNote(m));
    fmt::print("fitted {} pairs of {} lights: rmse {:.5g}; ", fit.model.used, run.lights.size(),
               fit.phong.rmse);
    printLeftOut(run, fit.model);
    if (fit.energyBoundReached)
        fmt::print(
            "warning: the fit ended on kd + ks = 1, the energy bound: the images are as bright as "
            "an energy-conserving material allows under light_intensities.txt, or brighter; if "
            "the intensities are relative, fit with --intensities relative\n");
    double seconds = fit.phong.timeSeconds;
    if (fit.holdout) {
        const MaterialFit& lam = fit.lambertian->materials[0];
        fmt::print("lambertian only: kd = {}\n", formatColor(lam.kd, lam.kdStd, a.grey));
        printHoldout(run, *fit.holdout, "Lambertian only");
        seconds += fit.lambertian->timeSeconds;
    }
    fmt::print(
        "{} in {:.2f} s; left out: path tracing and indirect light (direct light on known "
        "normals, one bounce) -> {}\n",
        fit.phong.converged ? "converged" : "not converged", seconds,
        (std::filesystem::path(a.output) / "fit.json").string());
}

void printAlbedoMapFit(const FitCli& a, const CaptureRun& run) {
    const AlbedoMapCaptureFit& fit = *run.albedoMap;
    const AlbedoMapFit& m = fit.fit;
    const auto lobeText = [&](const LobeFit& lobe) {
        const std::string n = std::isfinite(lobe.nStd)
                                  ? fmt::format("{:.5g} ± {:.2g}", lobe.n, lobe.nStd)
                                  : fmt::format("{:.5g}", lobe.n);
        return fmt::format(
            "ks = {}, n = {}{}{}", formatColor(lobe.ks, lobe.ksStd, a.grey), n,
            lobe.unconstrained.empty()
                ? ""
                : fmt::format("  (unconstrained: {})", fmt::join(lobe.unconstrained, ", ")),
            lobe.nAtBound
                ? fmt::format("  (at the end of the searched range {:g}-{:g})", m.minN, m.maxN)
                : "");
    };
    if (m.lobes.size() == 1) {
        fmt::print("capture, per-pixel albedo: {}\n", lobeText(m.lobes[0]));
    } else {
        fmt::print("capture, per-pixel albedo, {} materials -> {}\n", m.lobes.size(),
                   (std::filesystem::path(a.output) / "materials.png").string());
        for (std::size_t i = 0; i < m.lobes.size(); ++i)
            fmt::print("  material {} ({} pixels): {}\n", i + 1, m.lobes[i].pixels,
                       lobeText(m.lobes[i]));
    }
    fmt::print("kd map of {} pixels -> {}; {} pixel{} left out with fewer than {} usable pairs\n",
               m.pixelsFitted, (std::filesystem::path(a.output) / "kd.exr").string(),
               m.pixelsTooFewPairs, m.pixelsTooFewPairs == 1 ? "" : "s",
               AlbedoMapOptions{}.minPairs);
    fmt::print("fitted {} pairs of {} lights: rmse {:.5g} (per-pixel Lambertian {:.5g}); ", m.pairs,
               run.lights.size(), m.rmse, m.lambertianRmse);
    printLeftOut(run, fit.model);
    if (fit.holdout) printHoldout(run, *fit.holdout, "per-pixel Lambertian");
    if (run.intensities == "calibrated" && m.energyBoundExceeded)
        fmt::print(
            "warning: {} pixels have kd + ks > 1 beyond their noise (no energy bound is imposed "
            "per pixel): brighter than an energy-conserving material under "
            "light_intensities.txt; if the intensities are relative, say --intensities "
            "relative\n",
            m.kdAboveOne);
    fmt::print("{} in {:.2f} s -> {}\n", m.converged() ? "converged" : "not converged", m.seconds,
               (std::filesystem::path(a.output) / "fit.json").string());
}

void runCaptureFitCommand(const FitCli& a) {
    requireOutputDirectory(a.output);
    CaptureFitInputs in;
    in.dir = a.capture;
    in.lights = a.lights;
    in.holdout = a.holdout;
    in.fit.minCos = a.minCos;
    in.fit.fit = fitOptions(a);
    in.perPixelAlbedo = a.albedo == "per-pixel";
    in.intensities = a.intensities;
    in.materials = a.materialCount;
    if (a.materialCount != 1 && !in.perPixelAlbedo)
        throw Error(fmt::format("--materials {}: applies to --albedo per-pixel", a.materialCount));
    if (in.perPixelAlbedo && a.loss != "l2")
        throw Error(
            fmt::format("--loss {}: --albedo per-pixel fits least squares (l2) only", a.loss));
    in.read.decoding = decoding(a);
    if (a.saturation && !(*a.saturation > 0 && std::isfinite(*a.saturation)))
        throw Error(fmt::format("--saturation {}: must be a finite number > 0", *a.saturation));
    in.read.saturation = a.saturation;
    in.read.mask = a.mask;
    const CaptureRun run = runCaptureFit(in, a.quiet);
    writeCaptureFit(run, in, a.loss, a.output);
    if (run.albedoMap)
        printAlbedoMapFit(a, run);
    else
        printUniformFit(a, run);
}

// Throws Error naming the first option of `group` that was given.
void rejectGroup(const CLI::App& group, const std::string& why) {
    for (const CLI::Option* option : group.get_options())
        if (option->count() > 0) throw Error(fmt::format("{} {}", option->get_name(), why));
}

}  // namespace

void addFitCommand(CLI::App& app) {
    auto a = std::make_shared<FitCli>();
    CLI::App* cmd = app.add_subcommand(
        "fit", "recover kd, ks and n of phong materials from images of a scene or a capture");
    cmd->add_option("-o,--output", a->output, "output directory")->required();
    cmd->add_option("--mask", a->mask, "PNG mask: pixels that are 0 are left out");
    cmd->add_option("--loss", a->loss, "l2, huber or cauchy")
        ->check(CLI::IsMember({"l2", "huber", "cauchy"}));
    cmd->add_flag("--grey", a->grey, "one kd and one ks for all channels");
    cmd->add_option("--gamma", a->gamma, "decode LDR images as value^gamma");
    cmd->add_flag("--srgb", a->srgb, "decode images with the sRGB curve (default for 8-bit)");
    cmd->add_flag("--linear", a->linear, "images are linear (default for 16-bit and EXR)");
    cmd->add_option("--saturation", a->saturation,
                    "leave out pixels with a channel at or above this linear value");
    cmd->add_option("--threads", a->threads, "worker threads (default: all)")
        ->check(CLI::Range(1, 1024));
    cmd->add_flag("--quiet", a->quiet, "no progress lines");
    cmd->add_flag("--verbose", a->verbose, "Ceres reports");

    CLI::Option_group* scene = cmd->add_option_group("scene fits", "with --view");
    scene->add_option(
        "--view", a->views,
        "SCENE.xml:IMAGE (EXR, PFM linear; PNG/JPEG decoded from sRGB); repeat for a joint fit");
    scene->add_option("--material", a->materials, "id of a phong bsdf to fit; repeatable");
    scene->add_option("--spp", a->spp, "paths recorded per pixel and round")
        ->check(CLI::Range(1, 4096));
    scene
        ->add_option("--direct-spp", a->directSpp,
                     "paths recorded per round in pixels that see a fitted material directly "
                     "(default: --spp)")
        ->check(CLI::Range(1, 4096));
    scene
        ->add_option("--time-budget", a->timeBudget,
                     "seconds the fit may take, recording included: no round starts that would "
                     "end past it (the first always runs); the report then says not converged")
        ->check(CLI::NonNegativeNumber);
    scene
        ->add_option("--max-memory", a->maxMemory,
                     "gigabytes the fit may hold (default: what the machine has available): a fit "
                     "whose first round cannot fit fails before recording, and no round starts "
                     "whose paths would not fit (the report then says not converged)")
        ->check(CLI::NonNegativeNumber);
    scene
        ->add_option("--precision", a->precision,
                     "target relative standard error of every free parameter (kd, ks: of "
                     "max(value, 0.1), a ks showing no lobe of max(kd + ks, 0.1); n: of n): once "
                     "the estimate stops moving, rounds record more paths where they inform it "
                     "until every parameter is this precise or the images' own noise stands in "
                     "the way (0: no target)")
        ->check(CLI::Range(0.0, 0.5))
        ->capture_default_str();
    scene
        ->add_option("--adaptive-spp", a->adaptiveSpp,
                     "after the first round, this many more paths per pixel that sees a fitted "
                     "material, on average, spent where they inform the estimate most (0: none)")
        ->check(CLI::Range(0, 4096))
        ->capture_default_str();
    scene
        ->add_option("--compare-spp", a->compareSpp,
                     "paths per pixel of the re-rendered column of compare.png")
        ->check(CLI::Range(1, 4096))
        ->capture_default_str();
    scene
        ->add_option("--image-spp", a->imageSpp,
                     "samples per pixel the images were rendered with: where a pixel or a few "
                     "hold a parameter (a highlight smaller than a pixel), their noise is measured "
                     "on 16 renders of them like the image (-1: the spp of `phongfit render`'s "
                     "IMAGE.json beside the image, else the scene's sampleCount; 0: images without "
                     "noise, such as closed forms)")
        ->check(CLI::Range(-1, 1 << 20))
        ->capture_default_str();
    scene->add_option("--rounds", a->rounds, "at most this many record-and-solve rounds")
        ->check(CLI::Range(1, 100));
    scene->add_flag("--sampled-area-lights", a->sampledAreaLights,
                    "record spherical and rectangular lights by sampling alone, as renders do, "
                    "instead of integrating them by rings about the mirror direction where a "
                    "lobe can reach them (for comparisons)");
    scene->add_flag("--fit-exposure", a->fitExposure,
                    "also fit an unknown global scale of the images (observed = s * rendered)");
    scene->add_flag("--keep-indirect-pixels", a->keepIndirect,
                    "also fit the pixels that see the fitted materials only through other "
                    "surfaces (left out by default where every fitted material is seen directly; "
                    "always kept with --fit-exposure)");
    scene->add_option("--kd", a->kd, "start value, R,G,B or one number (default: the scene's)");
    scene->add_option("--ks", a->ks, "start value, R,G,B or one number (default: the scene's)");
    scene->add_option("--n", a->n, "start value of the exponent (default: the scene's)");
    scene->add_flag("--ignore-nonfinite", a->ignoreNonFinite,
                    "leave out NaN/Inf pixels instead of failing");
    scene->add_option("-D", a->defines, "override a scene default: name=value");
    scene->add_option("--seed", a->seed, "random seed of the recordings");

    CLI::Option_group* capture = cmd->add_option_group("capture fits", "with --capture");
    capture->add_option("--capture", a->capture,
                        "photometric-stereo folder (DiLiGenT layout: filenames.txt, "
                        "light_directions.txt, light_intensities.txt, mask.png, normals.exr) "
                        "instead of --view; --mask replaces its mask.png");
    capture->add_option("--lights", a->lights,
                        "lights to fit, e.g. 1-48 or 1-10,20 (default: all not held out)");
    capture->add_option("--holdout", a->holdout, "lights to predict and not fit, e.g. 49-96");
    capture
        ->add_option("--albedo", a->albedo,
                     "uniform: one kd for the object; per-pixel: a kd per mask pixel (a "
                     "textured object) with one shared ks and n, written to kd.exr")
        ->check(CLI::IsMember({"uniform", "per-pixel"}))
        ->capture_default_str();
    capture
        ->add_option("--materials", a->materialCount,
                     "with --albedo per-pixel: K materials, each with its own ks and n, found by "
                     "clustering the albedo (default 1: one lobe for the object)")
        ->check(CLI::Range(1, kMaxMaterials));
    capture
        ->add_option("--intensities", a->intensities,
                     "calibrated: light_intensities.txt is absolute (kd + ks <= 1); relative: "
                     "known up to a common factor (kd, ks in image units, no energy bound); "
                     "auto: relative when every light has the same intensity")
        ->check(CLI::IsMember({"auto", "calibrated", "relative"}))
        ->capture_default_str();
    capture->add_option("--min-cos", a->minCos,
                        "leave out pairs with n.l below this (shadows, grazing light; default "
                        "0.05)");

    cmd->callback([a, cmd, scene, capture] {
        if (a->views.empty() == a->capture.empty())
            throw Error("fit needs exactly one of --view SCENE.xml:IMAGE and --capture DIR");
        if (a->views.empty()) {
            if (cmd->count("--fit-exposure") > 0)
                throw Error(
                    "--fit-exposure does not apply to --capture: its images are divided by "
                    "calibrated light intensities and lit directly only, so an exposure cannot "
                    "be told from kd and ks");
            rejectGroup(*scene, "applies to scene fits (--view), not to --capture");
            runCaptureFitCommand(*a);
        } else {
            rejectGroup(*capture, "applies to --capture, not to --view");
            runSceneFit(*a);
        }
    });
}

}  // namespace phongfit
