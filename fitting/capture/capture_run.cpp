#include "capture_run.h"

#include <fmt/format.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <functional>
#include <nlohmann/json.hpp>

#include "atomic_file.h"
#include "color_json.h"
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

// The prediction of entry k of the shown view, one function per row.
using RowPrediction = std::function<Color3(std::size_t k)>;

// One row per model (Phong, then the Lambertian baseline if fitted), cropped to the mask;
// left-out pairs are grey, pixels outside the mask black (comparison_image.h).
cv::Mat comparison(const Capture& capture, const CaptureImage& image,
                   const std::vector<std::uint32_t>& entries,
                   const std::vector<RowPrediction>& rows) {
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
    for (std::size_t k = 0; k < entries.size(); ++k) {
        const std::size_t p = at[entries[k]];
        panels.state[p] = ComparePixel::Compared;
        for (std::size_t row = 0; row < rows.size(); ++row) panels.predicted[row][p] = rows[row](k);
    }
    return comparisonImage(panels);
}

nlohmann::json holdoutJson(const Capture& capture, const HoldoutPrediction& holdout,
                           const CaptureModel& heldOut) {
    nlohmann::json out = errorJson(holdout.phong, holdout.lambertian);
    out["pairs_left_out"] = heldOut.leftOut;
    out["per_light"] = nlohmann::json::array();
    for (const LightPrediction& l : holdout.perLight) {
        nlohmann::json j = errorJson(l.phong, l.lambertian);
        j["light"] = capture.lights[l.light].number;
        j["image"] = capture.lights[l.light].imagePath;
        out["per_light"].push_back(j);
    }
    return out;
}

nlohmann::json modelJson(const std::string& albedo, const std::vector<std::string>& lobes,
                         const std::vector<std::string>& lambertianLobes,
                         const CaptureFitInputs& inputs, const std::string& loss) {
    return {{"kind", "direct light on known normals"},
            {"albedo", albedo},
            {"view", "orthographic, direction (0, 0, 1) in the camera frame"},
            {"lights", "directional; each image divided by its light's intensity"},
            {"lobes", lobes},
            {"lambertian_lobes", lambertianLobes},
            {"bounces", 1},
            {"max_depth", 2},
            {"min_cos", inputs.fit.minCos},
            {"loss", loss}};
}

// What both kinds of capture fit report alike.
void describeCapture(const CaptureRun& run, const CaptureFitInputs& inputs,
                     const CaptureModel& model, nlohmann::json& report) {
    const Capture& capture = run.capture;
    report["capture"] = {{"dir", inputs.dir},
                         {"mask", capture.maskPath},
                         {"normals", capture.normalsPath},
                         {"mask_pixels", capture.pixels.size()},
                         {"lights", lightNumbers(capture, run.lights)},
                         {"holdout_lights", lightNumbers(capture, run.holdout)}};
    report["left_out"] = {
        "path tracing: no rays are traced; each (pixel, light) pair is the light's direct "
        "reflection on the known normal",
        "indirect light and interreflection: one bounce (depth 1; Mitsuba maxDepth 2)",
        "cast shadows: the surface is assumed unoccluded; pairs with n.l below min_cos are left "
        "out instead",
        "clipped and non-finite pixels",
        "mask pixels whose normal is zero, not unit or not finite (pixels.bad_normals)"};
    report["pairs"] = {{"total", model.pairs}, {"used", model.used}, {"left_out", model.leftOut}};
    report["decoding"] = run.images.front().decoding;
    report["intensities"] = run.intensities;
    if (const auto& check = run.decodingCheck)
        report["decoding_check"] = {{"used", curveName(check->used)},
                                    {"other_fits_more_pixels", check->otherBetterFraction},
                                    {"other", curveName(check->other)},
                                    {"other_fits_better", check->otherFitsBetter}};
}

// The compare.png of a typical held-out light (median Phong error), or of the middle fitted light
// without a hold-out; records which in report["compare"].
cv::Mat compareTypicalLight(
    const CaptureRun& run, const CaptureModel& model, const std::optional<CaptureModel>& heldOut,
    const std::optional<HoldoutPrediction>& holdout,
    const std::function<std::vector<RowPrediction>(const CaptureModel&, std::size_t view)>& rows,
    const std::vector<std::string>& rowNames, nlohmann::json& report) {
    const CaptureModel& shown = heldOut ? *heldOut : model;
    const std::size_t view = holdout ? medianView(*holdout) : shown.lights.size() / 2;
    const std::vector<CaptureImage>& images = heldOut ? run.heldOutImages : run.images;
    const CaptureImage& image = *std::find_if(
        images.begin(), images.end(), [&](const auto& i) { return i.light == shown.lights[view]; });
    const CaptureLight& light = run.capture.lights[shown.lights[view]];
    report["compare"] = {{"light", light.number},
                         {"image", light.imagePath},
                         {"held_out", heldOut.has_value()},
                         {"rows", rowNames},
                         {"columns", {"observed", "predicted", "signed error"}}};
    return comparison(run.capture, image, shown.entries[view], rows(shown, view));
}

void writeReport(const fs::path& out, const nlohmann::json& report, const cv::Mat& compare) {
    writeAtomically(out / "fit.json", [&](const fs::path& tmp) {
        std::ofstream file(tmp);
        file << report.dump(2) << "\n";
        file.close();
        if (!file) throw Error(fmt::format("{}: could not be written", tmp.string()));
    });
    writePng(compare, (out / "compare.png").string());
}

void writeUniformFit(const CaptureRun& run, const CaptureFitInputs& inputs, const std::string& loss,
                     const fs::path& out) {
    const CaptureFit& fit = *run.fit;
    std::vector<PhongMaterial> materials = {fit.phong.materials[0].material()};
    if (fit.lambertian) materials.push_back(fit.lambertian->materials[0].material());
    nlohmann::json report = toJson(fit.phong, {"capture"});
    describeCapture(run, inputs, fit.model, report);
    report["model"] = modelJson("uniform", {"diffuse", "specular"}, {"diffuse"}, inputs, loss);
    report["start"] = {
        {"kd", colorJson(fit.start.kd)}, {"ks", colorJson(fit.start.ks)}, {"n", fit.start.n}};
    report["energy_bound_reached"] = fit.energyBoundReached;
    report["units"] =
        fit.scale == 1
            ? "kd and ks absolute (calibrated light intensities), bounded by kd + ks <= 1"
            : "kd and ks in the units of the images divided by the light intensities, known up to "
              "the intensities' common factor, with no energy bound; n is absolute";
    report["pixels"] = {{"used", run.capture.pixels.size()},
                        {"bad_normals", run.capture.badNormals}};
    // The Lambertian-only fit, reported as the Phong fit is (its ks and n are unconstrained).
    report["lambertian"] =
        fit.lambertian ? toJson(*fit.lambertian, {"capture"}) : nlohmann::json(nullptr);
    report["holdout"] = fit.holdout ? holdoutJson(run.capture, *fit.holdout, *fit.heldOut)
                                    : nlohmann::json(nullptr);
    const auto rows = [&](const CaptureModel& shown, std::size_t view) {
        std::vector<RowPrediction> out;
        for (const PhongMaterial& m : materials)
            out.push_back([&shown, view, m](std::size_t k) -> Color3 {
                return replayPixel(shown.paths[view], k, &m);
            });
        return out;
    };
    const std::vector<std::string> names = fit.lambertian
                                               ? std::vector<std::string>{"phong", "lambertian"}
                                               : std::vector<std::string>{"phong"};
    const cv::Mat compare =
        compareTypicalLight(run, fit.model, fit.heldOut, fit.holdout, rows, names, report);
    writeReport(out, report, compare);
}

// The albedo map as a linear EXR and a PNG preview (exposed so the brightest 1% is white).
void writeAlbedoMap(const Capture& capture, const std::vector<Color3>& kd, const fs::path& out) {
    Image image(capture.width, capture.height);
    std::vector<double> luminance;
    for (std::size_t i = 0; i < capture.pixels.size(); ++i) {
        const std::uint32_t p = capture.pixels[i];
        image.set(int(p % std::uint32_t(capture.width)), int(p / std::uint32_t(capture.width)),
                  kd[i].cast<float>());
        luminance.push_back(kd[i].maxCoeff());
    }
    writeExr(image, (out / "kd.exr").string());
    const auto white = luminance.begin() + std::ptrdiff_t(0.99 * double(luminance.size() - 1));
    std::nth_element(luminance.begin(), white, luminance.end());
    writePng(image, (out / "kd.png").string(), *white > 0 ? 1 / *white : 1.0);
}

// materials.png: each mask pixel's material as a grey level, darkest for material 1; black outside.
void writeMaterialMap(const Capture& capture, const AlbedoMapFit& fit, const fs::path& out) {
    cv::Mat map(capture.height, capture.width, CV_8UC3, cv::Scalar(0, 0, 0));
    const double step = 200.0 / double(fit.lobes.size() - 1);
    for (std::size_t i = 0; i < capture.pixels.size(); ++i) {
        const int level = 55 + int(std::lround(step * fit.material[i]));
        map.at<cv::Vec3b>(int(capture.pixels[i] / std::uint32_t(capture.width)),
                          int(capture.pixels[i] % std::uint32_t(capture.width))) =
            cv::Vec3b(uchar(level), uchar(level), uchar(level));
    }
    writePng(map, (out / "materials.png").string());
}

void writeAlbedoMapFit(const CaptureRun& run, const CaptureFitInputs& inputs, const fs::path& out) {
    const AlbedoMapCaptureFit& fit = *run.albedoMap;
    const AlbedoMapFit& m = fit.fit;
    nlohmann::json report;
    report["albedo"] = "per-pixel";
    report["lobes"] = nlohmann::json::array();
    for (std::size_t i = 0; i < m.lobes.size(); ++i) {
        const LobeFit& lobe = m.lobes[i];
        report["lobes"].push_back(
            {{"material", i + 1},
             {"pixels", lobe.pixels},
             {"ks", colorJson(lobe.ks)},
             {"ks_std", colorJson(lobe.ksStd)},
             {"n", lobe.n},
             {"n_std", std::isfinite(lobe.nStd) ? nlohmann::json(lobe.nStd) : nlohmann::json()},
             {"unconstrained", lobe.unconstrained},
             {"n_at_search_bound", lobe.nAtBound},
             {"evaluations", lobe.evaluations}});
    }
    if (m.lobes.size() == 1)  // one lobe for the object: its fields at the top too
        for (const char* key : {"ks", "ks_std", "n", "n_std", "unconstrained", "n_at_search_bound"})
            report[key] = report["lobes"][0][key];
    report["n_search_range"] = {m.minN, m.maxN};
    if (m.lobes.size() > 1) report["material_map"] = "materials.png";
    report["kd_map"] = {{"exr", "kd.exr"},
                        {"png", "kd.png"},
                        {"fitted_pixels", m.pixelsFitted},
                        {"kd_plus_ks_above_1", m.kdAboveOne},
                        {"energy_bound_exceeded", m.energyBoundExceeded}};
    report["units"] =
        run.intensities == "calibrated"
            ? "kd and ks absolute (calibrated light intensities); no energy bound is imposed per "
              "pixel (kd_map.kd_plus_ks_above_1 counts the pixels beyond it)"
            : "kd and ks in the units of the images divided by the light intensities, known up to "
              "the intensities' common factor; n is absolute; no energy bound is imposed";
    report["rmse"] = m.rmse;
    report["lambertian_rmse"] = m.lambertianRmse;
    report["time_seconds"] = m.seconds;
    describeCapture(run, inputs, fit.model, report);
    report["model"] =
        modelJson("per-pixel",
                  {"diffuse (per pixel)",
                   m.lobes.size() == 1 ? "specular (shared)" : "specular (one per material)"},
                  {"diffuse (per pixel)"}, inputs, "l2");
    report["model"]["materials"] = m.lobes.size();
    report["model"]["min_pairs_per_pixel"] = AlbedoMapOptions{}.minPairs;
    report["pixels"] = {{"used", m.pixelsFitted},
                        {"bad_normals", run.capture.badNormals},
                        {"too_few_pairs", m.pixelsTooFewPairs}};
    report["holdout"] = fit.holdout ? holdoutJson(run.capture, *fit.holdout, *fit.heldOut)
                                    : nlohmann::json(nullptr);
    const auto rows = [&](const CaptureModel& shown, std::size_t view) {
        const auto predict = [&shown, view, &m](bool lobe) -> RowPrediction {
            return [&shown, view, &m, lobe](std::size_t k) -> Color3 {
                const std::uint32_t p = shown.entries[view][k];
                const double cosine = shown.paths[view].terms[k].constant[0];
                if (!lobe) return m.lambertianKd[p] * cosine * kInvPi;
                return predictAlbedoMap(m, p, cosine, shown.paths[view].vertices[k].logCos);
            };
        };
        return std::vector<RowPrediction>{predict(true), predict(false)};
    };
    const cv::Mat compare = compareTypicalLight(run, fit.model, fit.heldOut, fit.holdout, rows,
                                                {"phong", "lambertian per pixel"}, report);
    writeAlbedoMap(run.capture, m.kd, out);
    if (m.lobes.size() > 1) writeMaterialMap(run.capture, m, out);
    writeReport(out, report, compare);
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
    const bool allEqual = std::all_of(
        run.capture.lights.begin(), run.capture.lights.end(), [&](const CaptureLight& l) {
            return (l.intensity == run.capture.lights.front().intensity).all();
        });
    CaptureFitOptions fitOptions = inputs.fit;
    fitOptions.relativeIntensities =
        inputs.intensities == "relative" || (inputs.intensities == "auto" && allEqual);
    run.intensities =
        !fitOptions.relativeIntensities ? "calibrated"
        : inputs.intensities == "relative"
            ? "relative (--intensities relative)"
            : "relative (every light has the same intensity; --intensities calibrated if they "
              "are calibrated)";
    if (inputs.perPixelAlbedo) {
        AlbedoMapOptions options;
        options.grey = inputs.fit.fit.grey;
        options.threads = inputs.fit.fit.threads;
        options.materials = inputs.materials;
        run.albedoMap = fitCaptureAlbedoMap(run.capture, run.images, run.heldOutImages,
                                            inputs.fit.minCos, options);
    } else {
        run.fit = fitCapture(run.capture, run.images, run.heldOutImages, fitOptions);
    }
    run.decodingCheck =
        checkDecoding(run.capture, run.albedoMap ? run.albedoMap->model : run.fit->model,
                      run.images, inputs.fit.fit.threads);
    return run;
}

void writeCaptureFit(const CaptureRun& run, const CaptureFitInputs& inputs, const std::string& loss,
                     const std::string& dir) {
    fs::create_directories(dir);
    if (run.albedoMap)
        writeAlbedoMapFit(run, inputs, dir);
    else
        writeUniformFit(run, inputs, loss, dir);
}

}  // namespace phongfit
