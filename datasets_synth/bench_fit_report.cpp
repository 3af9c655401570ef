#include "bench_fit_report.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>

#include "image.h"
#include "json_files.h"
#include "machine_info.h"
#include "plot.h"

namespace phongfit {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

// A start colour as given on the command line: one number when grey.
std::string startText(const Color3& c) {
    return c[0] == c[1] && c[1] == c[2] ? fmt::format("{:g}", c[0])
                                        : fmt::format("{:g},{:g},{:g}", c[0], c[1], c[2]);
}

// Whether the sample's truth has a specular lobe: n has a true value to err from only then.
bool hasLobe(const FitRow& r) { return (r.sample->truth.ks > 0).any(); }

std::string csvField(const std::string& s) {
    if (s.find_first_of(",\"\n") == std::string::npos) return s;
    std::string quoted = "\"";
    for (const char c : s) quoted += c == '"' ? std::string("\"\"") : std::string(1, c);
    return quoted + "\"";
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
        if (!r->returned || !isFinite(r->fit)) continue;
        s.notConverged += !r->converged;
        s.unconstrained += !r->fit.unconstrained.empty();
        s.withinErrors += r->withinErrors;
        s.withinTolerance += r->verdict.withinTolerance;
        s.passed += r->verdict.pass;
        kd.push_back(r->errors.kd);
        ks.push_back(r->errors.ks);
        if (hasLobe(*r)) n.push_back(r->errors.n);
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
            s.withinTolerance, s.passed, percentText(s.kdMedian), percentText(s.kdP95),
            percentText(s.ksMedian), percentText(s.ksP95), percentText(s.nMedian),
            percentText(s.nP95),
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
                   : fmt::format("{} {}±{}", name, percentText(error), percentText(std));
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
                    if (c == 2 && !hasLobe(r)) continue;
                    e[c].push_back(component(p.errors, c));
                    sd[c].push_back(component(p.stds, c));
                }
            }
            if (t.empty()) continue;
            const double time = quantile(t, 0.5);
            for (int c = 0; c < 3; ++c) {
                if (e[c].empty()) continue;
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

std::string percentText(double v) { return std::isnan(v) ? "-" : fmt::format("{:.3g}%", 100 * v); }

void writeBenchFitReport(const std::vector<FitRow>& rows, const BenchFitOptions& o,
                         std::size_t samples, bool interrupted) {
    const fs::path dir(o.output);
    writeTextAtomically(dir / "recovery.csv", recoveryCsv(rows));
    writeTextAtomically(dir / "rounds.csv", roundsCsv(rows));
    writePng(recoveryPlot(rows, o.sppPerRound), (dir / "recovered_vs_true.png").string());
    writePng(errorVsTimePlot(rows, o.sppPerRound), (dir / "error_vs_time_fit.png").string());

    const json machine = machineInfo(o.threads);
    const json run = {
        {"command", "bench fit"},
        {"dataset", o.dataset},
        {"samples", samples},
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
        {"interrupted", interrupted}};
    json info = machine;
    info["run"] = run;
    writeTextAtomically(dir / "machine.json", info.dump(2) + "\n");

    const std::vector<SummaryRow> table = summaries(rows, o.sppPerRound);
    json summary = {{"machine", machine}, {"run", run}, {"rows", json::array()}};
    for (const SummaryRow& s : table) summary["rows"].push_back(toJson(s));
    writeTextAtomically(dir / "summary.json", summary.dump(2) + "\n");
    const std::string definitions = fmt::format(
        "Relative errors: |x - x_true| / |x_true|, for kd and ks with |.| the RGB length "
        "(absolute where the truth is 0); n's over the fits whose truth has a lobe (ks > 0), the "
        "only ones where n has a true value. A fit fails when it throws, returns a non-finite "
        "value, or the error of a parameter it did not hold exceeds {:g}; "
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
    writeTextAtomically(
        dir / "summary.md",
        fmt::format("# bench fit: {}\n\n{}\n\n{}\nMachine: {}, {} cores ({} threads), {} "
                    "build, {}, commit {}.\n",
                    o.dataset, definitions, md, machine["cpu"].get<std::string>(),
                    machine["cores"].get<int>(), machine["threads_used"].get<int>(),
                    machine["build_type"].get<std::string>(),
                    machine["compiler"].get<std::string>(), machine["commit"].get<std::string>()));
    fmt::print("\n{}\n{}", definitions, md);
    fmt::print("-> {}\n", (dir / "summary.md").string());
    if (interrupted)
        fmt::print("interrupted: the tables hold the {} fits done so far\n", rows.size());
}

}  // namespace phongfit
