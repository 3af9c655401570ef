#include "synth.h"

#include <fmt/format.h>

#include <atomic>
#include <chrono>
#include <exception>
#include <filesystem>
#include <mutex>
#include <nlohmann/json.hpp>
#include <thread>

#include "color_json.h"
#include "error.h"
#include "image.h"
#include "interrupt.h"
#include "json_files.h"
#include "progress.h"
#include "renderer.h"
#include "sample_spec.h"
#include "scene_baker.h"
#include "scene_parser.h"

namespace phongfit {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

// What the dataset is made from (a resumed run must match it: "config" and "scene_digests"), and
// what `synth --merge` needs to write the index without the config file.
json datasetRecord(const SynthConfig& config) {
    json digests = json::object();
    for (const GroupConfig& g : config.groups)
        for (std::size_t i = 0; i < g.scenes.size(); ++i)
            digests[g.scenes[i]] = textDigest(readTextFile(g.scenePaths[i]));
    return {
        {"generator", "phongfit synth"}, {"config", config.json},
        {"scene_digests", digests},      {"config_file", fs::path(config.path).filename().string()},
        {"seed", config.seed},           {"samples", config.totalSamples()}};
}

bool sameSource(const json& a, const json& b) {
    return a.is_object() && b.is_object() &&
           a.value("config", json()) == b.value("config", json()) &&
           a.value("scene_digests", json()) == b.value("scene_digests", json());
}

json readRecord(const fs::path& path) {
    try {
        return json::parse(readTextFile(path));
    } catch (const json::exception&) {
        return nullptr;
    }
}

// Whether `dir` holds anything but a shard's temporary config.json (another shard of this run
// creating the dataset at the same moment).
bool holdsFiles(const fs::path& dir) {
    for (const fs::directory_entry& e : fs::directory_iterator(dir))
        if (e.path().filename().string().rfind(".config.json.", 0) != 0) return true;
    return false;
}

void prepareOutput(const fs::path& dir, const json& record) {
    const fs::path recordPath = dir / "config.json";
    if (fs::exists(dir) && !fs::is_directory(dir))
        throw Error(fmt::format("-o '{}': exists and is not a directory", dir.string()));
    // A shard that sees samples of another sees its config.json too: it is written first.
    if (!fs::exists(recordPath) && fs::exists(dir) && holdsFiles(dir) && !fs::exists(recordPath))
        throw Error(
            fmt::format("-o '{}': not empty and not a synth dataset (no config.json): use "
                        "a new or empty folder",
                        dir.string()));
    if (!fs::exists(recordPath)) {
        if (!fs::is_directory(fs::absolute(dir).parent_path()))
            throw Error(fmt::format("-o '{}': directory '{}' does not exist", dir.string(),
                                    fs::absolute(dir).parent_path().string()));
        fs::create_directories(dir);
        writeJsonAtomically(recordPath, record);
    }
    const json existing = readRecord(recordPath);
    if (!sameSource(existing, record))
        throw Error(fmt::format(
            "-o '{}': holds a dataset made from another config or other scene files (see {}): "
            "use another folder, or delete this one to start over",
            dir.string(), recordPath.string()));
    if (existing != record) writeJsonAtomically(recordPath, record);  // from an older phongfit
}

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
        {"kd", colorJson(truth.kd)},
        {"ks", colorJson(truth.ks)},
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
    writeJsonAtomically(sampleDir / "truth.json", truthJson);
    return true;
}

bool sampleComplete(const fs::path& dir, int index, int total) {
    return fs::exists(dir / sampleName(index, total) / "truth.json");
}

// The indices of the samples not complete yet, of all `total`.
std::vector<int> missingSamples(const fs::path& dir, int total) {
    std::vector<int> missing;
    for (int i = 0; i < total; ++i)
        if (!sampleComplete(dir, i, total)) missing.push_back(i);
    return missing;
}

// From the dataset's config.json (datasetRecord).
void writeIndex(const json& record, const fs::path& dir) {
    const int count = record.at("samples").get<int>();
    json samples = json::array();
    for (int i = 0; i < count; ++i) {
        const std::string name = sampleName(i, count);
        const json truth = readJsonFile(dir / name / "truth.json");
        samples.push_back({{"name", name},
                           {"group", truth["group"]},
                           {"base_scene", truth["base_scene"]},
                           {"material", truth["material"]},
                           {"kd", truth["kd"]},
                           {"ks", truth["ks"]},
                           {"n", truth["n"]}});
    }
    writeJsonAtomically(dir / "index.json", {{"generator", "phongfit synth"},
                                             {"config", record.at("config_file")},
                                             {"seed", record.at("seed")},
                                             {"count", count},
                                             {"samples", samples}});
}

}  // namespace

SynthSummary runSynth(const SynthConfig& config, const SynthOptions& options) {
    const auto start = std::chrono::steady_clock::now();
    const fs::path dir(options.output);
    const json record = datasetRecord(config);
    prepareOutput(dir, record);

    SynthSummary summary;
    summary.datasetTotal = config.totalSamples();
    std::vector<int> pending;
    for (int i = 0; i < summary.datasetTotal; ++i) {
        if (!options.shard.contains(i)) continue;
        ++summary.total;
        if (sampleComplete(dir, i, summary.datasetTotal))
            ++summary.alreadyComplete;
        else
            pending.push_back(i);
    }

    const int jobs = std::clamp(options.jobs, 1, std::max(1, int(pending.size())));
    const int hardware = std::max(1, int(std::thread::hardware_concurrency()));
    const int threads = std::max(1, (options.threads > 0 ? options.threads : hardware) / jobs);
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
        // Whichever shard ends last finds every sample and writes the index.
        summary.datasetComplete =
            summary.datasetTotal - int(missingSamples(dir, summary.datasetTotal).size());
        if (summary.datasetComplete == summary.datasetTotal) {
            writeIndex(record, dir);
            summary.indexWritten = true;
        }
    }
    summary.seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return summary;
}

SynthSummary mergeSynth(const std::string& directory) {
    const auto start = std::chrono::steady_clock::now();
    const fs::path dir(directory);
    const fs::path recordPath = dir / "config.json";
    if (!fs::is_directory(dir) || !fs::exists(recordPath))
        throw Error(fmt::format("--merge '{}': not a synth dataset (no config.json)", directory));
    const json record = readRecord(recordPath);
    if (!record.is_object() || !record.contains("samples") || !record.contains("config_file") ||
        !record.contains("seed") || !record["samples"].is_number_integer())
        throw Error(fmt::format(
            "--merge '{}': {} was written by an older phongfit or is damaged: run phongfit synth "
            "CONFIG -o {} to finish the dataset",
            directory, recordPath.string(), directory));
    SynthSummary summary;
    summary.datasetTotal = summary.total = record["samples"].get<int>();
    const std::vector<int> missing = missingSamples(dir, summary.datasetTotal);
    summary.datasetComplete = summary.alreadyComplete = summary.datasetTotal - int(missing.size());
    if (!missing.empty()) {
        std::string names;
        for (std::size_t k = 0; k < std::min<std::size_t>(missing.size(), 3); ++k)
            names += (k ? ", " : "") + sampleName(missing[k], summary.datasetTotal);
        throw Error(fmt::format(
            "--merge '{}': {} of {} samples are not complete ({}{}): run the missing shards "
            "again (finished samples are kept)",
            directory, missing.size(), summary.datasetTotal, names,
            missing.size() > 3 ? ", ..." : ""));
    }
    writeIndex(record, dir);
    summary.indexWritten = true;
    summary.seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return summary;
}

}  // namespace phongfit
