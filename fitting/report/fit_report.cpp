#include "fit_report.h"

#include <fmt/format.h>

#include <algorithm>
#include <fstream>

#include "atomic_file.h"
#include "color_json.h"
#include "error.h"
#include "memory_plan.h"

namespace phongfit {
namespace {

nlohmann::json materialsJson(const std::vector<MaterialFit>& materials,
                             const std::vector<std::string>& ids) {
    if (materials.size() != ids.size())
        throw Error(fmt::format("fit report: {} material ids given for {} fitted materials",
                                ids.size(), materials.size()));
    nlohmann::json out = nlohmann::json::object();
    for (std::size_t s = 0; s < materials.size(); ++s) {
        const MaterialFit& m = materials[s];
        out[ids[s]] = {{"kd", colorJson(m.kd)},
                       {"ks", colorJson(m.ks)},
                       {"n", m.n},
                       {"kd_std", colorJson(m.kdStd)},
                       {"ks_std", colorJson(m.ksStd)},
                       {"n_std", m.nStd},
                       {"log_n_std", m.logNStd},
                       {"image_noise_std",
                        {{"kd", colorJson(m.kdImageStd)},
                         {"ks", colorJson(m.ksImageStd)},
                         {"n", m.n * m.logNImageStd},
                         {"log_n_sharper", m.logNSharperImageStd}}},
                       {"unconstrained", m.unconstrained}};
    }
    return out;
}

nlohmann::json exposureJson(const ExposureFit& e) {
    return {{"value", e.value}, {"std", e.std}, {"unconstrained", e.unconstrained}};
}

// The fit's peak against what it holds: the process at the start, the program's code first run
// since (as the peak's round began: pages taken in later are counted against the fit), the
// recorded paths, and per used pixel the rest (at most kStateBytesPerPixel by design; it also
// counts anything else the process allocated meanwhile).
nlohmann::json memoryJson(const FitResult& result) {
    std::size_t peak = 0, recorded = 0, program = 0;
    for (const FitRound& r : result.rounds) {
        if (r.peakMemoryBytes > peak) program = r.programBytes;
        peak = std::max(peak, r.peakMemoryBytes);
        recorded = std::max(recorded, r.recordedBytes);
    }
    const double rest =
        double(peak) - double(result.residentAtStartBytes) - double(program) - double(recorded);
    return {{"peak_bytes", peak},
            {"resident_at_start_bytes", result.residentAtStartBytes},
            {"program_pages_bytes", program},
            {"most_recorded_bytes", recorded},
            {"rest_per_used_pixel_bytes",
             result.pixelsUsed > 0 ? std::max(rest, 0.0) / double(result.pixelsUsed) : 0.0},
            {"state_bound_per_used_pixel_bytes", kStateBytesPerPixel}};
}

}  // namespace

nlohmann::json toJson(const FitResult& result, const std::vector<std::string>& materialIds) {
    nlohmann::json rounds = nlohmann::json::array();
    for (const FitRound& r : result.rounds)
        rounds.push_back({{"round", r.round},
                          {"paths", r.paths},
                          {"path_factor", r.pathFactor},
                          {"pooled_rounds", r.pooledRounds},
                          {"probe", r.probe},
                          {"broad_stride", r.broadStride},
                          {"time_s", r.timeSeconds},
                          {"record_time_s", r.recordSeconds},
                          {"rmse", r.rmse},
                          {"iterations", r.iterations},
                          {"time_per_iteration_s", r.secondsPerIteration},
                          {"recorded_bytes", r.recordedBytes},
                          {"peak_memory_bytes", r.peakMemoryBytes},
                          {"materials", materialsJson(r.materials, materialIds)}});
    if (result.exposure)
        for (std::size_t k = 0; k < result.rounds.size(); ++k)
            rounds[k]["exposure"] = exposureJson(result.rounds[k].exposure);
    nlohmann::json out = {{"materials", materialsJson(result.materials, materialIds)},
                          {"rmse", result.rmse},
                          {"converged", result.converged},
                          {"interrupted", result.interrupted},
                          {"stop_reason", result.stopReason},
                          {"rounds", rounds},
                          {"time_s", result.timeSeconds},
                          {"pixels_used", result.pixelsUsed},
                          {"pixels_left_out", result.pixelsLeftOut}};
    if (result.exposure) out["exposure"] = exposureJson(*result.exposure);
    out["memory"] = memoryJson(result);
    return out;
}

void writeFitReport(const std::filesystem::path& path, const FitResult& result,
                    const std::vector<std::string>& materialIds) {
    const std::string text = toJson(result, materialIds).dump(2) + "\n";
    writeAtomically(path, [&](const std::filesystem::path& temporary) {
        std::ofstream out(temporary);
        out << text;
        out.close();
        if (!out) throw Error(fmt::format("{}: could not be written", temporary.string()));
    });
}

}  // namespace phongfit
