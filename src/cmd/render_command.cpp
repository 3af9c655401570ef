// phongfit render SCENE.xml -o OUT.exr ...
#include <fmt/format.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <thread>

#include "atomic_file.h"
#include "commands.h"
#include "defines.h"
#include "error.h"
#include "image.h"
#include "interrupt.h"
#include "phong_sampler.h"
#include "render_sidecar.h"
#include "renderer.h"
#include "scene_parser.h"

namespace phongfit {
namespace {

struct RenderArgs {
    std::string scene, output, png;
    std::vector<std::string> defines;
    RenderOptions options;
};

// A material as messages name it: its id, or where it is defined.
std::string materialName(const Scene& scene, int bsdf) {
    if (bsdf < 0) return "environment";
    const BsdfDesc& b = scene.bsdfs[bsdf];
    return b.id.empty() ? fmt::format("{} at {}", b.type, b.loc.str()) : b.id;
}

Image toImage(const RenderResult& r) {
    Image image(r.width, r.height);
    image.rgb = r.rgb;
    return image;
}

// Fails before any work when an output could not be written afterwards.
void requireOutputDirectory(const std::string& path) {
    const std::filesystem::path parent = std::filesystem::absolute(path).parent_path();
    if (!std::filesystem::is_directory(parent))
        throw Error(
            fmt::format("cannot write '{}': directory '{}' does not exist", path, parent.string()));
}

void runRender(const RenderArgs& args) {
    requireExrName(args.output);
    requireOutputDirectory(args.output);
    if (!args.png.empty()) requireOutputDirectory(args.png);
    Renderer renderer(loadScene(args.scene, parseDefines(args.defines)));
    const RenderResult result = renderer.render(args.options);
    const Image image = toImage(result);
    writeExr(image, args.output);
    if (!args.png.empty()) writePng(image, args.png);

    const RenderStats& s = result.stats;
    const int threads =
        args.options.threads > 0 ? args.options.threads : int(std::thread::hardware_concurrency());
    nlohmann::json sidecar = {
        {"scene", args.scene},
        {"defines", parseDefines(args.defines)},
        {"seed", args.options.seed},
        {"spp", s.spp},
        {"samples", s.samples},
        {"interrupted", s.interrupted},
        {"sampler", args.options.sampler},
        {"pixel_sampler", pixelSamplerName(args.options.pixelSampler.value_or(
                              renderer.scene().sensor.pixelSampler))},
        {"mis", args.options.mis},
        {"max_depth", renderer.effectiveMaxDepth(args.options.maxDepth)},
        {"pixel_filter", pixelFilterJson(pixelFilterOf(renderer.scene().sensor))},
        {"threads", threads},
        {"width", result.width},
        {"height", result.height},
        {"time_s", s.seconds},
        {"rays", s.rays},
        {"mrays_per_s", s.rays / s.seconds / 1e6},
        {"samples_per_s", s.samples / s.seconds},
        {"non_finite_samples", s.nonFinite},
        {"non_finite_first", nlohmann::json::array()},
    };
    for (const NonFiniteSample& n : s.nonFiniteFirst) {
        const std::string material = materialName(renderer.scene(), n.bsdf);
        sidecar["non_finite_first"].push_back({{"pixel", {n.x, n.y}},
                                               {"sample", n.sample},
                                               {"depth", n.depth},
                                               {"material", material}});
    }
    writeAtomically(args.output + ".json", [&](const std::filesystem::path& tmp) {
        std::ofstream(tmp) << sidecar.dump(2) << "\n";
    });

    fmt::print("rendered {}x{} at {} spp in {:.2f} s: {:.1f} Mrays/s, {:.2f} Msamples/s -> {}\n",
               result.width, result.height, s.spp, s.seconds, s.rays / s.seconds / 1e6,
               s.samples / s.seconds / 1e6, args.output);
    if (s.nonFinite > 0) {
        const NonFiniteSample& n = s.nonFiniteFirst.front();
        fmt::print(
            "warning: {} samples had a non-finite value and were left out (the first at "
            "pixel ({}, {}), path depth {}, material '{}'; all in {}.json)\n",
            s.nonFinite, n.x, n.y, n.depth, materialName(renderer.scene(), n.bsdf), args.output);
    }
    if (s.interrupted)
        fmt::print("interrupted: the image holds {} of {} samples ({:.1f}%)\n", s.samples,
                   std::uint64_t(s.spp) * result.width * result.height,
                   100.0 * s.samples / (double(s.spp) * result.width * result.height));
}

}  // namespace

void addRenderCommand(CLI::App& app) {
    auto args = std::make_shared<RenderArgs>();
    CLI::App* cmd = app.add_subcommand("render", "render a Mitsuba-XML scene to a linear EXR");
    cmd->add_option("scene", args->scene, "scene file (Mitsuba 0.6 XML subset)")->required();
    cmd->add_option("-o,--output", args->output, "output EXR")->required();
    cmd->add_option("--spp", args->options.spp, "samples per pixel (default: the scene's)")
        ->check(CLI::Range(1, 1 << 20));
    cmd->add_option("--seed", args->options.seed, "random seed");
    cmd->add_option("--threads", args->options.threads, "worker threads (default: all)")
        ->check(CLI::Range(1, 1024));
    cmd->add_option("--sampler", args->options.sampler, "Phong sampler")
        ->check(CLI::IsMember(phongSamplerNames()));
    cmd->add_option_function<std::string>(
           "--pixel-sampler",
           [args](const std::string& name) { args->options.pixelSampler = pixelSamplerType(name); },
           "samples of a pixel: independent, sobol or ldsampler (padded Sobol points) (default: "
           "the scene's "
           "<sampler type>, sobol when it names none)")
        ->check(CLI::IsMember(pixelSamplerNames()));
    cmd->add_option("--max-depth", args->options.maxDepth,
                    "path depth as in Mitsuba (1 = emitters only, 2 = direct, -1 = unbounded)")
        ->check(CLI::Range(-1, 1000));
    cmd->add_flag("!--no-mis", args->options.mis,
                  "area and environment light only by BRDF sampling (no light sampling, no MIS)");
    cmd->add_option("-D", args->defines, "override a scene default: name=value");
    cmd->add_option("--png", args->png, "also write a tone-mapped sRGB PNG preview");
    cmd->add_flag("--quiet", args->options.quiet, "no progress bar");
    cmd->callback([args] { runRender(*args); });
}

}  // namespace phongfit
