#include "render_sidecar.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <vector>

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

std::string filterWords(SensorDesc::Filter filter, double width) {
    const PixelFilterName& f = pixelFilterName(filter);
    if (f.width == nullptr) return "a box pixel filter";
    return fmt::format("a {} pixel filter ({} {:g} pixels)",
                       filter == SensorDesc::Filter::Gaussian ? "Gaussian" : f.type, f.width,
                       width);
}

std::string depthWords(int depth) {
    return depth < 0 ? "unbounded depth" : fmt::format("depth {}", depth);
}

// Depths that render the same image: equal, or both at least 2 where direct light is exact.
bool sameDepth(int a, int b, bool directExact) {
    const auto reach = [](int d) { return d < 0 ? std::numeric_limits<int>::max() : d; };
    return reach(a) == reach(b) || (directExact && reach(a) >= 2 && reach(b) >= 2);
}

}  // namespace

nlohmann::json pixelFilterJson(const PixelFilter& filter) {
    const PixelFilterName& f = pixelFilterName(filter.filter);
    nlohmann::json out = {{"type", f.type}};
    if (f.width != nullptr) out[f.width] = filter.width;
    return out;
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
        const auto known = std::find_if(std::begin(kPixelFilters), std::end(kPixelFilters),
                                        [&](const PixelFilterName& n) { return type == n.type; });
        const nlohmann::json width =
            known != std::end(kPixelFilters) && known->width != nullptr && f.contains(known->width)
                ? f[known->width]
                : nullptr;
        if (known == std::end(kPixelFilters) ||
            (known->width != nullptr &&
             !(width.is_number() && width.get<double>() > 0 && std::isfinite(width.get<double>()))))
            throw fail(
                fmt::format("pixel_filter {} (allowed: {{\"type\": \"box\"}}, "
                            "{{\"type\": \"gaussian\", \"stddev\": pixels > 0}} or "
                            "{{\"type\": \"tent\", \"radius\": pixels > 0}})",
                            shown(f)));
        const double w = known->width != nullptr ? width.get<double>() : 0.0;
        const double filmWidth = pixelFilterOf(film).width;  // 0: the box, whose sidecar names none
        if (known->filter != film.filter || std::abs(w - filmWidth) > 1e-6 * filmWidth)
            throw misstated(filterWords(known->filter, w),
                            filterWords(film.filter, filmWidth) +
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

bool filterAssumed(const SensorDesc& film, const RenderedAs& as) {
    return !film.filterNamed && !as.filterKnown;
}

nlohmann::json pixelFilterReport(const SensorDesc& film, const RenderedAs& as) {
    nlohmann::json report = pixelFilterJson(pixelFilterOf(film));
    report["from"] = as.filterKnown ? as.source : filterAssumed(film, as) ? "default" : "scene";
    return report;
}

}  // namespace phongfit
