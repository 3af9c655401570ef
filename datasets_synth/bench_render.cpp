#include "bench_render.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>

#include "atomic_file.h"
#include "defines.h"
#include "error.h"
#include "image.h"
#include "interrupt.h"
#include "machine_info.h"
#include "phong_sampler.h"
#include "plot.h"
#include "renderer.h"
#include "scene_parser.h"

namespace phongfit {
namespace {

namespace fs = std::filesystem;

struct Strategy {
    std::string name, sampler;
    bool mis = true;
    PixelSamplerType pixelSampler = PixelSamplerType::Independent;
    int colour = 0;
};

// Every Phong sampler with and without MIS, on independent samples (named as before the Sobol
// samplers existed), on Sobol points ("sobol/" first) and on padded Sobol points ("ldsampler/");
// `selected` (names) keeps a subset.
std::vector<Strategy> strategies(const std::vector<std::string>& selected) {
    std::vector<Strategy> all;
    const std::vector<std::string>& names = phongSamplerNames();
    int colour = 0;
    for (const PixelSamplerType pixel :
         {PixelSamplerType::Independent, PixelSamplerType::Sobol, PixelSamplerType::Padded})
        for (std::size_t i = 0; i < names.size(); ++i, ++colour) {
            const std::string prefix =
                pixel == PixelSamplerType::Independent ? "" : pixelSamplerName(pixel) + "/";
            all.push_back({prefix + names[i] + "+mis", names[i], true, pixel, colour});
            all.push_back({prefix + names[i], names[i], false, pixel, colour});
        }
    if (selected.empty()) return all;
    std::vector<Strategy> out;
    for (const std::string& name : selected) {
        const auto it =
            std::find_if(all.begin(), all.end(), [&](const Strategy& s) { return s.name == name; });
        if (it == all.end()) {
            std::string allowed;
            for (const Strategy& s : all) allowed += (allowed.empty() ? "" : ", ") + s.name;
            throw Error(
                fmt::format("--strategies: unknown strategy '{}' (allowed: {})", name, allowed));
        }
        out.push_back(*it);
    }
    return out;
}

// Efficiency 1 / (relMSE x seconds) of `row` relative to the baseline's render at the same spp,
// or NaN when the baseline has none.
double relativeEfficiency(const BenchRenderRow& row, const std::vector<BenchRenderRow>& rows,
                          const std::string& baseline) {
    for (const BenchRenderRow& b : rows)
        if (b.strategy == baseline && b.spp == row.spp)
            return (b.error.relmse * b.seconds) / (row.error.relmse * row.seconds);
    return std::numeric_limits<double>::quiet_NaN();
}

void writeCsv(const fs::path& path, const std::vector<BenchRenderRow>& rows,
              const std::string& baseline) {
    writeAtomically(path, [&](const fs::path& tmp) {
        std::ofstream out(tmp);
        out << "strategy,spp,time_s,rmse,relmse,efficiency_vs_baseline\n";
        for (const BenchRenderRow& r : rows)
            out << fmt::format("{},{},{:.6g},{:.6g},{:.6g},{:.6g}\n", r.strategy, r.spp, r.seconds,
                               r.error.rmse, r.error.relmse, relativeEfficiency(r, rows, baseline));
        if (!out) throw Error(fmt::format("cannot write '{}'", tmp.string()));
    });
}

cv::Mat plot(const std::string& sceneName, const std::vector<Strategy>& chosen,
             const std::vector<BenchRenderRow>& rows) {
    PlotPanel rmse{"RMSE", {"wall time [s]", true}, {"RMSE", true}, {}, false};
    PlotPanel relmse{"relative MSE", {"wall time [s]", true}, {"relMSE", true}, {}, false};
    for (const Strategy& s : chosen) {
        PlotSeries a{s.name, plotColor(s.colour), !s.mis, true, true, {}};
        PlotSeries b = a;
        for (const BenchRenderRow& r : rows)
            if (r.strategy == s.name) {
                a.points.emplace_back(r.seconds, r.error.rmse);
                b.points.emplace_back(r.seconds, r.error.relmse);
            }
        if (a.points.empty()) continue;
        rmse.series.push_back(a);
        relmse.series.push_back(b);
    }
    return drawFigure(
        fmt::format("{}: error against render time (solid: MIS, dashed: no MIS)", sceneName),
        {rmse, relmse});
}

}  // namespace

std::vector<BenchRenderRow> runBenchRender(const BenchRenderOptions& options) {
    if (!(options.budget > 0))
        throw Error(fmt::format("--budget {}: must be > 0 seconds", options.budget));
    std::vector<Strategy> chosen = strategies(options.strategies);
    const Strategy baseline = strategies({options.baseline}).front();
    if (std::none_of(chosen.begin(), chosen.end(),
                     [&](const Strategy& s) { return s.name == baseline.name; }))
        chosen.insert(chosen.begin(), baseline);

    requireOutputDirectory(options.output);
    const fs::path dir(options.output);
    const Renderer renderer(loadScene(options.scene, parseDefines(options.defines)));
    const int width = renderer.scene().sensor.width, height = renderer.scene().sensor.height;
    Image reference;
    if (!options.reference.empty()) {
        reference = readImage(options.reference);
        if (reference.width != width || reference.height != height)
            throw Error(fmt::format("--reference '{}': is {}x{} but the film of {} is {}x{}",
                                    options.reference, reference.width, reference.height,
                                    options.scene, width, height));
    }
    fs::create_directories(dir);

    RenderOptions render;
    render.threads = options.threads;
    render.quiet = true;
    if (options.reference.empty()) {
        render.spp = options.referenceSpp;
        render.seed = options.seed + 1;  // independent of the measured renders
        render.quiet = options.quiet;
        const RenderResult r = renderer.render(render);
        if (r.stats.interrupted) throw Error("interrupted while rendering the reference");
        reference = Image(width, height);
        reference.rgb = r.rgb;
        writeExr(reference, (dir / "reference.exr").string());
        if (!options.quiet)
            fmt::print(
                "reference: the defaults ({}+mis on the scene's pixel sampler), {} spp, "
                "{:.2f} s -> {}\n",
                render.sampler, options.referenceSpp, r.stats.seconds,
                (dir / "reference.exr").string());
        render.quiet = true;
    }

    std::vector<BenchRenderRow> rows;
    render.seed = options.seed;
    for (const Strategy& s : chosen) {
        render.sampler = s.sampler;
        render.mis = s.mis;
        render.pixelSampler = s.pixelSampler;
        double spent = 0;
        for (int spp = 1; spp <= options.sppMax && !interruptRequested(); spp *= 2) {
            render.spp = spp;
            const RenderResult r = renderer.render(render);
            if (r.stats.interrupted) break;
            rows.push_back({s.name, spp, r.stats.seconds, imageError(r.rgb, reference.rgb)});
            spent += r.stats.seconds;
            // The next render takes about twice as long: stop if it would overrun the budget.
            if (spent + 2 * r.stats.seconds > options.budget || spp > options.sppMax / 2) break;
        }
        if (!options.quiet && !rows.empty() && rows.back().strategy == s.name)
            fmt::print(stderr, "{:<21} up to {:>6} spp in {:.2f} s\n", s.name, rows.back().spp,
                       spent);
    }

    writeCsv(dir / "error_vs_time.csv", rows, baseline.name);
    writePng(plot(fs::path(options.scene).filename().string(), chosen, rows),
             (dir / "error_vs_time.png").string());
    nlohmann::json info = machineInfo(options.threads);
    info["run"] = {{"command", "bench render"},
                   {"scene", options.scene},
                   {"defines", parseDefines(options.defines)},
                   {"width", width},
                   {"height", height},
                   {"reference", options.reference.empty() ? "reference.exr" : options.reference},
                   {"reference_spp", options.reference.empty() ? options.referenceSpp : 0},
                   {"budget_s", options.budget},
                   {"spp_max", options.sppMax},
                   {"seed", options.seed},
                   {"strategies", options.strategies},
                   {"baseline", baseline.name},
                   {"efficiency", "1 / (relmse x time_s), relative to the baseline's at equal spp"},
                   {"rmse", "sqrt(mean((x - ref)^2)) over pixels and RGB channels"},
                   {"relmse", fmt::format("mean((x - ref)^2 / (ref^2 + {})) over pixels and RGB "
                                          "channels",
                                          kRelMseEpsilon)},
                   {"interrupted", interruptRequested()}};
    writeAtomically(dir / "machine.json",
                    [&](const fs::path& tmp) { std::ofstream(tmp) << info.dump(2) << "\n"; });

    // Each strategy's last point, its relMSE times time (the lower, the less time it needs for
    // a given error: MSE falls as 1 / time for an unbiased estimator), and its efficiency relative
    // to the baseline at equal spp, at each spp both reached from 4 up.
    std::vector<int> spps;
    for (const BenchRenderRow& r : rows)
        if (r.strategy == baseline.name && r.spp >= 4) spps.push_back(r.spp);
    std::string header = fmt::format("{:<21} {:>7} {:>9} {:>11} {:>11} {:>12}", "strategy", "spp",
                                     "time_s", "rmse", "relmse", "relmse*time");
    for (const int spp : spps) header += fmt::format(" {:>8}", fmt::format("eff@{}", spp));
    fmt::print("{}\n", header);
    for (const Strategy& s : chosen) {
        const BenchRenderRow* last = nullptr;
        for (const BenchRenderRow& r : rows)
            if (r.strategy == s.name) last = &r;
        if (!last) continue;
        std::string line = fmt::format("{:<21} {:>7} {:>9.3f} {:>11.4g} {:>11.4g} {:>12.4g}",
                                       last->strategy, last->spp, last->seconds, last->error.rmse,
                                       last->error.relmse, last->error.relmse * last->seconds);
        for (const int spp : spps) {
            double eff = std::numeric_limits<double>::quiet_NaN();
            for (const BenchRenderRow& r : rows)
                if (r.strategy == s.name && r.spp == spp)
                    eff = relativeEfficiency(r, rows, baseline.name);
            line += std::isnan(eff) ? fmt::format(" {:>8}", "-") : fmt::format(" {:>8.3g}", eff);
        }
        fmt::print("{}\n", line);
    }
    fmt::print("eff@N: efficiency 1 / (relMSE x time) at N spp relative to {} at N spp\n",
               baseline.name);
    fmt::print("-> {}, {}\n", (dir / "error_vs_time.csv").string(),
               (dir / "error_vs_time.png").string());
    if (interruptRequested()) fmt::print("interrupted: the CSV holds the renders done so far\n");
    return rows;
}

}  // namespace phongfit
