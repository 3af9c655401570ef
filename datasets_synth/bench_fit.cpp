#include "bench_fit.h"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <optional>

#include "atomic_file.h"
#include "bench_fit_report.h"
#include "bench_fit_row.h"
#include "color_json.h"
#include "error.h"
#include "interrupt.h"
#include "json_files.h"
#include "machine_info.h"
#include "scene_fit.h"
#include "synth_dataset.h"

namespace phongfit {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

// One parameter of a fit beside its truth: `name` as the fit lists it when held ("kd.g", "n").
struct ParameterCheck {
    std::string name, group;  // group: "kd", "ks" or "n"
    double value, truth, std;
};

std::vector<ParameterCheck> parameterChecks(const MaterialFit& m, const PhongMaterial& truth) {
    std::vector<ParameterCheck> checks;
    for (int c = 0; c < 3; ++c) {
        const std::string channel(1, "rgb"[c]);
        checks.push_back({"kd." + channel, "kd", m.kd[c], truth.kd[c], m.kdStd[c]});
        checks.push_back({"ks." + channel, "ks", m.ks[c], truth.ks[c], m.ksStd[c]});
    }
    checks.push_back({"n", "n", m.n, truth.n, m.nStd});
    return checks;
}

bool isHeld(const MaterialFit& m, const ParameterCheck& p) {
    return m.isUnconstrained(p.group) || m.isUnconstrained(p.name);
}

// Whether every parameter the fit did not hold lies within 3 of its standard errors of the truth
// (kd and ks per channel): whether the uncertainty the tool reports covers its error.
bool withinErrors(const MaterialFit& m, const PhongMaterial& truth) {
    for (const ParameterCheck& p : parameterChecks(m, truth))
        if (!isHeld(m, p) && !(std::abs(p.value - p.truth) <= 3 * p.std)) return false;
    return true;
}

// Against the recovery target (BenchFitOptions' tolerances), for the parameters not held: whether
// all are within tolerance, and whether the fit passes: its standard errors cover the truth
// (withinErrors), and each parameter out of tolerance has a standard error of at least half the
// tolerance, so that its +-2 std interval does not claim the target.
Verdict judge(const MaterialFit& m, const PhongMaterial& truth, const BenchFitOptions& o) {
    Verdict v;
    v.pass = withinErrors(m, truth);
    for (const ParameterCheck& p : parameterChecks(m, truth)) {
        if (isHeld(m, p)) continue;
        const double tolerance = p.group == "n"
                                     ? o.nTolerance * p.truth
                                     : std::max(o.kdKsTolerance * p.truth, o.toleranceFloor);
        if (std::abs(p.value - p.truth) <= tolerance) continue;
        v.withinTolerance = false;
        if (!(2 * p.std >= tolerance)) v.pass = false;
    }
    return v;
}

double startExponent(const BenchFitOptions& o, double truth) {
    if (!(o.startNFactor > 0)) return o.startN;
    return truth * o.startNFactor <= kMaxStartN ? truth * o.startNFactor : truth / o.startNFactor;
}

// Fits `s` and writes the fit's outputs into `out`.
FitRow fitSample(const DatasetSample& s, int spp, const BenchFitOptions& o, const fs::path& out) {
    FitRow row;
    row.sample = &s;
    row.spp = spp;
    SceneFitInputs in;
    in.views = {{s.scenePath, s.imagePath}};
    in.materials = {s.material};
    in.kd = o.startKd;
    in.ks = o.startKs;
    in.n = startExponent(o, s.truth.n);
    const SceneRecording recording{spp, 0, 0, o.threads, o.adaptiveSpp, !o.sampledAreaLights};
    FitOptions options;
    options.maxRounds = o.rounds;
    options.precision = o.precision;
    options.timeBudget = o.timeBudget;
    options.grey = s.grey;
    options.threads = o.threads;
    options.stopRequested = interruptRequested;
    // Timed: reading the inputs and fitting, not writing the fit's outputs (which re-render).
    const auto start = std::chrono::steady_clock::now();
    try {
        const SceneFitProblem problem = loadSceneFit(in);
        const FitResult r = fitScene(problem, recording, options);
        row.seconds =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
        writeSceneFit(problem, r, recording, 32, out.string());
        row.returned = true;
        row.fit = r.materials.at(0);
        row.rounds = int(r.rounds.size());
        row.converged = r.converged;
        row.rmse = r.rmse;
        row.errors = errorsOf(row.fit, s.truth);
        row.withinErrors = withinErrors(row.fit, s.truth);
        row.verdict = judge(row.fit, s.truth, o);
        double cumulative = 0;
        for (const FitRound& round : r.rounds) {
            cumulative += round.timeSeconds;
            row.history.push_back({cumulative, errorsOf(round.materials.at(0), s.truth),
                                   relativeStdOf(round.materials.at(0), s.truth)});
        }
        if (!isFinite(row.fit)) {
            row.failed = true;
            row.error = "non-finite result";
        } else if (std::max({row.fit.isUnconstrained("kd") ? 0 : row.errors.kd,
                             row.fit.isUnconstrained("ks") ? 0 : row.errors.ks,
                             row.fit.isUnconstrained("n") ? 0 : row.errors.n}) > o.failThreshold) {
            row.failed = true;
            row.error = fmt::format("relative error above {}", o.failThreshold);
        }
    } catch (const std::exception& e) {
        row.seconds =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
        row.failed = true;
        row.error = e.what();
    }
    return row;
}

// The options that decide the results (not the threads, the output or the shard), exactly.
json settingsJson(const BenchFitOptions& o) {
    return {{"spp_per_round", o.sppPerRound},
            {"start_kd", colorJson(o.startKd)},
            {"start_ks", colorJson(o.startKs)},
            {"start_n", o.startN},
            {"start_n_factor", o.startNFactor},
            {"kd_ks_tolerance", o.kdKsTolerance},
            {"tolerance_floor", o.toleranceFloor},
            {"n_tolerance", o.nTolerance},
            {"rounds", o.rounds},
            {"adaptive_spp", o.adaptiveSpp},
            {"sampled_area_lights", o.sampledAreaLights},
            {"precision", o.precision},
            {"time_budget", o.timeBudget},
            {"fail_threshold", o.failThreshold}};
}

void applySettings(const json& s, const std::string& file, BenchFitOptions& o) {
    o.sppPerRound = s.at("spp_per_round").get<std::vector<int>>();
    o.startKd = colorFromJson(s.at("start_kd"), file, "settings.start_kd");
    o.startKs = colorFromJson(s.at("start_ks"), file, "settings.start_ks");
    o.startN = s.at("start_n").get<double>();
    o.startNFactor = s.at("start_n_factor").get<double>();
    o.kdKsTolerance = s.at("kd_ks_tolerance").get<double>();
    o.toleranceFloor = s.at("tolerance_floor").get<double>();
    o.nTolerance = s.at("n_tolerance").get<double>();
    o.rounds = s.at("rounds").get<int>();
    o.adaptiveSpp = s.at("adaptive_spp").get<int>();
    o.sampledAreaLights = s.value("sampled_area_lights", true);  // runs before rings sampled
    o.precision = s.value("precision", 0.0);                     // runs before it had none
    o.timeBudget = s.value("time_budget", 0.0);
    o.failThreshold = s.at("fail_threshold").get<double>();
}

// DIR/bench_run.json: what the run fits (the dataset, as its index reads now), how, and with which
// build (a digest of the running executable itself: a rebuild with uncommitted changes is another
// run). Its key marks every saved row: a row of another run is not reused.
json runRecord(const BenchFitOptions& o) {
    json record = {{"generator", "phongfit bench fit"},
                   {"settings", settingsJson(o)},
                   {"dataset_index", textDigest(readTextFile(fs::path(o.dataset) / "index.json"))},
                   {"commit", machineInfo(0).at("commit")},
                   {"executable", textDigest(readTextFile("/proc/self/exe"))}};
    record["run"] = textDigest(record.dump());
    record["dataset"] = fs::absolute(o.dataset).lexically_normal().string();
    return record;
}

fs::path fitFolder(const fs::path& dir, int spp, const DatasetSample& s) {
    return dir / "fits" / fmt::format("spp{}", spp) / s.name;
}

fs::path rowPath(const fs::path& dir, int spp, const DatasetSample& s) {
    return fitFolder(dir, spp, s) / "bench_row.json";
}

// The saved row of this run, if any. A row that does not read back (edited or damaged by hand: rows
// are written atomically) counts as not done, and is fitted again.
std::optional<FitRow> savedRow(const fs::path& dir, int spp, const DatasetSample& s,
                               const std::string& run) {
    const fs::path path = rowPath(dir, spp, s);
    if (!fs::exists(path)) return std::nullopt;
    try {
        const json j = readJsonFile(path);
        if (!j.is_object() || j.value("run", "") != run) return std::nullopt;
        return fitRowFromJson(j, s, path.string());
    } catch (const Error&) {
        return std::nullopt;
    }
}

// Every row of this run saved so far, spp-major in dataset order; `missing` counts the others.
std::vector<FitRow> savedRows(const fs::path& dir, const BenchFitOptions& o,
                              const std::vector<DatasetSample>& samples, const std::string& run,
                              std::size_t& missing) {
    std::vector<FitRow> rows;
    missing = 0;
    for (const int spp : o.sppPerRound)
        for (const DatasetSample& s : samples) {
            std::optional<FitRow> row = savedRow(dir, spp, s, run);
            if (row)
                rows.push_back(std::move(*row));
            else
                ++missing;
        }
    return rows;
}

std::string progressLine(const FitRow& r) {
    return r.returned ? fmt::format("kd {}, ks {}, n {} off; {} rounds, {:.2f} s{}",
                                    percentText(r.errors.kd), percentText(r.errors.ks),
                                    percentText(r.errors.n), r.rounds, r.seconds,
                                    r.failed ? " (failed)" : "")
                      : "failed: " + r.error;
}

}  // namespace

void runBenchFit(const BenchFitOptions& o) {
    if (o.sppPerRound.empty()) throw Error("--spp-per-round: give at least one value");
    for (const int spp : o.sppPerRound)
        if (spp < 1 || spp > 4096)
            throw Error(fmt::format("--spp-per-round {}: each value must be in [1, 4096]", spp));
    if (!(o.failThreshold > 0))
        throw Error(fmt::format("--fail-threshold {}: must be > 0", o.failThreshold));
    requireOutputDirectory(o.output);
    const fs::path dir(o.output);
    const std::vector<DatasetSample> samples = readDataset(o.dataset);
    fs::create_directories(dir);
    const json record = runRecord(o);
    const std::string run = record.at("run");
    writeJsonAtomically(dir / "bench_run.json", record);

    // This shard's fits: item k = spp index x samples + sample index.
    std::vector<std::pair<int, const DatasetSample*>> mine;
    for (std::size_t i = 0; i < o.sppPerRound.size(); ++i)
        for (std::size_t j = 0; j < samples.size(); ++j)
            if (o.shard.contains(int(i * samples.size() + j)))
                mine.emplace_back(o.sppPerRound[i], &samples[j]);
    std::size_t done = 0, kept = 0;
    for (const auto& [spp, s] : mine) {
        if (interruptRequested()) break;
        ++done;
        if (savedRow(dir, spp, *s, run)) {
            ++kept;
            continue;
        }
        const fs::path out = fitFolder(dir, spp, *s);
        fs::create_directories(out);
        FitRow row = fitSample(*s, spp, o, out);
        if (interruptRequested()) {  // stopped mid-way: not a measurement
            --done;
            break;
        }
        writeJsonAtomically(rowPath(dir, spp, *s), toJson(row, run));
        if (!o.quiet)
            fmt::print(stderr, "[{}/{}] {} at {} spp/round: {}\n", done, mine.size(), s->name, spp,
                       progressLine(row));
    }
    const bool interrupted = done < mine.size();
    const std::string part = o.shard.whole() ? "" : fmt::format("shard {}: ", o.shard.text());
    if (kept > 0)
        fmt::print(
            "bench fit: {}{} fits done earlier with these settings, dataset and build were "
            "kept, not refitted\n",
            part, kept);

    std::size_t missing = 0;
    const std::vector<FitRow> rows = savedRows(dir, o, samples, run, missing);
    if (missing == 0 || (interrupted && o.shard.whole())) {
        writeBenchFitReport(rows, o, samples.size(), interrupted);
        return;
    }
    if (interrupted)
        throw Error(
            fmt::format("interrupted: {}{} of {} fits done in {}; run the same command "
                        "again to resume",
                        part, done, mine.size(), o.output));
    fmt::print(
        "bench fit: {}{} fits done; {} of the run's {} fits are done: the tables are written by "
        "the shard that completes them, or by phongfit bench fit --merge {}\n",
        part, mine.size(), rows.size(), rows.size() + missing, o.output);
}

void mergeBenchFit(const std::string& directory, int threads) {
    const fs::path dir(directory);
    const fs::path recordPath = dir / "bench_run.json";
    if (!fs::exists(recordPath))
        throw Error(
            fmt::format("--merge '{}': not a bench fit folder (no bench_run.json)", directory));
    const json record = readJsonFile(recordPath);
    BenchFitOptions o;
    try {
        applySettings(record.at("settings"), recordPath.string(), o);
        o.dataset = record.at("dataset").get<std::string>();
    } catch (const json::exception& e) {
        throw Error(fmt::format("{}: damaged: {}", recordPath.string(), e.what()));
    }
    o.output = directory;
    o.threads = threads;
    const std::vector<DatasetSample> samples = readDataset(o.dataset);
    const std::string run = runRecord(o).at("run");
    if (run != record.value("run", ""))
        throw Error(fmt::format(
            "--merge '{}': the dataset {} or the phongfit build changed since the run began: "
            "run bench fit again",
            directory, o.dataset));
    std::size_t missing = 0;
    const std::vector<FitRow> rows = savedRows(dir, o, samples, run, missing);
    if (missing > 0)
        throw Error(
            fmt::format("--merge '{}': {} of {} fits are not done: run the missing "
                        "shards again (finished fits are kept)",
                        directory, missing, rows.size() + missing));
    writeBenchFitReport(rows, o, samples.size(), false);
}

}  // namespace phongfit
