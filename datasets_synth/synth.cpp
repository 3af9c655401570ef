#include "synth.h"

#include <fmt/format.h>

#include <atomic>
#include <chrono>
#include <exception>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <nlohmann/json.hpp>
#include <sstream>
#include <thread>

#include "atomic_file.h"
#include "error.h"
#include "image.h"
#include "interrupt.h"
#include "progress.h"
#include "renderer.h"
#include "sample_spec.h"
#include "scene_baker.h"
#include "scene_parser.h"

namespace phongfit {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

std::string readFile(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw Error(fmt::format("cannot read '{}'", path));
    std::stringstream s;
    s << in.rdbuf();
    return s.str();
}

std::uint64_t fnv1a(const std::string& s) {
    std::uint64_t h = 0xcbf29ce484222325ULL;
    for (const unsigned char c : s) h = (h ^ c) * 0x100000001b3ULL;
    return h;
}

void writeJson(const fs::path& path, const json& j) {
    writeAtomically(path, [&](const fs::path& tmp) {
        std::ofstream out(tmp);
        out << j.dump(2) << "\n";
        if (!out) throw Error(fmt::format("cannot write '{}'", tmp.string()));
    });
}

// What the dataset was made from: a resumed run must match it.
json datasetRecord(const SynthConfig& config) {
    json digests = json::object();
    for (const GroupConfig& g : config.groups)
        for (std::size_t i = 0; i < g.scenes.size(); ++i)
            digests[g.scenes[i]] = fmt::format("{:016x}", fnv1a(readFile(g.scenePaths[i])));
    return {{"generator", "phongfit synth"}, {"config", config.json}, {"scene_digests", digests}};
}

void prepareOutput(const fs::path& dir, const json& record) {
    const fs::path recordPath = dir / "config.json";
    if (fs::exists(dir) && !fs::is_directory(dir))
        throw Error(fmt::format("-o '{}': exists and is not a directory", dir.string()));
    if (fs::exists(recordPath)) {
        json existing;
        try {
            existing = json::parse(readFile(recordPath.string()));
        } catch (const json::exception&) {
            existing = nullptr;
        }
        if (existing != record)
            throw Error(fmt::format(
                "-o '{}': holds a dataset made from another config or other scene files (see {}): "
                "use another folder, or delete this one to start over",
                dir.string(), recordPath.string()));
        return;
    }
    if (fs::exists(dir) && !fs::is_empty(dir))
        throw Error(
            fmt::format("-o '{}': not empty and not a synth dataset (no config.json): use "
                        "a new or empty folder",
                        dir.string()));
    if (!fs::is_directory(fs::absolute(dir).parent_path()))
        throw Error(fmt::format("-o '{}': directory '{}' does not exist", dir.string(),
                                fs::absolute(dir).parent_path().string()));
    fs::create_directories(dir);
    writeJson(recordPath, record);
}

json toJson(const Color3& c) { return json::array({c[0], c[1], c[2]}); }

// Renders one sample into dir/<name>; false (and no truth.json) if the render was interrupted.
bool makeSample(const SynthConfig& config, const SampleSpec& s, const fs::path& dir, int threads) {
    const GroupConfig& g = config.groups[s.group];
    const fs::path sampleDir = dir / s.name;
    fs::remove_all(sampleDir);  // what an interrupted attempt left
    fs::create_directories(sampleDir);
    const std::string scenePath = (sampleDir / "scene.xml").string();
    const std::set<std::string> baked =
        bakeSceneDefaults(g.scenePaths[s.scene], s.defines,
                          fmt::format("phongfit synth: {} of {} (group {}, seed {}), from {}",
                                      s.name, fs::path(config.path).filename().string(), g.name,
                                      config.seed, g.scenes[s.scene]),
                          scenePath);

    // The truth is what the written scene file says, as the renderer reads it.
    const Renderer renderer(loadScene(scenePath));
    const PhongMaterial truth =
        renderer.scene().bsdfs[renderer.scene().findBsdf(g.material)].params;
    RenderOptions options;
    options.spp = g.spp;
    options.seed = s.renderSeed;
    options.threads = threads;
    options.quiet = true;
    const RenderResult r = renderer.render(options);
    if (r.stats.interrupted) return false;
    Image image(r.width, r.height);
    image.rgb = r.rgb;
    writeExr(image, (sampleDir / "image.exr").string());

    json defines = json::object();
    for (const std::string& name : baked) defines[name] = s.defines.at(name);
    json truthJson = {
        {"name", s.name},
        {"index", s.index},
        {"group", g.name},
        {"base_scene", g.scenes[s.scene]},
        {"scene", "scene.xml"},
        {"image", "image.exr"},
        {"material", g.material},
        {"kd", toJson(truth.kd)},
        {"ks", toJson(truth.ks)},
        {"n", truth.n},
        // Drawn grey, or a grid material grey in kd and ks: the fit ties the channels.
        {"grey", g.grid ? truth.kd.maxCoeff() == truth.kd.minCoeff() &&
                              truth.ks.maxCoeff() == truth.ks.minCoeff()
                        : !g.colour},
        {"defines", defines},
        {"spp", g.spp},
        {"seed", s.renderSeed},
        {"width", r.width},
        {"height", r.height},
        {"sampler", options.sampler},
        {"mis", options.mis},
        {"non_finite_samples", r.stats.nonFinite},
    };
    if (s.light)
        truthJson["light"] = {
            {"phase_deg", s.light->phaseDeg},
            {"azimuth_deg", s.light->azimuthDeg},
            {"distance", s.light->distance},
            {"position",
             json::array({s.light->position.x(), s.light->position.y(), s.light->position.z()})}};
    writeJson(sampleDir / "truth.json", truthJson);
    return true;
}

void writeIndex(const SynthConfig& config, const fs::path& dir) {
    json samples = json::array();
    for (int i = 0; i < config.totalSamples(); ++i) {
        const std::string name = sampleName(i, config.totalSamples());
        const json truth = json::parse(readFile((dir / name / "truth.json").string()));
        samples.push_back({{"name", name},
                           {"group", truth["group"]},
                           {"base_scene", truth["base_scene"]},
                           {"material", truth["material"]},
                           {"kd", truth["kd"]},
                           {"ks", truth["ks"]},
                           {"n", truth["n"]}});
    }
    writeJson(dir / "index.json", {{"generator", "phongfit synth"},
                                   {"config", fs::path(config.path).filename().string()},
                                   {"seed", config.seed},
                                   {"count", config.totalSamples()},
                                   {"samples", samples}});
}

}  // namespace

SynthSummary runSynth(const SynthConfig& config, const SynthOptions& options) {
    const auto start = std::chrono::steady_clock::now();
    const fs::path dir(options.output);
    prepareOutput(dir, datasetRecord(config));

    SynthSummary summary;
    summary.total = config.totalSamples();
    std::vector<int> pending;
    for (int i = 0; i < summary.total; ++i) {
        if (fs::exists(dir / sampleName(i, summary.total) / "truth.json"))
            ++summary.alreadyComplete;
        else
            pending.push_back(i);
    }

    const int jobs = std::clamp(options.jobs, 1, std::max(1, int(pending.size())));
    const int threads = std::max(1, int(std::thread::hardware_concurrency()) / jobs);
    Progress progress("synth", pending.size(), "samples", options.quiet);
    std::atomic<std::size_t> next{0};
    std::atomic<int> rendered{0};
    std::atomic<bool> failed{false};
    std::exception_ptr error;
    std::mutex errorMutex;
    auto worker = [&] {
        while (!failed && !interruptRequested()) {
            const std::size_t k = next++;
            if (k >= pending.size()) return;
            try {
                if (makeSample(config, drawSample(config, pending[k]), dir, threads)) {
                    ++rendered;
                    progress.advance();
                }
            } catch (...) {
                const std::lock_guard lock(errorMutex);
                if (!error) error = std::current_exception();
                failed = true;
            }
        }
    };
    std::vector<std::thread> pool;
    for (int j = 1; j < jobs; ++j) pool.emplace_back(worker);
    worker();
    for (std::thread& t : pool) t.join();
    if (error) std::rethrow_exception(error);

    summary.rendered = rendered;
    summary.interrupted = summary.rendered + summary.alreadyComplete < summary.total;
    if (!summary.interrupted) {
        progress.finish();
        writeIndex(config, dir);
    }
    summary.seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return summary;
}

}  // namespace phongfit
