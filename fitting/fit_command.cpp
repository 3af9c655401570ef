// phongfit fit --view SCENE.xml:IMAGE [--view ...] --material ID ... -o OUTDIR
#include "fit_command.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <optional>

#include "atomic_file.h"
#include "capture_command.h"
#include "commands.h"
#include "comparison_image.h"
#include "defines.h"
#include "error.h"
#include "fit_report.h"
#include "fitter.h"
#include "image.h"
#include "interrupt.h"
#include "renderer.h"
#include "scene_parser.h"
#include "scene_writer.h"

namespace phongfit {
namespace {

namespace fs = std::filesystem;

struct View {
    std::string scenePath, imagePath;
    std::unique_ptr<Renderer> renderer;
    std::vector<int> fittedBsdfs;  // per slot
    int maxDepth = -2;
    std::string depthNote;  // what the pipeline left out, in words
    Image image;
    Observation observation;
    std::size_t clipped = 0, masked = 0, nonFinite = 0;
};

Color3 parseColor(const std::string& text, const std::string& flag) {
    std::vector<double> values;
    std::size_t pos = 0;
    while (pos <= text.size()) {
        const std::size_t comma = std::min(text.find(',', pos), text.size());
        const std::string item = text.substr(pos, comma - pos);
        char* end = nullptr;
        const double v = std::strtod(item.c_str(), &end);
        if (item.empty() || end != item.c_str() + item.size())
            throw Error(fmt::format("{} '{}': expected one number or three separated by commas",
                                    flag, text));
        values.push_back(v);
        pos = comma + 1;
    }
    if (values.size() == 1) return Color3::Constant(values[0]);
    if (values.size() == 3) return Color3(values[0], values[1], values[2]);
    throw Error(
        fmt::format("{} '{}': expected one number or three separated by commas", flag, text));
}

ReadOptions readOptions(const FitArgs& args) {
    ReadOptions o;
    if (int(args.gamma.has_value()) + int(args.srgb) + int(args.linear) > 1)
        throw Error("--gamma, --srgb and --linear exclude each other");
    if (args.gamma) {
        if (!(*args.gamma > 0) || !std::isfinite(*args.gamma))
            throw Error(fmt::format("--gamma {}: must be a finite number > 0", *args.gamma));
        o.encoding = Encoding::Gamma;
        o.gamma = *args.gamma;
    }
    if (args.srgb) o.encoding = Encoding::Srgb;
    if (args.linear) o.encoding = Encoding::Linear;
    return o;
}

// A scene whose only object is one sphere (convex: it cannot see itself) lit only by point and
// directional lights has no indirect light at all: direct illumination (depth 2) is exact.
bool directLightIsExact(const Scene& scene) {
    if (scene.shapes.size() != 1 || scene.shapes[0].type != ShapeDesc::Type::Sphere ||
        scene.shapes[0].areaRadiance)
        return false;
    return std::all_of(scene.emitters.begin(), scene.emitters.end(), [](const EmitterDesc& e) {
        return e.type == EmitterDesc::Type::Point || e.type == EmitterDesc::Type::Directional;
    });
}

View loadView(const std::string& spec, const FitArgs& args, const std::vector<uint8_t>* sharedMask,
              const std::map<std::string, std::string>& defines) {
    const auto colon = spec.rfind(':');
    if (colon == std::string::npos || colon == 0 || colon + 1 == spec.size())
        throw Error(fmt::format("--view '{}': expected SCENE.xml:IMAGE", spec));
    View v;
    v.scenePath = spec.substr(0, colon);
    v.imagePath = spec.substr(colon + 1);
    Scene scene = loadScene(v.scenePath, defines);
    for (const std::string& id : args.materials) {
        const int b = scene.findBsdf(id);
        if (b < 0) {
            std::vector<std::string> ids;
            for (const BsdfDesc& d : scene.bsdfs)
                if (!d.id.empty()) ids.push_back(d.id);
            throw Error(fmt::format("{}: no bsdf with id '{}' (ids in the file: {})", v.scenePath,
                                    id, fmt::join(ids, ", ")));
        }
        if (scene.bsdfs[b].type != "phong")
            throw Error(
                fmt::format("{}: bsdf '{}' is '{}', not 'phong': only phong materials are "
                            "fitted",
                            scene.bsdfs[b].loc.str(), id, scene.bsdfs[b].type));
        v.fittedBsdfs.push_back(b);
    }
    if (directLightIsExact(scene)) {
        v.maxDepth = 2;
        v.depthNote =
            "indirect bounces (one convex object under point/directional lights: direct "
            "light is exact, depth 2)";
    } else {
        v.depthNote = "nothing (path tracing at the scene's depth)";
    }

    v.image = readImage(v.imagePath, readOptions(args));
    const SensorDesc& film = scene.sensor;
    if (v.image.width != film.width || v.image.height != film.height)
        throw Error(fmt::format("{}: image is {}x{} but the film of {} is {}x{}", v.imagePath,
                                v.image.width, v.image.height, v.scenePath, film.width,
                                film.height));
    Observation& o = v.observation;
    o.width = v.image.width;
    o.height = v.image.height;
    o.rgb = v.image.rgb;
    o.valid.assign(v.image.pixelCount(), 1);
    for (std::size_t p = 0; p < v.image.pixelCount(); ++p) {
        const float* c = &o.rgb[3 * p];
        if (!std::isfinite(c[0]) || !std::isfinite(c[1]) || !std::isfinite(c[2])) {
            if (!args.ignoreNonFinite)
                throw Error(
                    fmt::format("{}: pixel ({}, {}) is not finite (use --ignore-nonfinite "
                                "to leave such pixels out)",
                                v.imagePath, p % o.width, p / o.width));
            o.valid[p] = 0;
            o.rgb[3 * p] = o.rgb[3 * p + 1] = o.rgb[3 * p + 2] = 0;
            ++v.nonFinite;
        } else if ((sharedMask && !(*sharedMask)[p])) {
            o.valid[p] = 0;
            ++v.masked;
        } else if ((!v.image.clipped.empty() && v.image.clipped[p]) ||
                   (args.saturation && std::max({c[0], c[1], c[2]}) >= *args.saturation)) {
            o.valid[p] = 0;
            ++v.clipped;
        }
    }
    if (std::none_of(o.valid.begin(), o.valid.end(), [](uint8_t x) { return x != 0; }))
        throw Error(fmt::format("{}: every pixel is masked, clipped or not finite: nothing to fit",
                                v.imagePath));
    v.renderer = std::make_unique<Renderer>(std::move(scene));
    return v;
}

// observed | re-rendered with the fitted parameters | signed error (comparison_image.h). Rendered
// anew with more paths than a round records, so the middle column shows the model rather than the
// recording's noise.
cv::Mat comparison(const View& v, const std::vector<PhongMaterial>& fitted, double exposure,
                   const FitArgs& args) {
    Scene scene = v.renderer->scene();
    for (std::size_t s = 0; s < fitted.size(); ++s)
        scene.bsdfs[v.fittedBsdfs[s]].params = fitted[s];
    RenderOptions options;
    options.spp = args.compareSpp;
    options.seed = args.seed + 7919;  // independent of every recording
    options.threads = args.threads;
    options.maxDepth = v.maxDepth;
    options.quiet = true;
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

}  // namespace

FitResult runFit(const FitArgs& args) {
    const auto defines = parseDefines(args.defines);
    FitOptions options;
    options.loss = parseLoss(args.loss);
    options.grey = args.grey;
    options.fitExposure = args.fitExposure;
    options.maxRounds = args.rounds;
    options.threads = args.threads;
    options.stopRequested = interruptRequested;
    options.verbose = args.verbose;
    if (fs::exists(args.output) && !fs::is_directory(args.output))
        throw Error(fmt::format("-o '{}': exists and is not a directory", args.output));
    if (!fs::is_directory(fs::absolute(args.output).parent_path()))
        throw Error(fmt::format("-o '{}': directory '{}' does not exist", args.output,
                                fs::absolute(args.output).parent_path().string()));

    // Everything is read and checked before anything is written.
    std::vector<View> views;
    std::optional<std::vector<uint8_t>> mask;
    for (const std::string& spec : args.views) {
        if (!args.mask.empty() && !mask) {
            // The mask is sized by the first view's film.
            const auto colon = spec.rfind(':');
            const Scene first = loadScene(spec.substr(0, colon), defines);
            mask = readMask(args.mask, first.sensor.width, first.sensor.height);
        }
        views.push_back(loadView(spec, args, mask ? &*mask : nullptr, defines));
    }
    std::vector<PhongMaterial> start;
    for (int b : views[0].fittedBsdfs) {
        PhongMaterial m = views[0].renderer->scene().bsdfs[b].params;
        if (!args.kd.empty()) m.kd = parseColor(args.kd, "--kd");
        if (!args.ks.empty()) m.ks = parseColor(args.ks, "--ks");
        if (args.n) m.n = *args.n;
        validatePhong(m, "start value (--kd, --ks, --n)");
        start.push_back(m);
    }

    installInterruptHandler();
    const PathRecorder record = [&](int view, const std::vector<PhongMaterial>& theta0,
                                    int round) -> PathSet {
        const View& v = views[view];
        RecordOptions o;
        o.spp = args.spp;
        o.directSpp = args.directSpp;
        o.seed = args.seed * 1000003 + std::uint64_t(round) * 1009 + std::uint64_t(view);
        o.threads = args.threads;
        o.maxDepth = v.maxDepth;
        o.fittedBsdfs = v.fittedBsdfs;
        o.theta0 = theta0;
        // An interrupted recording still holds every pixel (the mean of the paths it got); the
        // fitter polls the same flag (stopRequested), ends the round and marks the fit interrupted.
        return v.renderer->record(o).paths;
    };
    options.onRound = [&](const FitRound& r) {
        if (args.quiet) return;
        std::string params;
        for (std::size_t s = 0; s < r.materials.size(); ++s)
            params +=
                fmt::format("  {}: kd {:.4g} ks {:.4g} n {:.4g}", args.materials[s],
                            r.materials[s].kd.mean(), r.materials[s].ks.mean(), r.materials[s].n);
        if (args.fitExposure) params += fmt::format("  exposure {:.4g}", r.exposure.value);
        fmt::print(stderr,
                   "round {}: rmse {:.5g}, {} iterations of {:.3f} s, {:.2f} s, paths {:.1f} MB, "
                   "peak {:.0f} MB{}\n",
                   r.round + 1, r.rmse, r.iterations, r.secondsPerIteration, r.timeSeconds,
                   r.recordedBytes / 1e6, r.peakMemoryBytes / 1e6, params);
    };
    std::vector<Observation> observations;
    for (const View& v : views) observations.push_back(v.observation);
    const FitResult result = fitMaterials(observations, record, start, options);

    std::vector<PhongMaterial> fitted;
    for (const MaterialFit& m : result.materials) fitted.push_back(m.material());
    nlohmann::json report = toJson(result, args.materials);
    report["record_spp"] = args.spp;
    report["seed"] = args.seed;
    for (const View& v : views) {
        report["views"].push_back({{"scene", v.scenePath},
                                   {"image", v.imagePath},
                                   {"max_depth", v.renderer->effectiveMaxDepth(v.maxDepth)},
                                   {"left_out", v.depthNote},
                                   {"pixels_clipped", v.clipped},
                                   {"pixels_masked", v.masked},
                                   {"pixels_non_finite", v.nonFinite}});
    }

    fs::create_directories(args.output);
    const fs::path dir(args.output);
    writeAtomically(dir / "fit.json",
                    [&](const fs::path& tmp) { std::ofstream(tmp) << report.dump(2) << "\n"; });
    std::map<std::string, PhongMaterial> byId;
    for (std::size_t s = 0; s < fitted.size(); ++s) byId[args.materials[s]] = fitted[s];
    for (std::size_t k = 0; k < views.size(); ++k) {
        const std::string suffix = k == 0 ? "" : fmt::format("_view{}", k + 1);
        writeSceneWithMaterials(views[k].scenePath, defines, byId,
                                (dir / ("fitted" + suffix + ".xml")).string());
        writePng(comparison(views[k], fitted, result.exposure ? result.exposure->value : 1.0, args),
                 (dir / ("compare" + suffix + ".png")).string());
    }

    for (std::size_t s = 0; s < result.materials.size(); ++s) {
        const MaterialFit& m = result.materials[s];
        fmt::print("{}: kd = {}, ks = {}, n = {:.5g} ± {:.2g}{}\n", args.materials[s],
                   formatColor(m.kd, m.kdStd, args.grey), formatColor(m.ks, m.ksStd, args.grey),
                   m.n, m.nStd,
                   m.unconstrained.empty() ? ""
                                           : fmt::format("  (unconstrained, held at start: {})",
                                                         fmt::join(m.unconstrained, ", ")));
    }
    if (result.exposure)
        fmt::print("exposure = {:.5g} ± {:.2g}{}\n", result.exposure->value, result.exposure->std,
                   result.exposure->unconstrained
                       ? "  (unconstrained: the images cannot tell it from the scale of kd and "
                         "ks; held where the start materials match their brightness, or as far "
                         "above as kd + ks <= 1 needs)"
                       : "");
    fmt::print("rmse {:.5g} after {} round{}{} in {:.2f} s; left out: {} -> {}\n", result.rmse,
               result.rounds.size(), result.rounds.size() == 1 ? "" : "s",
               result.converged ? " (converged)" : " (not converged)", result.timeSeconds,
               views[0].depthNote, (dir / "fit.json").string());
    return result;
}

void addFitCommand(CLI::App& app) {
    auto args = std::make_shared<FitArgs>();
    CLI::App* cmd =
        app.add_subcommand("fit", "recover kd, ks and n of phong materials from images of a scene");
    cmd->add_option(
        "--view", args->views,
        "SCENE.xml:IMAGE (EXR linear; PNG/JPEG decoded from sRGB); repeat for a joint fit");
    cmd->add_option("--material", args->materials,
                    "with --view: id of a phong bsdf to fit; repeatable");
    cmd->add_option("-o,--output", args->output, "output directory")->required();
    cmd->add_option("--mask", args->mask, "PNG mask: pixels that are 0 are left out");
    cmd->add_option("--spp", args->spp, "paths recorded per pixel and round")
        ->check(CLI::Range(1, 4096));
    cmd->add_option("--direct-spp", args->directSpp,
                    "paths recorded per round in pixels that see a fitted material directly "
                    "(default: --spp)")
        ->check(CLI::Range(1, 4096));
    cmd->add_option("--compare-spp", args->compareSpp,
                    "paths per pixel of the re-rendered column of compare.png")
        ->check(CLI::Range(1, 4096))
        ->capture_default_str();
    cmd->add_option("--rounds", args->rounds, "at most this many record-and-solve rounds")
        ->check(CLI::Range(1, 100));
    cmd->add_option("--loss", args->loss, "l2, huber or cauchy")
        ->check(CLI::IsMember({"l2", "huber", "cauchy"}));
    cmd->add_flag("--grey", args->grey, "one kd and one ks for all channels");
    cmd->add_flag("--fit-exposure", args->fitExposure,
                  "also fit an unknown global scale of the images (observed = s * rendered)");
    cmd->add_option("--kd", args->kd, "start value, R,G,B or one number (default: the scene's)");
    cmd->add_option("--ks", args->ks, "start value, R,G,B or one number (default: the scene's)");
    cmd->add_option("--n", args->n, "start value of the exponent (default: the scene's)");
    cmd->add_option("--gamma", args->gamma, "decode LDR images as value^gamma");
    cmd->add_flag("--srgb", args->srgb, "decode images with the sRGB curve (default for 8-bit)");
    cmd->add_flag("--linear", args->linear, "images are linear (default for 16-bit and EXR)");
    cmd->add_option("--saturation", args->saturation,
                    "leave out pixels with a channel at or above this linear value");
    cmd->add_flag("--ignore-nonfinite", args->ignoreNonFinite,
                  "leave out NaN/Inf pixels instead of failing");
    cmd->add_option("-D", args->defines, "override a scene default: name=value");
    cmd->add_option("--seed", args->seed, "random seed of the recordings");
    cmd->add_option("--threads", args->threads, "worker threads (default: all)")
        ->check(CLI::Range(1, 1024));
    cmd->add_flag("--quiet", args->quiet, "no progress lines");
    cmd->add_flag("--verbose", args->verbose, "Ceres reports");
    auto capture = std::make_shared<CaptureArgs>();
    addCaptureOptions(*cmd, *capture);
    cmd->callback([args, capture, cmd] {
        if (runCaptureFitIfGiven(*cmd, *capture, *args)) return;
        if (args->materials.empty())
            throw Error("--view needs --material ID (the phong bsdf to fit)");
        runFit(*args);
    });
}

}  // namespace phongfit
