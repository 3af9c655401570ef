#include "scene_fit.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>

#include "atomic_file.h"
#include "comparison_image.h"
#include "edge_agreement.h"
#include "error.h"
#include "film_window.h"
#include "fit_report.h"
#include "instruments.h"
#include "memory_plan.h"
#include "path_growth.h"
#include "path_importance.h"
#include "render_sidecar.h"
#include "scene_parser.h"
#include "scene_writer.h"

namespace phongfit {
namespace {

namespace fs = std::filesystem;

// One sphere (convex: it cannot see itself) whose light can come back to it from nowhere else:
// every other shape is an area emitter with a black surface. Whatever the emitters (point,
// directional, area, environment), there is then no indirect light: direct illumination (depth 2)
// is exact.
bool directLightIsExact(const Scene& scene) {
    int objects = 0;
    for (const ShapeDesc& shape : scene.shapes) {
        const PhongMaterial& surface = scene.bsdfs[shape.bsdf].params;
        if (shape.areaRadiance && (surface.kd == 0).all() && (surface.ks == 0).all()) continue;
        if (shape.type != ShapeDesc::Type::Sphere || shape.areaRadiance) return false;
        ++objects;
    }
    return objects == 1;
}

std::vector<int> fittedBsdfs(const Scene& scene, const std::string& scenePath,
                             const std::vector<std::string>& materials) {
    std::vector<int> fitted;
    for (const std::string& id : materials) {
        const int b = scene.findBsdf(id);
        if (b < 0) {
            std::vector<std::string> ids;
            for (const BsdfDesc& d : scene.bsdfs)
                if (!d.id.empty()) ids.push_back(d.id);
            throw Error(fmt::format("{}: no bsdf with id '{}' (ids in the file: {})", scenePath, id,
                                    fmt::join(ids, ", ")));
        }
        if (scene.bsdfs[b].type != "phong")
            throw Error(
                fmt::format("{}: bsdf '{}' is '{}', not 'phong': only phong materials are "
                            "fitted",
                            scene.bsdfs[b].loc.str(), id, scene.bsdfs[b].type));
        fitted.push_back(b);
    }
    return fitted;
}

// The image as an observation: pixels without data, non-finite, masked and clipped ones left out
// and counted.
void observe(SceneView& v, const Image& image, const SceneFitInputs& in,
             const std::vector<std::uint8_t>* mask) {
    Observation& o = v.observation;
    o.width = image.width;
    o.height = image.height;
    o.rgb = image.rgb;
    o.valid.assign(image.pixelCount(), 1);
    for (std::size_t p = 0; p < image.pixelCount(); ++p) {
        const float* c = &o.rgb[3 * p];
        if (!image.noData.empty() && image.noData[p]) {
            o.valid[p] = 0;
            ++v.noData;
        } else if (!std::isfinite(c[0]) || !std::isfinite(c[1]) || !std::isfinite(c[2])) {
            if (!in.ignoreNonFinite)
                throw Error(
                    fmt::format("{}: pixel ({}, {}) is not finite (use --ignore-nonfinite "
                                "to leave such pixels out)",
                                v.imagePath, p % o.width, p / o.width));
            o.valid[p] = 0;
            o.rgb[3 * p] = o.rgb[3 * p + 1] = o.rgb[3 * p + 2] = 0;
            ++v.nonFinite;
        } else if (mask && !(*mask)[p]) {
            o.valid[p] = 0;
            ++v.masked;
        } else if ((!image.clipped.empty() && image.clipped[p]) ||
                   (in.saturation && std::max({c[0], c[1], c[2]}) >= *in.saturation)) {
            o.valid[p] = 0;
            ++v.clipped;
        }
    }
    if (std::none_of(o.valid.begin(), o.valid.end(), [](std::uint8_t x) { return x != 0; }))
        throw Error(
            fmt::format("{}: every pixel is masked, clipped, not finite or outside the "
                        "EXR's data window: nothing to fit",
                        v.imagePath));
}

SceneView loadView(const SceneFitInputs::View& spec, const SceneFitInputs& in,
                   const std::vector<std::uint8_t>* mask,
                   const std::optional<PixelFilter>& edgeFilter) {
    SceneView v;
    v.scenePath = spec.scenePath;
    v.imagePath = spec.imagePath;
    Scene scene = loadScene(v.scenePath, in.defines);
    if (edgeFilter && !scene.sensor.filterNamed) {
        setPixelFilter(scene.sensor, *edgeFilter);
        v.filterFromEdges = true;
    }
    v.fittedBsdfs = fittedBsdfs(scene, v.scenePath, in.materials);
    v.deltaLights =
        std::none_of(scene.shapes.begin(), scene.shapes.end(),
                     [](const ShapeDesc& s) { return bool(s.areaRadiance); }) &&
        std::all_of(scene.emitters.begin(), scene.emitters.end(), [](const EmitterDesc& e) {
            return e.type == EmitterDesc::Type::Point || e.type == EmitterDesc::Type::Directional;
        });
    const bool directExact = directLightIsExact(scene);
    if (directExact) {
        v.maxDepth = 2;
        v.deltaLightsOnly = v.deltaLights;
        v.depthNote =
            "indirect bounces (one convex object, and emitters that reflect nothing: direct "
            "light is exact, depth 2)";
    } else if (scene.integrator.type == "direct") {
        v.depthNote = "nothing (the scene's integrator is \"direct\": depth 2)";
    } else {
        v.depthNote = "nothing (path tracing at the scene's depth)";
    }
    // Framed as rendered: a crop window's EXR fits on the pixels it holds.
    ReadOptions read = in.decoding;
    read.exrDisplayWindow = true;
    const Image image = readImage(v.imagePath, read);
    const SensorDesc& film = scene.sensor;
    if (image.width != film.width || image.height != film.height)
        throw Error(fmt::format("{}: image is {}x{} but the film of {} is {}x{}", v.imagePath,
                                image.width, image.height, v.scenePath, film.width, film.height));
    observe(v, image, in, mask);
    v.renderer = std::make_unique<Renderer>(std::move(scene));
    v.renderedAs = readRenderedAs(v.imagePath, v.renderer->scene(),
                                  v.renderer->effectiveMaxDepth(-2), directExact);
    const std::vector<int> seen = v.renderer->bsdfSeen(0);
    v.direct = seesAny(seen, v.fittedBsdfs);
    v.edges = edgePixels(seen, image.width, image.height, v.fittedBsdfs);
    v.slotSeen.assign(v.fittedBsdfs.size(), false);
    for (std::size_t p = 0; p < seen.size(); ++p)
        for (std::size_t s = 0; s < v.fittedBsdfs.size(); ++s)
            if (seen[p] == v.fittedBsdfs[s] && v.observation.valid[p]) v.slotSeen[s] = true;
    return v;
}

// Where every fitted material is seen directly somewhere, the pixels that see none of them through
// their footprint are left out: what they show of the materials comes through other surfaces, a
// few noisy bounces that pulled the estimate (docs/design/fitter.md, "Pixels that see the
// materials only indirectly").
void leaveOutIndirectPixels(std::vector<SceneView>& views, std::size_t materials) {
    for (std::size_t s = 0; s < materials; ++s)
        if (std::none_of(views.begin(), views.end(),
                         [&](const SceneView& v) { return v.slotSeen[s]; }))
            return;
    for (SceneView& v : views) {
        const SensorDesc& film = v.renderer->scene().sensor;
        // A pixel's samples reach this far from its centre.
        const int radius = std::max(1, filterReach(film));
        // The direct pixels the fit keeps, widened by that reach.
        cv::Mat near(v.observation.height, v.observation.width, CV_8U);
        for (std::size_t p = 0; p < v.direct.size(); ++p)
            near.data[p] = v.direct[p] && v.observation.valid[p];
        cv::dilate(near, near, cv::Mat::ones(2 * radius + 1, 2 * radius + 1, CV_8U));
        for (std::size_t p = 0; p < v.direct.size(); ++p)
            if (v.observation.valid[p] && !near.data[p]) {
                v.observation.valid[p] = 0;
                ++v.offMaterials;
            }
    }
}

// observed | re-rendered with the fitted parameters | signed error (comparison_image.h). Rendered
// anew with more paths than a round records, so the middle column shows the model rather than the
// recording's noise.
cv::Mat comparison(const SceneView& v, const std::vector<PhongMaterial>& fitted, double exposure,
                   const SceneRecording& recording, int compareSpp) {
    Scene scene = v.renderer->scene();
    for (std::size_t s = 0; s < fitted.size(); ++s)
        scene.bsdfs[v.fittedBsdfs[s]].params = fitted[s];
    RenderOptions options;
    options.spp = compareSpp;
    options.seed = recording.seed + 7919;  // independent of every recording
    options.threads = recording.threads;
    options.maxDepth = v.maxDepth;
    options.quiet = true;
    // Only the compared pixels: the others are grey in the predicted and error columns.
    options.rendered = v.observation.valid;
    const RenderResult rendered = Renderer(std::move(scene)).render(options);
    ComparisonPanels panels;
    panels.width = v.observation.width;
    panels.height = v.observation.height;
    const std::size_t pixels = std::size_t(panels.width) * std::size_t(panels.height);
    panels.predicted.emplace_back(pixels);
    for (std::size_t p = 0; p < pixels; ++p) {
        panels.observed.push_back(Color3(v.observation.rgb[3 * p], v.observation.rgb[3 * p + 1],
                                         v.observation.rgb[3 * p + 2]));
        panels.state.push_back(v.observation.valid[p] ? ComparePixel::Compared
                                                      : ComparePixel::LeftOut);
        panels.predicted[0][p] = exposure * Color3(rendered.rgb[3 * p], rendered.rgb[3 * p + 1],
                                                   rendered.rgb[3 * p + 2]);
    }
    return comparisonImage(panels);
}

// The samples per pixel view `v`'s image was rendered with: --image-spp's, else its own.
int imageSpp(const SceneView& v, const SceneRecording& recording) {
    return recording.imageSpp >= 0 ? recording.imageSpp : v.renderedAs.spp;
}

// FitOptions::renderedNoise for view `v` (its fit covering `window`): the listed pixels rendered
// kNoiseRenders times at `spp` paths a pixel in the scene's sampler, each with its own seed, and
// their values' mean and covariance over the renders. Each is traced alone, in a window of its own,
// by the view's renderer at `theta`: a pixel's value is its own samples' (a Gaussian filter is
// importance-sampled, filmPosition), drawn from the seed and the pixel alone, and the fit's
// memory bound leaves no room for a film or a scene of their own.
constexpr int kNoiseRenders = 16;

std::vector<RenderedPixel> renderedNoise(const SceneView& v, const FilmWindow& window, int spp,
                                         const SceneRecording& recording,
                                         const std::vector<std::uint32_t>& pixels,
                                         const std::vector<PhongMaterial>& theta) {
    RenderOptions options = renderOptionsAt(v, theta, recording.threads);
    options.spp = spp;
    options.pixelSampler = v.renderedAs.pixelSampler;
    std::vector<RenderedPixel> rendered;
    const auto width = std::uint32_t(window.width);
    for (std::uint32_t p : pixels) {
        options.window = {window.x0 + int(p % width), window.y0 + int(p / width), 1, 1};
        Eigen::Vector3d sum = Eigen::Vector3d::Zero();
        Eigen::Matrix3d squares = Eigen::Matrix3d::Zero();
        for (int k = 0; k < kNoiseRenders; ++k) {
            options.seed = recording.seed * 7919 + 104729 + std::uint64_t(k);
            const RenderResult r = v.renderer->render(options);
            const Eigen::Vector3d c(r.rgb[0], r.rgb[1], r.rgb[2]);
            sum += c;
            squares += c * c.transpose();
        }
        rendered.push_back({sum / kNoiseRenders,
                            (squares - sum * sum.transpose() / kNoiseRenders) / (kNoiseRenders - 1),
                            kNoiseRenders});
    }
    return rendered;
}

}  // namespace

int filterReach(const SensorDesc& film) {
    switch (film.filter) {
        case SensorDesc::Filter::Box:
            return 0;
        case SensorDesc::Filter::Gaussian:
            return int(std::ceil(3 * film.filterWidth + 0.5));
        case SensorDesc::Filter::Tent:
            break;
    }
    return int(std::ceil(film.filterWidth + 0.5));
}

SceneFitProblem loadSceneFit(const SceneFitInputs& inputs) {
    if (inputs.views.empty()) throw Error("the fit needs at least one --view SCENE.xml:IMAGE");
    if (inputs.materials.empty()) throw Error("--view needs --material ID (the phong bsdf to fit)");
    SceneFitProblem problem;
    problem.materials = inputs.materials;
    problem.defines = inputs.defines;
    std::optional<std::vector<std::uint8_t>> mask;
    for (const SceneFitInputs::View& spec : inputs.views) {
        if (!inputs.maskPath.empty() && !mask) {
            // The mask is sized by the first view's film.
            const Scene first = loadScene(spec.scenePath, inputs.defines);
            mask = readMask(inputs.maskPath, first.sensor.width, first.sensor.height);
        }
        const std::size_t k = problem.views.size();
        problem.views.push_back(
            loadView(spec, inputs, mask ? &*mask : nullptr,
                     k < inputs.edgeFilters.size() ? inputs.edgeFilters[k] : std::nullopt));
    }
    if (!inputs.keepIndirect) leaveOutIndirectPixels(problem.views, inputs.materials.size());
    for (int b : problem.views[0].fittedBsdfs) {
        PhongMaterial m = problem.views[0].renderer->scene().bsdfs[b].params;
        if (inputs.kd) m.kd = *inputs.kd;
        if (inputs.ks) m.ks = *inputs.ks;
        if (inputs.n) m.n = *inputs.n;
        validatePhong(m, "start value (--kd, --ks, --n)");
        problem.start.push_back(m);
    }
    return problem;
}

RenderOptions renderOptionsAt(const SceneView& v, const std::vector<PhongMaterial>& theta,
                              int threads) {
    RenderOptions options;
    options.sampler = v.renderedAs.sampler;
    options.mis = v.renderedAs.mis;
    options.threads = threads;
    options.maxDepth = v.maxDepth;
    options.quiet = true;
    const std::size_t fitted = std::min(theta.size(), v.fittedBsdfs.size());
    options.bsdfs.assign(v.fittedBsdfs.begin(), v.fittedBsdfs.begin() + std::ptrdiff_t(fitted));
    options.bsdfParams.assign(theta.begin(), theta.begin() + std::ptrdiff_t(fitted));
    return options;
}

FitResult fitScene(const SceneFitProblem& problem, const SceneRecording& recording,
                   const FitOptions& options) {
    // Each view's fit and recordings cover the bounding box of the pixels it uses (film_window.h):
    // what the fit holds per pixel grows with those, not with the pixels it leaves out.
    std::vector<Observation> observations;
    std::vector<FilmWindow> windows;
    std::vector<std::vector<std::uint8_t>> direct;
    for (const SceneView& v : problem.views) {
        const Observation& full = v.observation;
        // Widened by the instruments' reach: a pixel near the edge averages over the same
        // neighbourhood (used or not) as on the whole film, and gets the same instrument.
        const FilmWindow w = full.valid.empty()
                                 ? FilmWindow{0, 0, full.width, full.height}
                                 : widened(boundingWindow(full.valid, full.width, full.height),
                                           kInstrumentRadius, full.width, full.height);
        const auto crop = [&](const auto& film, int channels = 1) {
            return film.empty() ? film : cropped(film, full.width, w, channels);
        };
        observations.push_back(
            {w.width, w.height, crop(full.rgb, 3), crop(full.valid), crop(full.weight)});
        windows.push_back(w);
        direct.push_back(crop(v.direct));
    }
    const std::size_t state = stateBytes(observations);
    const PathRecorder record = [&](int view, const std::vector<PhongMaterial>& theta0, int round,
                                    const std::vector<float>& importance,
                                    double pathFactor) -> PathSet {
        const SceneView& v = problem.views[view];
        RecordOptions o;
        // Below 1 (the sharper probe's round) every count shrinks, to at least a path a pixel.
        const auto scaled = [&](int spp) {
            return pathFactor < 1 && spp > 0 ? std::max(1, int(std::ceil(spp * pathFactor))) : spp;
        };
        o.spp = scaled(recording.spp);
        o.directSpp = scaled(recording.directSpp);
        // Per pixel that sees a fitted material: --adaptive-spp, and what --precision asks for.
        const double extra =
            std::min(pathFactor, 1.0) * recording.adaptiveSpp +
            std::max(pathFactor - 1, 0.0) * (o.directSpp > 0 ? o.directSpp : o.spp);
        if (!importance.empty() && extra > 0) {
            const auto seen =
                std::count_if(importance.begin(), importance.end(), [](float w) { return w > 0; });
            o.extraPaths = allocatePaths(importance, extra * double(seen), kMostExtraPaths);
        }
        o.window = windows[std::size_t(view)];
        o.recorded = observations[std::size_t(view)].valid;  // left out: no paths needed
        o.direct = direct[std::size_t(view)];
        o.seed = recording.seed * 1000003 + std::uint64_t(round) * 1009 + std::uint64_t(view);
        o.threads = recording.threads;
        o.maxDepth = v.maxDepth;
        o.lightRings = recording.lightRings;
        o.fittedBsdfs = v.fittedBsdfs;
        o.theta0 = theta0;
        // What the fit may hold, less the state its solve will need (memory_plan.h).
        if (const std::optional<std::size_t> available = fitMemoryAvailable(options.memoryLimit))
            o.memoryBudget = std::max(double(*available) - double(state), 1.0);
        return v.renderer->record(o).paths;
    };
    FitOptions o = options;
    // Images without noise (closed forms, --image-spp 0) are not rendered anew, nor is their noise
    // taken where a lobe is sharper.
    if (std::any_of(problem.views.begin(), problem.views.end(),
                    [&](const SceneView& v) { return imageSpp(v, recording) > 0; }))
        o.renderedNoise = [&](int view, const std::vector<std::uint32_t>& pixels,
                              const std::vector<PhongMaterial>& theta) {
            const SceneView& v = problem.views[std::size_t(view)];
            const int spp = imageSpp(v, recording);
            if (spp <= 0) return std::vector<RenderedPixel>{};
            return renderedNoise(v, windows[std::size_t(view)], spp, recording, pixels, theta);
        };
    o.recordingFollowsEstimate = !std::all_of(problem.views.begin(), problem.views.end(),
                                              [](const SceneView& v) { return v.deltaLightsOnly; });
    o.extendedLights = !std::all_of(problem.views.begin(), problem.views.end(),
                                    [](const SceneView& v) { return v.deltaLights; });
    FitResult result = fitMaterials(observations, record, problem.start, o);
    // A converged fit of an image its scene misstates is a confident wrong answer. Part of the
    // fit's time.
    const auto checkBegin = std::chrono::steady_clock::now();
    const std::vector<PhongMaterial> fitted = result.fittedMaterials();
    const double exposure = result.exposureValue();
    for (const SceneView& v : problem.views) {
        result.edgeChecks.push_back(edgeAgreement(v, fitted, exposure, imageSpp(v, recording),
                                                  recording.seed, recording.threads));
        if (result.edgeChecks.back().disagrees && result.converged) {
            result.converged = false;
            result.stopReason = "images disagree";
        }
    }
    result.timeSeconds +=
        std::chrono::duration<double>(std::chrono::steady_clock::now() - checkBegin).count();
    return result;
}

namespace {

// What fit.json says of a view's pixel filter: where its image's edges chose it, or where the
// scene, a sidecar or the default did; and the other filter the fit ran with, if any.
nlohmann::json filterReport(const SceneFitProblem& problem, std::size_t k) {
    const SceneView& v = problem.views[k];
    const SensorDesc& film = v.renderer->scene().sensor;
    nlohmann::json report = v.filterFromEdges ? pixelFilterJson(pixelFilterOf(film))
                                              : pixelFilterReport(film, v.renderedAs);
    if (v.filterFromEdges) report["from"] = "edges";
    if (const auto& other = problem.otherFilterFit;
        other && k < other->filters.size() && other->filters[k]) {
        report["residual_rms"] = other->keptResidual;
        report["also_fitted"] = pixelFilterJson(*other->filters[k]);
        report["also_fitted"]["residual_rms"] = other->residual;
    }
    return report;
}

// What fit.json says of a view's image noise as rendered (FitOptions::renderedNoise).
nlohmann::json renderedAsJson(const SceneView& v, const SceneRecording& recording) {
    const RenderedAs& as = v.renderedAs;
    const int spp = imageSpp(v, recording);
    if (spp == 0) return "without noise";
    return {{"spp", spp},
            {"pixel_sampler", pixelSamplerName(as.pixelSampler)},
            {"sampler", as.sampler},
            {"mis", as.mis},
            {"from", recording.imageSpp >= 0 ? "--image-spp" : as.source}};
}

}  // namespace

void writeSceneFit(const SceneFitProblem& problem, const FitResult& result,
                   const SceneRecording& recording, int compareSpp, const std::string& dir) {
    const std::vector<PhongMaterial> fitted = result.fittedMaterials();
    nlohmann::json report = toJson(result, problem.materials);
    report["record_spp"] = recording.spp;
    report["seed"] = recording.seed;
    const auto ringed = [&](const SceneView& v) {
        return recording.lightRings && v.renderer->recordsByRings(v.maxDepth);
    };
    const auto emitting = [](const SceneView& v) {
        const std::vector<ShapeDesc>& shapes = v.renderer->scene().shapes;
        return std::any_of(shapes.begin(), shapes.end(),
                           [](const ShapeDesc& s) { return bool(s.areaRadiance); });
    };
    const auto areaLights = [&](const SceneView& v) {
        return ringed(v) ? "rings" : emitting(v) ? "sampled" : "none";
    };
    const auto any = [&](auto&& f) {
        return std::any_of(problem.views.begin(), problem.views.end(), f);
    };
    report["area_lights"] = any(ringed) ? "rings" : any(emitting) ? "sampled" : "none";
    for (std::size_t k = 0; k < problem.views.size(); ++k) {
        const SceneView& v = problem.views[k];
        report["views"].push_back({{"scene", v.scenePath},
                                   {"image", v.imagePath},
                                   {"area_lights", areaLights(v)},
                                   {"max_depth", v.renderer->effectiveMaxDepth(v.maxDepth)},
                                   {"left_out", v.depthNote},
                                   {"pixels_clipped", v.clipped},
                                   {"pixels_masked", v.masked},
                                   {"pixels_off_the_materials", v.offMaterials},
                                   {"pixels_non_finite", v.nonFinite},
                                   {"pixels_without_data", v.noData},
                                   {"pixel_filter", filterReport(problem, k)},
                                   {"image_rendered_as", renderedAsJson(v, recording)}});
    }
    for (std::size_t k = 0; k < result.edgeChecks.size() && k < problem.views.size(); ++k) {
        const EdgeCheck& e = result.edgeChecks[k];
        report["views"][k]["edges"] = {
            {"pixels_compared", e.pixels},
            {"median_deviation", e.medianDeviation},
            {"misfit", e.misfit},
            {"better_pixel_filter", e.betterFilter ? pixelFilterLabel(*e.betterFilter) : ""},
            {"better_misfit", e.betterMisfit},
            {"alike_pixel_filter", e.alikeFilter ? pixelFilterLabel(*e.alikeFilter) : ""},
            {"alike_misfit", e.alikeMisfit},
            {"agree",
             e.pixels < kLeastEdgePixels ? nlohmann::json() : nlohmann::json(!e.disagrees)}};
    }
    fs::create_directories(dir);
    const fs::path out(dir);
    writeAtomically(out / "fit.json",
                    [&](const fs::path& tmp) { std::ofstream(tmp) << report.dump(2) << "\n"; });
    std::map<std::string, PhongMaterial> byId;
    for (std::size_t s = 0; s < fitted.size(); ++s) byId[problem.materials[s]] = fitted[s];
    const double exposure = result.exposureValue();
    for (std::size_t k = 0; k < problem.views.size(); ++k) {
        const std::string suffix = k == 0 ? "" : fmt::format("_view{}", k + 1);
        writeSceneWithMaterials(problem.views[k].scenePath, problem.defines, byId,
                                (out / ("fitted" + suffix + ".xml")).string());
        writePng(comparison(problem.views[k], fitted, exposure, recording, compareSpp),
                 (out / ("compare" + suffix + ".png")).string());
    }
}

}  // namespace phongfit
