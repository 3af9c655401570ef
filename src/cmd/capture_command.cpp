// phongfit fit --capture DIR ...: fit.json and compare.png for a photometric-stereo capture.
#include "capture_command.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "atomic_file.h"
#include "capture.h"
#include "capture_fit.h"
#include "comparison_image.h"
#include "error.h"
#include "fit_report.h"
#include "image.h"
#include "interrupt.h"
#include "replay.h"

namespace phongfit {
namespace {

namespace fs = std::filesystem;

constexpr int kCompareMargin = 4;  // pixels around the mask's bounding box

CaptureReadOptions readOptions(const CaptureArgs& args) {
    if (int(args.gamma.has_value()) + int(args.srgb) + int(args.linear) > 1)
        throw Error("--gamma, --srgb and --linear exclude each other");
    CaptureReadOptions o;
    if (args.gamma) {
        if (!(*args.gamma > 0) || !std::isfinite(*args.gamma))
            throw Error(fmt::format("--gamma {}: must be a finite number > 0", *args.gamma));
        o.decoding.encoding = Encoding::Gamma;
        o.decoding.gamma = *args.gamma;
    }
    if (args.srgb) o.decoding.encoding = Encoding::Srgb;
    if (args.linear) o.decoding.encoding = Encoding::Linear;
    if (args.saturation && !(*args.saturation > 0 && std::isfinite(*args.saturation)))
        throw Error(fmt::format("--saturation {}: must be a finite number > 0", *args.saturation));
    o.saturation = args.saturation;
    o.mask = args.mask;
    return o;
}

// The fitted and held-out lights (indices), from --lights and --holdout.
std::pair<std::vector<int>, std::vector<int>> selectLights(const CaptureArgs& args, int count) {
    const std::vector<int> holdout = args.holdout.empty()
                                         ? std::vector<int>{}
                                         : parseLightList(args.holdout, count, "--holdout");
    std::vector<bool> heldOut(count, false);
    for (int l : holdout) heldOut[l] = true;
    std::vector<int> lights;
    if (args.lights.empty()) {
        for (int l = 0; l < count; ++l)
            if (!heldOut[l]) lights.push_back(l);
        if (lights.empty())
            throw Error(fmt::format("--holdout '{}' holds out all {} lights: none is left to fit",
                                    args.holdout, count));
    } else {
        lights = parseLightList(args.lights, count, "--lights");
        for (int l : lights)
            if (heldOut[l])
                throw Error(
                    fmt::format("light {} is in both --lights '{}' and --holdout '{}' (a "
                                "held-out light must not be fitted)",
                                l + 1, args.lights, args.holdout));
    }
    return {lights, holdout};
}

nlohmann::json rgb(const Color3& c) { return nlohmann::json::array({c[0], c[1], c[2]}); }

nlohmann::json errorJson(const PredictionError& phong, const PredictionError& lambertian) {
    return {{"pairs", phong.pairs},
            {"rmse", phong.rmse},
            {"rel_rmse", phong.relRmse},
            {"lambertian_rmse", lambertian.rmse},
            {"lambertian_rel_rmse", lambertian.relRmse}};
}

std::vector<int> lightNumbers(const Capture& capture, const std::vector<int>& lights) {
    std::vector<int> numbers;
    for (int l : lights) numbers.push_back(capture.lights[l].number);
    return numbers;
}

// The held-out light whose Phong error is the median: a typical one.
std::size_t medianView(const HoldoutPrediction& prediction) {
    std::vector<std::size_t> order(prediction.perLight.size());
    for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
    std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
        return prediction.perLight[a].phong.rmse < prediction.perLight[b].phong.rmse;
    });
    return order[order.size() / 2];
}

// One row per material (Phong, then Lambertian-only if fitted), cropped to the mask; left-out
// pairs are grey, pixels outside the mask black (comparison_image.h).
cv::Mat comparison(const Capture& capture, const CaptureImage& image, const CaptureModel& model,
                   std::size_t view, const std::vector<PhongMaterial>& rows) {
    const PathSet& ps = model.paths[view];
    int x0 = capture.width, y0 = capture.height, x1 = 0, y1 = 0;
    for (std::uint32_t p : capture.pixels) {
        const int x = int(p % capture.width), y = int(p / capture.width);
        x0 = std::min(x0, x), x1 = std::max(x1, x), y0 = std::min(y0, y), y1 = std::max(y1, y);
    }
    x0 = std::max(0, x0 - kCompareMargin), y0 = std::max(0, y0 - kCompareMargin);
    x1 = std::min(capture.width - 1, x1 + kCompareMargin);
    y1 = std::min(capture.height - 1, y1 + kCompareMargin);
    ComparisonPanels panels;
    panels.width = x1 - x0 + 1;
    panels.height = y1 - y0 + 1;
    panels.whitePercentile = 100;
    const std::size_t size = std::size_t(panels.width) * std::size_t(panels.height);
    panels.observed.assign(size, Color3::Zero());
    panels.state.assign(size, ComparePixel::Outside);
    panels.predicted.assign(rows.size(), std::vector<Color3>(size, Color3::Zero()));
    std::vector<std::size_t> at(capture.pixels.size());
    for (std::size_t i = 0; i < capture.pixels.size(); ++i) {
        const std::size_t x = capture.pixels[i] % std::size_t(capture.width) - std::size_t(x0);
        const std::size_t y = capture.pixels[i] / std::size_t(capture.width) - std::size_t(y0);
        at[i] = y * std::size_t(panels.width) + x;
        panels.observed[at[i]] = image.rgb[i].cast<double>();
        panels.state[at[i]] = ComparePixel::LeftOut;
    }
    for (std::size_t k = 0; k < model.entries[view].size(); ++k) {
        const std::size_t p = at[model.entries[view][k]];
        panels.state[p] = ComparePixel::Compared;
        for (std::size_t row = 0; row < rows.size(); ++row)
            panels.predicted[row][p] = replayPixel(ps, k, &rows[row]);
    }
    return comparisonImage(panels);
}

nlohmann::json holdoutJson(const Capture& capture, const CaptureFit& fit) {
    nlohmann::json out = errorJson(fit.holdout->phong, fit.holdout->lambertian);
    out["pairs_left_out"] = fit.heldOut->leftOut;
    out["per_light"] = nlohmann::json::array();
    for (const LightPrediction& l : fit.holdout->perLight) {
        nlohmann::json j = errorJson(l.phong, l.lambertian);
        j["light"] = capture.lights[l.light].number;
        j["image"] = capture.lights[l.light].imagePath;
        out["per_light"].push_back(j);
    }
    return out;
}

}  // namespace

FitResult runCaptureFit(const CaptureArgs& args) {
    if (args.output.empty()) throw Error("-o OUTDIR is required");
    if (fs::exists(args.output) && !fs::is_directory(args.output))
        throw Error(fmt::format("-o '{}': exists and is not a directory", args.output));
    if (!fs::is_directory(fs::absolute(args.output).parent_path()))
        throw Error(fmt::format("-o '{}': directory '{}' does not exist", args.output,
                                fs::absolute(args.output).parent_path().string()));
    CaptureFitOptions options;
    options.minCos = args.minCos;
    options.fit.loss = parseLoss(args.loss);
    options.fit.grey = args.grey;
    options.fit.threads = args.threads;
    options.fit.stopRequested = interruptRequested;
    options.fit.verbose = args.verbose;
    if (!(args.minCos >= 0 && args.minCos < 1))
        throw Error(fmt::format("--min-cos {}: must be in [0, 1)", args.minCos));

    // Everything is read and checked before anything is written.
    const CaptureReadOptions read = readOptions(args);
    const Capture capture = readCapture(args.dir, read);
    const auto [lights, holdout] = selectLights(args, int(capture.lights.size()));
    std::vector<int> all = lights;
    all.insert(all.end(), holdout.begin(), holdout.end());
    if (!args.quiet)
        fmt::print(stderr, "reading {} images of '{}' ({} mask pixels)\n", all.size(), args.dir,
                   capture.pixels.size());
    std::vector<CaptureImage> images = readCaptureImages(capture, all, read, args.threads);
    const std::vector<CaptureImage> heldOutImages(images.begin() + std::ptrdiff_t(lights.size()),
                                                  images.end());
    images.resize(lights.size());
    const CaptureFit fit = fitCapture(capture, images, heldOutImages, options);
    std::vector<PhongMaterial> rows = {fit.phong.materials[0].material()};
    if (fit.lambertian) rows.push_back(fit.lambertian->materials[0].material());

    nlohmann::json report = toJson(fit.phong, {"capture"});
    report["capture"] = {{"dir", args.dir},
                         {"mask", capture.maskPath},
                         {"normals", capture.normalsPath},
                         {"mask_pixels", capture.pixels.size()},
                         {"lights", lightNumbers(capture, lights)},
                         {"holdout_lights", lightNumbers(capture, holdout)}};
    report["model"] = {{"kind", "direct light on known normals"},
                       {"view", "orthographic, direction (0, 0, 1) in the camera frame"},
                       {"lights", "directional; each image divided by its light's intensity"},
                       {"lobes", {"diffuse", "specular"}},
                       {"lambertian_lobes", {"diffuse"}},
                       {"bounces", 1},
                       {"max_depth", 2},
                       {"min_cos", args.minCos},
                       {"loss", args.loss}};
    report["left_out"] = {
        "path tracing: no rays are traced; each (pixel, light) pair is the light's direct "
        "reflection on the known normal",
        "indirect light and interreflection: one bounce (depth 1; Mitsuba maxDepth 2)",
        "cast shadows: the surface is assumed unoccluded; pairs with n.l below min_cos are left "
        "out instead",
        "clipped and non-finite pixels"};
    report["start"] = {{"kd", rgb(fit.start.kd)}, {"ks", rgb(fit.start.ks)}, {"n", fit.start.n}};
    report["pairs"] = {
        {"total", fit.model.pairs}, {"used", fit.model.used}, {"left_out", fit.model.leftOut}};
    // The Lambertian-only fit, reported as the Phong fit is (its ks and n are unconstrained).
    report["lambertian"] =
        fit.lambertian ? toJson(*fit.lambertian, {"capture"}) : nlohmann::json(nullptr);
    report["holdout"] = fit.holdout ? holdoutJson(capture, fit) : nlohmann::json(nullptr);

    // compare.png shows a typical held-out light, or without a hold-out the middle fitted one.
    const CaptureModel& shown = fit.heldOut ? *fit.heldOut : fit.model;
    const std::size_t view = fit.holdout ? medianView(*fit.holdout) : shown.lights.size() / 2;
    const std::vector<CaptureImage>& shownImages = fit.heldOut ? heldOutImages : images;
    const CaptureImage& shownImage =
        *std::find_if(shownImages.begin(), shownImages.end(),
                      [&](const CaptureImage& i) { return i.light == shown.lights[view]; });
    const CaptureLight& shownLight = capture.lights[shown.lights[view]];
    report["compare"] = {{"light", shownLight.number},
                         {"image", shownLight.imagePath},
                         {"held_out", fit.heldOut.has_value()},
                         {"rows", fit.lambertian ? nlohmann::json({"phong", "lambertian"})
                                                 : nlohmann::json({"phong"})},
                         {"columns", {"observed", "predicted", "signed error"}}};
    const cv::Mat compare = comparison(capture, shownImage, shown, view, rows);

    fs::create_directories(args.output);
    const fs::path dir(args.output);
    writeAtomically(dir / "fit.json", [&](const fs::path& tmp) {
        std::ofstream out(tmp);
        out << report.dump(2) << "\n";
        out.close();
        if (!out) throw Error(fmt::format("{}: could not be written", tmp.string()));
    });
    writePng(compare, (dir / "compare.png").string());

    const MaterialFit& m = fit.phong.materials[0];
    fmt::print("capture: kd = {}, ks = {}, n = {:.5g} ± {:.2g}{}\n",
               formatColor(m.kd, m.kdStd, args.grey), formatColor(m.ks, m.ksStd, args.grey), m.n,
               m.nStd,
               m.unconstrained.empty() ? ""
                                       : fmt::format("  (unconstrained, held at start: {})",
                                                     fmt::join(m.unconstrained, ", ")));
    fmt::print(
        "fitted {} pairs of {} lights: rmse {:.5g}; left out {} pairs ({} below "
        "--min-cos, {} clipped, {} not finite, {} facing away)\n",
        fit.model.used, lights.size(), fit.phong.rmse, fit.model.pairs - fit.model.used,
        fit.model.leftOut.at("below_min_cos"), fit.model.leftOut.at("clipped"),
        fit.model.leftOut.at("non_finite"), fit.model.leftOut.at("facing_away"));
    double seconds = fit.phong.timeSeconds;
    if (fit.holdout) {
        const MaterialFit& lam = fit.lambertian->materials[0];
        fmt::print("lambertian only: kd = {}\n", formatColor(lam.kd, lam.kdStd, args.grey));
        fmt::print(
            "held out {} lights ({} pairs): rmse {:.5g} (relative {:.3g}), Lambertian "
            "only {:.5g} (relative {:.3g})\n",
            holdout.size(), fit.holdout->phong.pairs, fit.holdout->phong.rmse,
            fit.holdout->phong.relRmse, fit.holdout->lambertian.rmse,
            fit.holdout->lambertian.relRmse);
        seconds += fit.lambertian->timeSeconds;
    }
    fmt::print(
        "{} in {:.2f} s; left out: path tracing and indirect light (direct light on known "
        "normals, one bounce) -> {}\n",
        fit.phong.converged ? "converged" : "not converged", seconds, (dir / "fit.json").string());
    return fit.phong;
}

void addCaptureOptions(CLI::App& fit, CaptureArgs& args) {
    fit.add_option("--capture", args.dir,
                   "photometric-stereo folder (DiLiGenT layout: filenames.txt, "
                   "light_directions.txt, light_intensities.txt, mask.png, normals.exr) instead of "
                   "--view; --mask replaces its mask.png");
    fit.add_option(
        "--lights", args.lights,
        "with --capture: lights to fit, e.g. 1-48 or 1-10,20 (default: all not held out)");
    fit.add_option("--holdout", args.holdout,
                   "with --capture: lights to predict and not fit, e.g. 49-96");
    fit.add_option("--min-cos", args.minCos,
                   "with --capture: leave out pairs with n.l below this (shadows, grazing "
                   "light; default 0.05)");
}

bool runCaptureFitIfGiven(const CLI::App& fit, const CaptureArgs& capture, const FitArgs& shared) {
    if (shared.views.empty() == capture.dir.empty())
        throw Error("fit needs exactly one of --view SCENE.xml:IMAGE and --capture DIR");
    const auto reject = [&](std::initializer_list<const char*> options, const char* why) {
        for (const char* option : options)
            if (fit.count(option) > 0) throw Error(fmt::format("{} {}", option, why));
    };
    if (capture.dir.empty()) {
        reject({"--lights", "--holdout", "--min-cos"}, "applies to --capture, not to --view");
        return false;
    }
    reject({"--fit-exposure"},
           "does not apply to --capture: its images are divided by calibrated light "
           "intensities and lit directly only, so an exposure cannot be told from kd and ks");
    reject({"--material", "--spp", "--rounds", "--kd", "--ks", "--n", "-D", "--seed",
            "--ignore-nonfinite"},
           "applies to scene fits (--view), not to --capture");
    CaptureArgs args = capture;
    args.mask = shared.mask;
    args.output = shared.output;
    args.saturation = shared.saturation;
    args.gamma = shared.gamma;
    args.srgb = shared.srgb;
    args.linear = shared.linear;
    args.grey = shared.grey;
    args.loss = shared.loss;
    args.threads = shared.threads;
    args.quiet = shared.quiet;
    args.verbose = shared.verbose;
    runCaptureFit(args);
    return true;
}

}  // namespace phongfit
