#include "bench_fit.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>

#include "atomic_file.h"
#include "error.h"
#include "image.h"
#include "interrupt.h"
#include "machine_info.h"
#include "plot.h"
#include "scene_fit.h"
#include "synth_dataset.h"

namespace phongfit {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

// Relative errors: of a colour, the RGB distance over the true colour's length.
// Relative, or absolute where the truth is 0 (no lobe).
double colourError(const Color3& x, const Color3& truth) {
    const double norm = truth.matrix().norm();
    return (x - truth).matrix().norm() / (norm > 0 ? norm : 1.0);
}
double exponentError(double n, double truth) {
    return std::abs(n - truth) / std::max(truth, 1e-12);
}

struct Errors {
    double kd = 0, ks = 0, n = 0;
};

Errors errorsOf(const MaterialFit& m, const PhongMaterial& truth) {
    return {colourError(m.kd, truth.kd), colourError(m.ks, truth.ks), exponentError(m.n, truth.n)};
}

// The reported standard errors relative to the truth, as errorsOf measures the errors: what the
// fit says its error is, to set beside what it is.
Errors relativeStdOf(const MaterialFit& m, const PhongMaterial& truth) {
    const auto relative = [](const Color3& sd, const Color3& t) {
        const double norm = t.matrix().norm();
        return sd.matrix().norm() / (norm > 0 ? norm : 1.0);
    };
    return {relative(m.kdStd, truth.kd), relative(m.ksStd, truth.ks),
            m.nStd / std::max(truth.n, 1e-12)};
}

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
struct Verdict {
    bool withinTolerance = true, pass = true;
};

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

struct RoundPoint {
    double seconds = 0;  // cumulative, over the rounds so far
    Errors errors;
    Errors stds;  // reported standard errors, relative (relativeStdOf)
};

struct FitRow {
    const DatasetSample* sample = nullptr;
    int spp = 0;
    bool returned = false;  // false: the fit threw (see `error`)
    MaterialFit fit;
    int rounds = 0;
    bool converged = false;
    double seconds = 0;  // wall time of the whole fit command
    double rmse = 0;
    Errors errors;
    bool withinErrors = false;
    Verdict verdict{false, false};
    bool failed = false;
    std::string error;
    std::vector<RoundPoint> history;
};

// A start colour as given on the command line: one number when grey.
std::string startText(const Color3& c) {
    return c[0] == c[1] && c[1] == c[2] ? fmt::format("{:g}", c[0])
                                        : fmt::format("{:g},{:g},{:g}", c[0], c[1], c[2]);
}

double startExponent(const BenchFitOptions& o, double truth) {
    if (!(o.startNFactor > 0)) return o.startN;
    return truth * o.startNFactor <= kMaxStartN ? truth * o.startNFactor : truth / o.startNFactor;
}

bool finite(const MaterialFit& m) {
    return m.kd.allFinite() && m.ks.allFinite() && std::isfinite(m.n);
}

FitRow fitSample(const DatasetSample& s, int spp, const BenchFitOptions& o, const fs::path& dir) {
    FitRow row;
    row.sample = &s;
    row.spp = spp;
    SceneFitInputs in;
    in.views = {{s.scenePath, s.imagePath}};
    in.materials = {s.material};
    in.kd = o.startKd;
    in.ks = o.startKs;
    in.n = startExponent(o, s.truth.n);
    const SceneRecording recording{spp, 0, 0, o.threads, o.adaptiveSpp};
    FitOptions options;
    options.maxRounds = o.rounds;
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
        const fs::path out = dir / "fits" / fmt::format("spp{}", spp) / s.name;
        fs::create_directories(out.parent_path());
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
        if (!finite(row.fit)) {
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

std::string csvField(const std::string& s) {
    if (s.find_first_of(",\"\n") == std::string::npos) return s;
    std::string quoted = "\"";
    for (const char c : s) quoted += c == '"' ? std::string("\"\"") : std::string(1, c);
    return quoted + "\"";
}

void writeText(const fs::path& path, const std::string& text) {
    writeAtomically(path, [&](const fs::path& tmp) {
        std::ofstream out(tmp);
        out << text;
        if (!out) throw Error(fmt::format("cannot write '{}'", tmp.string()));
    });
}

std::string recoveryCsv(const std::vector<FitRow>& rows) {
    std::string csv =
        "sample,group,spp_per_round,kd_r_true,kd_g_true,kd_b_true,ks_r_true,ks_g_true,ks_b_true,"
        "n_true,kd_r,kd_g,kd_b,ks_r,ks_g,ks_b,n,kd_r_std,kd_g_std,kd_b_std,ks_r_std,ks_g_std,"
        "ks_b_std,n_std,kd_rel_err,ks_rel_err,n_rel_err,rounds,converged,time_s,rmse,"
        "unconstrained,within_3_std,failed,error,within_tolerance,pass\n";
    auto colour = [](const Color3& c) {
        return fmt::format("{:.6g},{:.6g},{:.6g}", c[0], c[1], c[2]);
    };
    for (const FitRow& r : rows) {
        const PhongMaterial& t = r.sample->truth;
        const MaterialFit& m = r.fit;
        csv += fmt::format("{},{},{},{},{},{:.6g},", r.sample->name, r.sample->group, r.spp,
                           colour(t.kd), colour(t.ks), t.n);
        if (r.returned)
            csv += fmt::format(
                "{},{},{:.6g},{},{},{:.3g},{:.6g},{:.6g},{:.6g},{},{},{:.4g},{:.6g},", colour(m.kd),
                colour(m.ks), m.n, colour(m.kdStd), colour(m.ksStd), m.nStd, r.errors.kd,
                r.errors.ks, r.errors.n, r.rounds, int(r.converged), r.seconds, r.rmse);
        else
            csv += fmt::format(",,,,,,,,,,,,,,,,,,{:.4g},,", r.seconds);
        csv += fmt::format("{},{},{},{},{},{}\n",
                           csvField(fmt::format("{}", fmt::join(m.unconstrained, ";"))),
                           int(r.withinErrors), int(r.failed), csvField(r.error),
                           int(r.verdict.withinTolerance), int(r.verdict.pass));
    }
    return csv;
}

std::string roundsCsv(const std::vector<FitRow>& rows) {
    std::string csv =
        "sample,group,spp_per_round,round,time_s,kd_rel_err,ks_rel_err,n_rel_err,kd_rel_std,"
        "ks_rel_std,n_rel_std\n";
    for (const FitRow& r : rows)
        for (std::size_t k = 0; k < r.history.size(); ++k) {
            const RoundPoint& p = r.history[k];
            csv +=
                fmt::format("{},{},{},{},{:.4g},{:.6g},{:.6g},{:.6g},{:.6g},{:.6g},{:.6g}\n",
                            r.sample->name, r.sample->group, r.spp, k + 1, p.seconds, p.errors.kd,
                            p.errors.ks, p.errors.n, p.stds.kd, p.stds.ks, p.stds.n);
        }
    return csv;
}

// Linear interpolation between order statistics; NaN for no values.
double quantile(std::vector<double> v, double q) {
    if (v.empty()) return std::nan("");
    std::sort(v.begin(), v.end());
    const double at = q * double(v.size() - 1);
    const std::size_t i = std::size_t(at);
    return i + 1 < v.size() ? v[i] + (at - double(i)) * (v[i + 1] - v[i]) : v[i];
}

struct SummaryRow {
    int spp = 0;
    std::string group;
    int fits = 0, failed = 0, threw = 0, notConverged = 0, unconstrained = 0, withinErrors = 0;
    int withinTolerance = 0, passed = 0;
    double kdMedian = 0, kdP95 = 0, ksMedian = 0, ksP95 = 0, nMedian = 0, nP95 = 0;
    double medianSeconds = 0, totalSeconds = 0, medianRounds = 0;
};

SummaryRow summarize(int spp, const std::string& group, const std::vector<const FitRow*>& rows) {
    SummaryRow s;
    s.spp = spp;
    s.group = group;
    std::vector<double> kd, ks, n, seconds, rounds;
    for (const FitRow* r : rows) {
        ++s.fits;
        s.failed += r->failed;
        s.threw += !r->returned;
        s.totalSeconds += r->seconds;
        seconds.push_back(r->seconds);
        if (!r->returned || !finite(r->fit)) continue;
        s.notConverged += !r->converged;
        s.unconstrained += !r->fit.unconstrained.empty();
        s.withinErrors += r->withinErrors;
        s.withinTolerance += r->verdict.withinTolerance;
        s.passed += r->verdict.pass;
        kd.push_back(r->errors.kd);
        ks.push_back(r->errors.ks);
        n.push_back(r->errors.n);
        rounds.push_back(r->rounds);
    }
    s.kdMedian = quantile(kd, 0.5);
    s.kdP95 = quantile(kd, 0.95);
    s.ksMedian = quantile(ks, 0.5);
    s.ksP95 = quantile(ks, 0.95);
    s.nMedian = quantile(n, 0.5);
    s.nP95 = quantile(n, 0.95);
    s.medianSeconds = quantile(seconds, 0.5);
    s.medianRounds = quantile(rounds, 0.5);
    return s;
}

std::vector<SummaryRow> summaries(const std::vector<FitRow>& rows, const std::vector<int>& spps) {
    std::vector<std::string> groups;
    for (const FitRow& r : rows)
        if (std::find(groups.begin(), groups.end(), r.sample->group) == groups.end())
            groups.push_back(r.sample->group);
    std::vector<SummaryRow> out;
    for (const int spp : spps) {
        std::vector<const FitRow*> all;
        for (const FitRow& r : rows)
            if (r.spp == spp) all.push_back(&r);
        if (all.empty()) continue;
        for (const std::string& g : groups) {
            std::vector<const FitRow*> mine;
            for (const FitRow* r : all)
                if (r->sample->group == g) mine.push_back(r);
            if (!mine.empty()) out.push_back(summarize(spp, g, mine));
        }
        if (groups.size() > 1) out.push_back(summarize(spp, "all", all));
    }
    return out;
}

std::string percent(double v) { return std::isnan(v) ? "-" : fmt::format("{:.3g}%", 100 * v); }

std::string markdownTable(const std::vector<SummaryRow>& rows) {
    std::string md =
        "| spp/round | group | fits | failed | not converged | unconstrained | within 3 std | "
        "within tolerance | pass | kd median | kd p95 | ks median | ks p95 | n median | n p95 | "
        "rounds (median) | time median [s] | time total [s] |\n"
        "|---:|:---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:"
        "|\n";
    for (const SummaryRow& s : rows)
        md += fmt::format(
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | "
            "{:.2f} | {:.1f} |\n",
            s.spp, s.group, s.fits, s.failed, s.notConverged, s.unconstrained, s.withinErrors,
            s.withinTolerance, s.passed, percent(s.kdMedian), percent(s.kdP95), percent(s.ksMedian),
            percent(s.ksP95), percent(s.nMedian), percent(s.nP95),
            std::isnan(s.medianRounds) ? "-" : fmt::format("{:g}", s.medianRounds), s.medianSeconds,
            s.totalSeconds);
    return md;
}

std::string cellText(const FitRow& r) {
    if (!r.returned) return "FAIL (threw)";
    const Errors sd = relativeStdOf(r.fit, r.sample->truth);
    const auto part = [&](const char* name, double error, double std) {
        return r.fit.isUnconstrained(name)
                   ? fmt::format("{} free", name)
                   : fmt::format("{} {}±{}", name, percent(error), percent(std));
    };
    const char* mark = r.verdict.withinTolerance && r.verdict.pass ? "ok"
                       : r.verdict.pass                            ? "ok (std)"
                                                                   : "FAIL";
    // No lobe in the truth: ks's error is its value, absolute.
    const std::string ks =
        (r.sample->truth.ks == 0).all() && !r.fit.isUnconstrained("ks")
            ? fmt::format("ks {:.2g}±{:.2g}", r.fit.ks.maxCoeff(), r.fit.ksStd.maxCoeff())
            : part("ks", r.errors.ks, sd.ks);
    return fmt::format("{}: {}, {}, {}; {:.1f} s", mark, part("kd", r.errors.kd, sd.kd), ks,
                       part("n", r.errors.n, sd.n), r.seconds);
}

// Per group whose samples form a full grid (every material with every exponent, once): a row per
// material and a column per exponent, each cell its verdict, errors +- reported standard errors
// (relative) and time. Empty when no group is a grid.
std::string matrixTables(const std::vector<FitRow>& rows, int spp) {
    std::vector<std::string> groups;
    for (const FitRow& r : rows)
        if (r.spp == spp &&
            std::find(groups.begin(), groups.end(), r.sample->group) == groups.end())
            groups.push_back(r.sample->group);
    std::string md;
    for (const std::string& g : groups) {
        std::vector<std::string> materials;
        std::vector<double> exponents;
        std::map<std::pair<std::string, double>, const FitRow*> cells;
        bool grid = true;
        for (const FitRow& r : rows) {
            if (r.spp != spp || r.sample->group != g) continue;
            const PhongMaterial& t = r.sample->truth;
            const std::string material =
                fmt::format("kd {}, ks {}", startText(t.kd), startText(t.ks));
            if (std::find(materials.begin(), materials.end(), material) == materials.end())
                materials.push_back(material);
            if (std::find(exponents.begin(), exponents.end(), t.n) == exponents.end())
                exponents.push_back(t.n);
            grid = grid && cells.emplace(std::make_pair(material, t.n), &r).second;
        }
        if (!grid || cells.size() != materials.size() * exponents.size() || exponents.size() < 2)
            continue;
        std::sort(exponents.begin(), exponents.end());
        md += fmt::format("\n### {} ({} spp/round)\n\n| material |", g, spp);
        for (const double n : exponents) md += fmt::format(" n {:g} |", n);
        md += "\n|:---|";
        for (std::size_t i = 0; i < exponents.size(); ++i) md += ":---|";
        md += "\n";
        for (const std::string& m : materials) {
            md += fmt::format("| {} |", m);
            for (const double n : exponents)
                md += fmt::format(" {} |", cellText(*cells.at({m, n})));
            md += "\n";
        }
    }
    return md;
}

json toJson(const SummaryRow& s) {
    auto number = [](double v) { return std::isnan(v) ? json(nullptr) : json(v); };
    return {{"spp_per_round", s.spp},
            {"group", s.group},
            {"fits", s.fits},
            {"failed", s.failed},
            {"threw", s.threw},
            {"not_converged", s.notConverged},
            {"unconstrained", s.unconstrained},
            {"within_3_std", s.withinErrors},
            {"within_tolerance", s.withinTolerance},
            {"pass", s.passed},
            {"kd_rel_err", {{"median", number(s.kdMedian)}, {"p95", number(s.kdP95)}}},
            {"ks_rel_err", {{"median", number(s.ksMedian)}, {"p95", number(s.ksP95)}}},
            {"n_rel_err", {{"median", number(s.nMedian)}, {"p95", number(s.nP95)}}},
            {"rounds_median", number(s.medianRounds)},
            {"time_s_median", s.medianSeconds},
            {"time_s_total", s.totalSeconds}};
}

// Recovered against true, one colour per spp per round.
cv::Mat recoveryPlot(const std::vector<FitRow>& rows, const std::vector<int>& spps) {
    PlotPanel kd{"kd", {"true kd", false}, {"recovered kd", false}, {}, true};
    PlotPanel ks{"ks", {"true ks", false}, {"recovered ks", false}, {}, true};
    PlotPanel n{"n", {"true n", true}, {"recovered n", true}, {}, true};
    double ksMin = 1e300, ksMax = 0;
    for (std::size_t i = 0; i < spps.size(); ++i) {
        const std::string label = fmt::format("{} spp/round", spps[i]);
        PlotSeries a{label, plotColor(int(i)), false, false, true, {}}, b = a, c = a;
        for (const FitRow& r : rows) {
            if (r.spp != spps[i] || !r.returned) continue;
            const PhongMaterial& t = r.sample->truth;
            for (int ch = 0; ch < (r.sample->grey ? 1 : 3); ++ch) {
                a.points.emplace_back(t.kd[ch], r.fit.kd[ch]);
                b.points.emplace_back(t.ks[ch], r.fit.ks[ch]);
                ksMin = std::min(ksMin, t.ks[ch]);
                ksMax = std::max(ksMax, t.ks[ch]);
            }
            c.points.emplace_back(t.n, r.fit.n);
        }
        kd.series.push_back(a);
        ks.series.push_back(b);
        n.series.push_back(c);
    }
    // Small specular reflectances (the stiff cases) only separate on a log axis.
    if (ksMin > 0 && ksMax / ksMin > 20) ks.x.log = ks.y.log = true;
    return drawFigure("recovered against true parameters", {kd, ks, n}, 440, 420);
}

// The median error after each round (solid) and the median reported standard error (dashed)
// against the median time spent up to it; a fit that stopped earlier keeps its last estimate and
// time.
cv::Mat errorVsTimePlot(const std::vector<FitRow>& rows, const std::vector<int>& spps) {
    const std::string x = "fit time [s]";
    PlotPanel kd{"kd", {x, true}, {"median relative error (dashed: std)", true}, {}, false};
    PlotPanel ks{"ks", {x, true}, {"median relative error (dashed: std)", true}, {}, false};
    PlotPanel n{"n", {x, true}, {"median relative error (dashed: std)", true}, {}, false};
    PlotPanel* panels[3] = {&kd, &ks, &n};
    const auto component = [](const Errors& e, int k) {
        return k == 0 ? e.kd : k == 1 ? e.ks : e.n;
    };
    std::size_t maxRounds = 0;
    for (const FitRow& r : rows) maxRounds = std::max(maxRounds, r.history.size());
    for (std::size_t i = 0; i < spps.size(); ++i) {
        const PlotSeries line{
            fmt::format("{} spp/round", spps[i]), plotColor(int(i)), false, true, true, {}};
        std::array<PlotSeries, 3> errors = {line, line, line};
        PlotSeries dashed = line;
        dashed.label = fmt::format("{} spp/round: reported std", spps[i]);
        dashed.dashed = true;
        std::array<PlotSeries, 3> stds = {dashed, dashed, dashed};
        for (std::size_t k = 0; k < maxRounds; ++k) {
            std::vector<double> t;
            std::array<std::vector<double>, 3> e, sd;
            for (const FitRow& r : rows) {
                if (r.spp != spps[i] || r.history.empty()) continue;
                const RoundPoint& p = r.history[std::min(k, r.history.size() - 1)];
                t.push_back(p.seconds);
                for (int c = 0; c < 3; ++c) {
                    e[c].push_back(component(p.errors, c));
                    sd[c].push_back(component(p.stds, c));
                }
            }
            if (t.empty()) continue;
            const double time = quantile(t, 0.5);
            for (int c = 0; c < 3; ++c) {
                errors[c].points.emplace_back(time, std::max(quantile(e[c], 0.5), 1e-6));
                stds[c].points.emplace_back(time, std::max(quantile(sd[c], 0.5), 1e-6));
            }
        }
        for (int c = 0; c < 3; ++c) {
            panels[c]->series.push_back(errors[c]);
            panels[c]->series.push_back(stds[c]);
        }
    }
    return drawFigure(
        "parameter error and reported standard error against fit time (one point "
        "per round)",
        {kd, ks, n}, 440, 400);
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

    std::vector<FitRow> rows;
    const std::size_t total = samples.size() * o.sppPerRound.size();
    for (const int spp : o.sppPerRound)
        for (const DatasetSample& s : samples) {
            if (interruptRequested()) break;
            FitRow row = fitSample(s, spp, o, dir);
            if (interruptRequested()) break;  // stopped mid-way: not a measurement
            rows.push_back(std::move(row));
            const FitRow& r = rows.back();
            if (!o.quiet)
                fmt::print(stderr, "[{}/{}] {} at {} spp/round: {}\n", rows.size(), total, s.name,
                           spp,
                           r.returned ? fmt::format("kd {}, ks {}, n {} off; {} rounds, {:.2f} s{}",
                                                    percent(r.errors.kd), percent(r.errors.ks),
                                                    percent(r.errors.n), r.rounds, r.seconds,
                                                    r.failed ? " (failed)" : "")
                                      : "failed: " + r.error);
        }

    writeText(dir / "recovery.csv", recoveryCsv(rows));
    writeText(dir / "rounds.csv", roundsCsv(rows));
    writePng(recoveryPlot(rows, o.sppPerRound), (dir / "recovered_vs_true.png").string());
    writePng(errorVsTimePlot(rows, o.sppPerRound), (dir / "error_vs_time_fit.png").string());

    const json machine = machineInfo(o.threads);
    const json run = {
        {"command", "bench fit"},
        {"dataset", o.dataset},
        {"samples", samples.size()},
        {"spp_per_round", o.sppPerRound},
        {"start",
         {{"kd", startText(o.startKd)},
          {"ks", startText(o.startKs)},
          {"n", o.startN},
          {"n_factor", o.startNFactor}}},
        {"tolerance",
         {{"kd_ks", o.kdKsTolerance}, {"floor", o.toleranceFloor}, {"n", o.nTolerance}}},
        {"max_rounds", o.rounds},
        {"fail_threshold", o.failThreshold},
        {"interrupted", interruptRequested()}};
    json info = machine;
    info["run"] = run;
    writeText(dir / "machine.json", info.dump(2) + "\n");

    const std::vector<SummaryRow> table = summaries(rows, o.sppPerRound);
    json summary = {{"machine", machine}, {"run", run}, {"rows", json::array()}};
    for (const SummaryRow& s : table) summary["rows"].push_back(toJson(s));
    writeText(dir / "summary.json", summary.dump(2) + "\n");
    const std::string definitions = fmt::format(
        "Relative errors: |x - x_true| / |x_true|, for kd and ks with |.| the RGB length "
        "(absolute where the truth is 0). A fit fails when it throws, returns a non-finite value, "
        "or the error of a parameter it did not hold exceeds {:g}; "
        "\"unconstrained\" counts fits that reported a parameter the image does not constrain; "
        "\"within 3 std\" those whose every parameter not held is within 3 of its reported "
        "standard errors of the truth; \"within tolerance\" those whose every parameter not "
        "held is within {:g}% (kd, ks per channel, or {:g} absolute) and {:g}% (n) of the truth; "
        "\"pass\" those within 3 std whose every parameter out of tolerance has a standard error "
        "of at least half the tolerance. Start for every sample: kd {}, ks {}, n {}; at most {} "
        "rounds.",
        o.failThreshold, 100 * o.kdKsTolerance, o.toleranceFloor, 100 * o.nTolerance,
        startText(o.startKd), startText(o.startKs),
        o.startNFactor > 0 ? fmt::format("{:g} times off the truth", o.startNFactor)
                           : fmt::format("{:g}", o.startN),
        o.rounds);
    std::string md = markdownTable(table);
    for (const int spp : o.sppPerRound) md += matrixTables(rows, spp);
    writeText(
        dir / "summary.md",
        fmt::format("# bench fit: {}\n\n{}\n\n{}\nMachine: {}, {} cores ({} threads), {} "
                    "build, {}, commit {}.\n",
                    o.dataset, definitions, md, machine["cpu"].get<std::string>(),
                    machine["cores"].get<int>(), machine["threads_used"].get<int>(),
                    machine["build_type"].get<std::string>(),
                    machine["compiler"].get<std::string>(), machine["commit"].get<std::string>()));
    fmt::print("\n{}\n{}", definitions, md);
    fmt::print("-> {}\n", (dir / "summary.md").string());
    if (interruptRequested())
        fmt::print("interrupted: the tables hold the {} fits done so far\n", rows.size());
}

}  // namespace phongfit
