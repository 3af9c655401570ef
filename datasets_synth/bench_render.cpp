#include "bench_render.h"

#include <fmt/format.h>

#include <filesystem>
#include <fstream>

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
    int colour = 0;
};

std::vector<Strategy> strategies() {
    std::vector<Strategy> out;
    const std::vector<std::string>& names = phongSamplerNames();
    for (std::size_t i = 0; i < names.size(); ++i) {
        out.push_back({names[i] + "+mis", names[i], true, int(i)});
        out.push_back({names[i], names[i], false, int(i)});
    }
    return out;
}

void writeCsv(const fs::path& path, const std::vector<BenchRenderRow>& rows) {
    writeAtomically(path, [&](const fs::path& tmp) {
        std::ofstream out(tmp);
        out << "strategy,spp,time_s,rmse,relmse\n";
        for (const BenchRenderRow& r : rows)
            out << fmt::format("{},{},{:.6g},{:.6g},{:.6g}\n", r.strategy, r.spp, r.seconds,
                               r.error.rmse, r.error.relmse);
        if (!out) throw Error(fmt::format("cannot write '{}'", tmp.string()));
    });
}

cv::Mat plot(const std::string& sceneName, const std::vector<BenchRenderRow>& rows) {
    PlotPanel rmse{"RMSE", {"wall time [s]", true}, {"RMSE", true}, {}, false};
    PlotPanel relmse{"relative MSE", {"wall time [s]", true}, {"relMSE", true}, {}, false};
    for (const Strategy& s : strategies()) {
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
            fmt::print("reference: lafortune+mis, {} spp, {:.2f} s -> {}\n", options.referenceSpp,
                       r.stats.seconds, (dir / "reference.exr").string());
        render.quiet = true;
    }

    std::vector<BenchRenderRow> rows;
    render.seed = options.seed;
    for (const Strategy& s : strategies()) {
        render.sampler = s.sampler;
        render.mis = s.mis;
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
            fmt::print(stderr, "{:<15} up to {:>6} spp in {:.2f} s\n", s.name, rows.back().spp,
                       spent);
    }

    writeCsv(dir / "error_vs_time.csv", rows);
    writePng(plot(fs::path(options.scene).filename().string(), rows),
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
                   {"rmse", "sqrt(mean((x - ref)^2)) over pixels and RGB channels"},
                   {"relmse", fmt::format("mean((x - ref)^2 / (ref^2 + {})) over pixels and RGB "
                                          "channels",
                                          kRelMseEpsilon)},
                   {"interrupted", interruptRequested()}};
    writeAtomically(dir / "machine.json",
                    [&](const fs::path& tmp) { std::ofstream(tmp) << info.dump(2) << "\n"; });

    // Each strategy's last point, and its MSE times time: the lower, the less time it needs for
    // a given error (MSE falls as 1 / time for an unbiased estimator).
    fmt::print("{:<15} {:>7} {:>9} {:>11} {:>11} {:>12}\n", "strategy", "spp", "time_s", "rmse",
               "relmse", "relmse*time");
    for (const Strategy& s : strategies()) {
        const BenchRenderRow* last = nullptr;
        for (const BenchRenderRow& r : rows)
            if (r.strategy == s.name) last = &r;
        if (last)
            fmt::print("{:<15} {:>7} {:>9.3f} {:>11.4g} {:>11.4g} {:>12.4g}\n", last->strategy,
                       last->spp, last->seconds, last->error.rmse, last->error.relmse,
                       last->error.relmse * last->seconds);
    }
    fmt::print("-> {}, {}\n", (dir / "error_vs_time.csv").string(),
               (dir / "error_vs_time.png").string());
    if (interruptRequested()) fmt::print("interrupted: the CSV holds the renders done so far\n");
    return rows;
}

}  // namespace phongfit
