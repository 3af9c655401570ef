#include "capture_run.h"

#include <fmt/format.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "atomic_file.h"
#include "comparison_image.h"
#include "error.h"
#include "fit_report.h"
#include "image.h"
#include "replay.h"

namespace phongfit {
namespace {

namespace fs = std::filesystem;

constexpr int kCompareMargin = 4;  // pixels around the mask's bounding box

// The fitted and held-out lights (indices), from --lights and --holdout.
std::pair<std::vector<int>, std::vector<int>> selectLights(const CaptureFitInputs& args,
                                                           int count) {
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

CaptureRun runCaptureFit(const CaptureFitInputs& inputs, bool quiet) {
    if (!(inputs.fit.minCos >= 0 && inputs.fit.minCos < 1))
        throw Error(fmt::format("--min-cos {}: must be in [0, 1)", inputs.fit.minCos));
    CaptureRun run;
    run.capture = readCapture(inputs.dir, inputs.read);
    std::tie(run.lights, run.holdout) = selectLights(inputs, int(run.capture.lights.size()));
    std::vector<int> all = run.lights;
    all.insert(all.end(), run.holdout.begin(), run.holdout.end());
    if (!quiet)
        fmt::print(stderr, "reading {} images of '{}' ({} mask pixels)\n", all.size(), inputs.dir,
                   run.capture.pixels.size());
    run.images = readCaptureImages(run.capture, all, inputs.read, inputs.fit.fit.threads);
    run.heldOutImages.assign(run.images.begin() + std::ptrdiff_t(run.lights.size()),
                             run.images.end());
    run.images.resize(run.lights.size());
    run.fit = fitCapture(run.capture, run.images, run.heldOutImages, inputs.fit);
    return run;
}

void writeCaptureFit(const CaptureRun& run, const CaptureFitInputs& inputs, const std::string& loss,
                     const std::string& dir) {
    const Capture& capture = run.capture;
    const CaptureFit& fit = run.fit;
    std::vector<PhongMaterial> rows = {fit.phong.materials[0].material()};
    if (fit.lambertian) rows.push_back(fit.lambertian->materials[0].material());
    nlohmann::json report = toJson(fit.phong, {"capture"});
    report["capture"] = {{"dir", inputs.dir},
                         {"mask", capture.maskPath},
                         {"normals", capture.normalsPath},
                         {"mask_pixels", capture.pixels.size()},
                         {"lights", lightNumbers(capture, run.lights)},
                         {"holdout_lights", lightNumbers(capture, run.holdout)}};
    report["model"] = {{"kind", "direct light on known normals"},
                       {"view", "orthographic, direction (0, 0, 1) in the camera frame"},
                       {"lights", "directional; each image divided by its light's intensity"},
                       {"lobes", {"diffuse", "specular"}},
                       {"lambertian_lobes", {"diffuse"}},
                       {"bounces", 1},
                       {"max_depth", 2},
                       {"min_cos", inputs.fit.minCos},
                       {"loss", loss}};
    report["left_out"] = {
        "path tracing: no rays are traced; each (pixel, light) pair is the light's direct "
        "reflection on the known normal",
        "indirect light and interreflection: one bounce (depth 1; Mitsuba maxDepth 2)",
        "cast shadows: the surface is assumed unoccluded; pairs with n.l below min_cos are left "
        "out instead",
        "clipped and non-finite pixels",
        "mask pixels whose normal is zero, not unit or not finite (pixels.bad_normals)"};
    report["start"] = {{"kd", rgb(fit.start.kd)}, {"ks", rgb(fit.start.ks)}, {"n", fit.start.n}};
    report["pairs"] = {
        {"total", fit.model.pairs}, {"used", fit.model.used}, {"left_out", fit.model.leftOut}};
    report["decoding"] = run.images.front().decoding;
    report["pixels"] = {{"used", capture.pixels.size()}, {"bad_normals", capture.badNormals}};
    // The Lambertian-only fit, reported as the Phong fit is (its ks and n are unconstrained).
    report["lambertian"] =
        fit.lambertian ? toJson(*fit.lambertian, {"capture"}) : nlohmann::json(nullptr);
    report["holdout"] = fit.holdout ? holdoutJson(capture, fit) : nlohmann::json(nullptr);

    // compare.png shows a typical held-out light, or without a hold-out the middle fitted one.
    const CaptureModel& shown = fit.heldOut ? *fit.heldOut : fit.model;
    const std::size_t view = fit.holdout ? medianView(*fit.holdout) : shown.lights.size() / 2;
    const std::vector<CaptureImage>& shownImages = fit.heldOut ? run.heldOutImages : run.images;
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

    fs::create_directories(dir);
    const fs::path out(dir);
    writeAtomically(out / "fit.json", [&](const fs::path& tmp) {
        std::ofstream file(tmp);
        file << report.dump(2) << "\n";
        file.close();
        if (!file) throw Error(fmt::format("{}: could not be written", tmp.string()));
    });
    writePng(compare, (out / "compare.png").string());
}

}  // namespace phongfit
