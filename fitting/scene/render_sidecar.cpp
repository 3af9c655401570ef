#include "render_sidecar.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>

#include "error.h"
#include "phong_sampler.h"

namespace phongfit {
namespace {

namespace fs = std::filesystem;

constexpr unsigned long long kMaxDepth = 1 << 20;

// A JSON value as the error shows it, cut short.
std::string shown(const nlohmann::json& value) {
    const std::string text = value.dump();
    return text.size() <= 60 ? text : text.substr(0, 57) + "...";
}

std::string filterWords(SensorDesc::Filter filter, double stddev) {
    return filter == SensorDesc::Filter::Box
               ? "a box pixel filter"
               : fmt::format("a Gaussian pixel filter (stddev {:g} pixels)", stddev);
}

std::string depthWords(int depth) {
    return depth < 0 ? "unbounded depth" : fmt::format("depth {}", depth);
}

// Depths that render the same image: equal, or both at least 2 where direct light is exact.
bool sameDepth(int a, int b, bool directExact) {
    const auto reach = [](int d) { return d < 0 ? INT32_MAX : d; };
    return reach(a) == reach(b) || (directExact && reach(a) >= 2 && reach(b) >= 2);
}

}  // namespace

nlohmann::json pixelFilterJson(const SensorDesc& film) {
    if (film.filter == SensorDesc::Filter::Box) return {{"type", "box"}};
    return {{"type", "gaussian"}, {"stddev", film.gaussianStddev}};
}

RenderedAs readRenderedAs(const std::string& imagePath, const Scene& scene, int maxDepth,
                          bool directExact) {
    const SensorDesc& film = scene.sensor;
    RenderedAs as{film.sampleCount, film.pixelSampler, "mixture", true, "scene", false};
    const fs::path sidecar = imagePath + ".json";
    if (!fs::exists(sidecar)) return as;
    const nlohmann::json j = nlohmann::json::parse(std::ifstream(sidecar), nullptr, false);
    const auto fail = [&](const std::string& what) {
        return Error(
            fmt::format("{}: {} (the settings `phongfit render` writes beside an image: "
                        "spp, pixel_sampler, sampler, mis, pixel_filter, max_depth)",
                        sidecar.string(), what));
    };
    if (!j.is_object()) throw fail("not a JSON object");
    if (!j.contains("spp")) return as;
    if (!j["spp"].is_number_integer() || j["spp"].get<long long>() < 0 ||
        j["spp"].get<long long>() > (1 << 20))
        throw fail(
            fmt::format("spp {} is not a whole number in [0, {}]", j["spp"].dump(), 1 << 20));
    as.spp = j["spp"].get<int>();
    as.source = sidecar.string();
    // A name from `names`, where the sidecar has `key`.
    const auto named = [&](const char* key, const std::vector<std::string>& names,
                           std::string& out) {
        if (!j.contains(key)) return;
        if (!j[key].is_string() ||
            std::find(names.begin(), names.end(), j[key].get<std::string>()) == names.end())
            throw fail(
                fmt::format("{} {} (allowed: {})", key, j[key].dump(), fmt::join(names, ", ")));
        out = j[key].get<std::string>();
    };
    std::string pixelSampler = pixelSamplerName(as.pixelSampler);
    named("pixel_sampler", pixelSamplerNames(), pixelSampler);
    as.pixelSampler = pixelSamplerType(pixelSampler);
    named("sampler", phongSamplerNames(), as.sampler);
    if (j.contains("mis")) {
        if (!j["mis"].is_boolean()) throw fail("mis is not true or false");
        as.mis = j["mis"].get<bool>();
    }
    // The image was made otherwise than the scene says: fitted so, it gives a confident wrong lobe.
    const auto misstated = [&](const std::string& image, const std::string& sceneSays,
                               const char* allowed) {
        return Error(
            fmt::format("{}: the image was rendered with {} but {} says {}: fitted so, it "
                        "would give a confidently wrong lobe (allowed: {})",
                        sidecar.string(), image, scene.file, sceneSays, allowed));
    };
    if (j.contains("pixel_filter")) {
        const nlohmann::json& f = j["pixel_filter"];
        const nlohmann::json type = f.is_object() && f.contains("type") ? f["type"] : nullptr;
        const nlohmann::json stddev = f.is_object() && f.contains("stddev") ? f["stddev"] : nullptr;
        const bool box = type == "box";
        if (!box && !(type == "gaussian" && stddev.is_number() && stddev.get<double>() > 0 &&
                      std::isfinite(stddev.get<double>())))
            throw fail(
                fmt::format("pixel_filter {} (allowed: {{\"type\": \"box\"}} or "
                            "{{\"type\": \"gaussian\", \"stddev\": pixels > 0}})",
                            shown(f)));
        const auto filter = box ? SensorDesc::Filter::Box : SensorDesc::Filter::Gaussian;
        const double sigma = box ? 0.0 : stddev.get<double>();
        if (filter != film.filter ||
            (!box && std::abs(sigma - film.gaussianStddev) > 1e-6 * film.gaussianStddev))
            throw misstated(filterWords(filter, sigma),
                            filterWords(film.filter, film.gaussianStddev) +
                                (film.filterNamed ? "" : " (its film names no <rfilter>)"),
                            "the image's filter, named in the film's <rfilter>");
        as.filterKnown = true;
    }
    if (j.contains("max_depth")) {
        const nlohmann::json& d = j["max_depth"];
        const bool inRange = d.is_number_unsigned()
                                 ? d.get<unsigned long long>() <= kMaxDepth
                                 : d.is_number_integer() && d.get<long long>() >= -1;
        if (!inRange)
            throw fail(
                fmt::format("max_depth {} is not a whole number in [-1, {}]", shown(d), kMaxDepth));
        if (!sameDepth(d.get<int>(), maxDepth, directExact))
            throw misstated(depthWords(d.get<int>()), depthWords(maxDepth),
                            "the image's depth, named in the integrator's maxDepth");
    }
    return as;
}

nlohmann::json pixelFilterReport(const SensorDesc& film, const RenderedAs& as) {
    nlohmann::json report = pixelFilterJson(film);
    report["from"] = as.filterKnown ? as.source : film.filterNamed ? "scene" : "default";
    return report;
}

}  // namespace phongfit
