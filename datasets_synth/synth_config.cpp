#include "synth_config.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

#include "error.h"
#include "phong_brdf.h"
#include "scene_parser.h"
#include "scene_xml.h"

namespace phongfit {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

// Keys a group may set; at the top level they are the defaults of every group.
const std::vector<std::string> kGroupKeys = {"scenes",   "material", "spp",    "albedo",
                                             "ks_share", "n",        "colour", "tint",
                                             "light",    "defines",  "grid"};
// Keys whose values a grid sets instead.
const std::vector<std::string> kDrawnKeys = {"albedo", "ks_share", "n", "colour", "tint"};
// Defaults that synth itself sets: a config cannot set them through "defines".
const std::map<std::string, std::string> kOwnDefines = {{"kd", "albedo, ks_share, colour and tint"},
                                                        {"ks", "albedo, ks_share, colour and tint"},
                                                        {"n", "n"},
                                                        {"spp", "spp"},
                                                        {"light_x", "light"},
                                                        {"light_y", "light"},
                                                        {"light_z", "light"}};

using scene_xml::isIdentifier;

// Reads one config file; `fail` names the file, the key path and the value.
class Reader {
public:
    explicit Reader(std::string file) : file_(std::move(file)) {}

    [[noreturn]] void fail(const std::string& key, const json& value,
                           const std::string& problem) const {
        throw Error(fmt::format("{}: {} = {}: {}", file_, key, value.dump(), problem));
    }
    [[noreturn]] void fail(const std::string& problem) const {
        throw Error(fmt::format("{}: {}", file_, problem));
    }

    void checkKeys(const json& object, const std::string& prefix,
                   const std::vector<std::string>& allowed) const {
        for (const auto& [key, value] : object.items())
            if (std::find(allowed.begin(), allowed.end(), key) == allowed.end())
                fail(prefix + key, value,
                     fmt::format("unknown key (allowed: {})", fmt::join(allowed, ", ")));
    }

    std::int64_t integer(const std::string& key, const json& v, std::int64_t lo,
                         std::int64_t hi) const {
        if (!v.is_number_integer() || v.get<std::int64_t>() < lo || v.get<std::int64_t>() > hi)
            fail(key, v, fmt::format("expected an integer in [{}, {}]", lo, hi));
        return v.get<std::int64_t>();
    }

    std::string string(const std::string& key, const json& v) const {
        if (!v.is_string() || v.get<std::string>().empty())
            fail(key, v, "expected a non-empty string");
        return v.get<std::string>();
    }

    bool boolean(const std::string& key, const json& v) const {
        if (!v.is_boolean()) fail(key, v, "expected true or false");
        return v.get<bool>();
    }

    // A number or [lo, hi] with lo <= hi, within [min, max].
    Range range(const std::string& key, const json& v, double min, double max) const {
        const std::string allowed =
            fmt::format("a number or [lo, hi] with {} <= lo <= hi <= {}", min, max);
        Range r;
        if (v.is_number()) {
            r.lo = r.hi = v.get<double>();
            r.integer = v.is_number_integer();
        } else if (v.is_array() && v.size() == 2 && v[0].is_number() && v[1].is_number()) {
            r.lo = v[0].get<double>();
            r.hi = v[1].get<double>();
            r.integer = v[0].is_number_integer() && v[1].is_number_integer();
        } else {
            fail(key, v, "expected " + allowed);
        }
        if (!std::isfinite(r.lo) || !std::isfinite(r.hi) || r.lo > r.hi || r.lo < min || r.hi > max)
            fail(key, v, "expected " + allowed);
        return r;
    }

    // A grey number or [r, g, b], each in [0, 1].
    Color3 colour(const std::string& key, const json& v) const {
        if (v.is_number()) {
            const double x = v.get<double>();
            if (x >= 0 && x <= 1) return Color3::Constant(x);
        } else if (v.is_array() && v.size() == 3 && v[0].is_number() && v[1].is_number() &&
                   v[2].is_number()) {
            const Color3 c(v[0].get<double>(), v[1].get<double>(), v[2].get<double>());
            if ((c.array() >= 0).all() && (c.array() <= 1).all()) return c;
        }
        fail(key, v, "expected a number or [r, g, b], each in [0, 1]");
    }

    const std::string& file() const { return file_; }

private:
    std::string file_;
};

// The scene's defaults, and a check that `material` is a phong bsdf taking kd, ks, n from
// $kd, $ks, $n (a probe with unusual values must come back as those values).
void checkScene(const Reader& reader, const std::string& key, const std::string& written,
                const std::string& path, const GroupConfig& g,
                const std::map<std::string, std::string>& required) {
    std::ifstream in(path, std::ios::binary);
    if (!in) reader.fail(key, written, fmt::format("cannot read '{}'", path));
    std::stringstream text;
    text << in.rdbuf();
    const auto defaults = sceneVariables(text.str(), path, {});
    for (const auto& [name, why] : required) {
        if (defaults.count(name)) continue;
        std::vector<std::string> names;
        for (const auto& [n, v] : defaults) names.push_back(n);
        reader.fail(
            fmt::format("{}: scene '{}' has no <default name=\"{}\"> for {} (its "
                        "defaults: {})",
                        key, path, name, why, fmt::join(names, ", ")));
    }

    const Scene probe = loadScene(path, {{"kd", "0.125"}, {"ks", "0.25"}, {"n", "33"}});
    const int b = probe.findBsdf(g.material);
    if (b < 0 || probe.bsdfs[b].type != "phong")
        reader.fail(fmt::format("{}: scene '{}' has no phong bsdf with id '{}' (\"material\")", key,
                                path, g.material));
    const PhongMaterial& m = probe.bsdfs[b].params;
    if ((m.kd.array() != 0.125).any() || (m.ks.array() != 0.25).any() || m.n != 33)
        reader.fail(
            fmt::format("{}: bsdf '{}' of scene '{}' does not take its values from $kd, "
                        "$ks and $n, so the sampled values would not reach it",
                        key, g.material, path));
}

// {"n": [exponents], "materials": [{"kd": c, "ks": c}, ...]}, with kd + ks <= 1 per channel.
GridSpec readGrid(const Reader& reader, const std::string& key, const json& v) {
    if (!v.is_object()) reader.fail(key, v, "expected {\"n\": [...], \"materials\": [...]}");
    reader.checkKeys(v, key + ".", {"n", "materials"});
    for (const char* k : {"n", "materials"})
        if (!v.contains(k)) reader.fail(fmt::format("missing key '{}.{}'", key, k));
    GridSpec grid;
    const json& n = v.at("n");
    if (!n.is_array() || n.empty()) reader.fail(key + ".n", n, "expected a non-empty list");
    for (std::size_t i = 0; i < n.size(); ++i) {
        const std::string k = fmt::format("{}.n[{}]", key, i);
        if (!n[i].is_number() || !(n[i].get<double>() >= 1e-3 && n[i].get<double>() <= 1e6))
            reader.fail(k, n[i], "expected a number in [0.001, 1e6]");
        grid.n.push_back(n[i].get<double>());
    }
    const json& materials = v.at("materials");
    if (!materials.is_array() || materials.empty())
        reader.fail(key + ".materials", materials, "expected a non-empty list");
    for (std::size_t i = 0; i < materials.size(); ++i) {
        const std::string k = fmt::format("{}.materials[{}]", key, i);
        const json& m = materials[i];
        if (!m.is_object()) reader.fail(k, m, "expected {\"kd\": ..., \"ks\": ...}");
        reader.checkKeys(m, k + ".", {"kd", "ks"});
        for (const char* c : {"kd", "ks"})
            if (!m.contains(c)) reader.fail(fmt::format("missing key '{}.{}'", k, c));
        const GridSpec::Material material{reader.colour(k + ".kd", m.at("kd")),
                                          reader.colour(k + ".ks", m.at("ks"))};
        if (((material.kd + material.ks).array() > 1 + kEnergySumSlack).any())
            reader.fail(k, m, "kd + ks must be at most 1 in every channel");
        grid.materials.push_back(material);
    }
    if (grid.n.size() * grid.materials.size() > 1000000)
        reader.fail(key, v, "more than 1000000 cells");
    return grid;
}

// The ranges the material is drawn from.
template <typename Key, typename Require>
void readDrawn(const Reader& reader, const json& merged, const Key& key, const Require& require,
               GroupConfig& g) {
    g.albedo = reader.range(key("albedo"), require("albedo"), 0, 1);
    g.ksShare = reader.range(key("ks_share"), require("ks_share"), 0, 1);
    g.n = reader.range(key("n"), require("n"), 0, 1e6);
    if (g.n.lo < g.n.hi && g.n.lo <= 0)
        reader.fail(key("n"), merged.at("n"),
                    "a range of n is drawn log-uniformly, so its lower end must be > 0");
    if (merged.contains("colour")) g.colour = reader.boolean(key("colour"), merged.at("colour"));
    g.tint = Range{0.25, 1, false};
    if (merged.contains("tint")) {
        if (!g.colour) reader.fail(key("tint"), merged.at("tint"), "a tint needs \"colour\": true");
        g.tint = reader.range(key("tint"), merged.at("tint"), 0, 1);
    }
}

GroupConfig readGroup(const Reader& reader, const json& merged,
                      const std::map<std::string, std::string>& prefixOf, const fs::path& baseDir) {
    auto key = [&](const std::string& k) { return prefixOf.at(k) + k; };
    auto require = [&](const std::string& k) -> const json& {
        if (!merged.contains(k))
            reader.fail(fmt::format("missing key '{}'{}", k,
                                    prefixOf.count("name") ? " in " + prefixOf.at("name") : ""));
        return merged.at(k);
    };
    GroupConfig g;
    const json& scenes = require("scenes");
    if (!scenes.is_array() || scenes.empty())
        reader.fail(key("scenes"), scenes, "expected a non-empty list of scene files");
    for (std::size_t i = 0; i < scenes.size(); ++i) {
        g.scenes.push_back(reader.string(fmt::format("{}[{}]", key("scenes"), i), scenes[i]));
        const fs::path p(g.scenes.back());
        g.scenePaths.push_back((p.is_absolute() ? p : baseDir / p).lexically_normal().string());
    }
    g.material = reader.string(key("material"), require("material"));
    g.spp = int(reader.integer(key("spp"), require("spp"), 1, 1 << 20));
    if (merged.contains("grid")) {
        g.grid = readGrid(reader, key("grid"), merged.at("grid"));
        for (const std::string& k : kDrawnKeys)
            if (merged.contains(k) && prefixOf.at(k) == prefixOf.at("grid"))
                reader.fail(key(k), merged.at(k), "the \"grid\" beside it sets these values");
    } else {
        readDrawn(reader, merged, key, require, g);
    }
    if (merged.contains("light")) {
        const json& l = merged.at("light");
        const std::string p = key("light") + ".";
        if (!l.is_object())
            reader.fail(key("light"), l, "expected {\"phase_deg\", \"azimuth_deg\", \"distance\"}");
        reader.checkKeys(l, p, {"phase_deg", "azimuth_deg", "distance"});
        for (const char* k : {"phase_deg", "azimuth_deg", "distance"})
            if (!l.contains(k)) reader.fail(fmt::format("missing key '{}{}'", p, k));
        LightSpec s;
        s.phaseDeg = reader.range(p + "phase_deg", l.at("phase_deg"), 0, 180);
        s.azimuthDeg = reader.range(p + "azimuth_deg", l.at("azimuth_deg"), -360, 360);
        s.distance = reader.range(p + "distance", l.at("distance"), 0, 1e6);
        if (s.distance.lo <= 0)
            reader.fail(p + "distance", l.at("distance"), "the light's distance must be > 0");
        g.light = s;
    }
    // Defaults the scenes must declare, and why (the key that sets them).
    std::map<std::string, std::string> required = {{"kd", "the sampled material"},
                                                   {"ks", "the sampled material"},
                                                   {"n", "the sampled material"}};
    if (g.light)
        for (const char* name : {"light_x", "light_y", "light_z"}) required[name] = key("light");
    if (merged.contains("defines")) {
        const json& d = merged.at("defines");
        if (!d.is_object()) reader.fail(key("defines"), d, "expected an object {\"name\": value}");
        for (const auto& [name, value] : d.items()) {
            const std::string k = prefixOf.at("defines." + name) + "defines." + name;
            if (!isIdentifier(name))
                reader.fail(k, value, "not a valid default name (allowed: letters, digits and _)");
            if (kOwnDefines.count(name))
                reader.fail(k, value,
                            fmt::format("'{}' is set by {}, not by \"defines\"", name,
                                        kOwnDefines.at(name)));
            DefineSpec spec;
            if (value.is_string())
                spec.text = value.get<std::string>();
            else
                spec.range = reader.range(k, value, -1e12, 1e12);
            g.defines[name] = spec;
            required[name] = k;
        }
    }
    for (std::size_t i = 0; i < g.scenePaths.size(); ++i)
        checkScene(reader, fmt::format("{}[{}]", key("scenes"), i), g.scenes[i], g.scenePaths[i], g,
                   required);
    return g;
}

// "samples", or with a grid its cells for every scene (then "samples" is not given).
int sampleCount(const Reader& reader, const GroupConfig& g, const json& object,
                const std::string& prefix) {
    if (g.grid) {
        if (object.contains("samples"))
            reader.fail(prefix + "samples", object.at("samples"),
                        "with a \"grid\" the samples are its cells for every scene");
        const std::int64_t count = std::int64_t(g.grid->cells()) * std::int64_t(g.scenes.size());
        if (count > 1000000)
            reader.fail(prefix + "grid", count, "more than 1000000 samples with its scenes");
        return int(count);
    }
    if (!object.contains("samples"))
        reader.fail(
            fmt::format("missing key '{}samples'{}", prefix,
                        prefix.empty() ? " (or \"groups\" or \"grid\")" : " (or \"grid\")"));
    return int(reader.integer(prefix + "samples", object.at("samples"), 1, 1000000));
}

}  // namespace

int SynthConfig::totalSamples() const {
    int total = 0;
    for (const GroupConfig& g : groups) total += g.samples;
    return total;
}

SynthConfig loadSynthConfig(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw Error(fmt::format("cannot read config '{}'", path));
    SynthConfig config;
    config.path = path;
    const Reader reader(path);
    try {
        config.json = json::parse(in);
    } catch (const json::parse_error& e) {
        reader.fail(fmt::format("not valid JSON: {}", e.what()));
    }
    const json& top = config.json;
    if (!top.is_object()) reader.fail("expected a JSON object {\"scenes\": ..., ...}");
    std::vector<std::string> topKeys = kGroupKeys;
    topKeys.insert(topKeys.end(), {"samples", "seed", "groups", "description"});
    reader.checkKeys(top, "", topKeys);
    if (top.contains("seed"))
        config.seed = std::uint64_t(reader.integer("seed", top.at("seed"), 0, INT64_MAX));
    if (top.contains("description")) reader.string("description", top.at("description"));
    if (top.contains("defines") && !top.at("defines").is_object())
        reader.fail("defines", top.at("defines"), "expected an object {\"name\": value}");

    const fs::path baseDir = fs::absolute(path).parent_path();
    // Each group is the top level's keys overridden by its own; `prefixOf` tells an error which
    // of the two a key came from.
    auto mergeGroup = [&](const json& group, const std::string& groupPrefix) {
        json merged = json::object();
        std::map<std::string, std::string> prefixOf;
        for (const std::string& k : kGroupKeys) {
            if (top.contains(k)) {
                merged[k] = top.at(k);
                prefixOf[k] = "";
            }
            if (group.contains(k) && k != "defines") {
                merged[k] = group.at(k);
                prefixOf[k] = groupPrefix;
            }
        }
        json defines = top.value("defines", json::object());
        if (top.contains("defines"))
            for (const auto& [name, v] : top.at("defines").items())
                prefixOf["defines." + name] = "";
        if (group.contains("defines")) {
            if (!group.at("defines").is_object())
                reader.fail(groupPrefix + "defines", group.at("defines"),
                            "expected an object {\"name\": value}");
            for (const auto& [name, v] : group.at("defines").items()) {
                defines[name] = v;
                prefixOf["defines." + name] = groupPrefix;
            }
        }
        if (!defines.empty() || merged.contains("defines")) {
            merged["defines"] = defines;
            prefixOf["defines"] = group.contains("defines") ? groupPrefix : "";
        }
        for (const std::string& k : kGroupKeys) prefixOf.try_emplace(k, groupPrefix);
        return std::make_pair(merged, prefixOf);
    };

    if (top.contains("groups")) {
        if (top.contains("samples"))
            reader.fail("samples", top.at("samples"),
                        "with \"groups\", give \"samples\" in each group instead");
        const json& groups = top.at("groups");
        if (!groups.is_array() || groups.empty())
            reader.fail("groups", groups, "expected a non-empty list of group objects");
        std::set<std::string> names;
        for (std::size_t i = 0; i < groups.size(); ++i) {
            const std::string prefix = fmt::format("groups[{}].", i);
            const json& group = groups[i];
            if (!group.is_object())
                reader.fail(fmt::format("groups[{}]", i), group, "expected an object");
            std::vector<std::string> keys = kGroupKeys;
            keys.insert(keys.end(), {"name", "samples", "description"});
            reader.checkKeys(group, prefix, keys);
            if (!group.contains("name")) reader.fail(fmt::format("missing key '{}name'", prefix));
            const std::string name = reader.string(prefix + "name", group.at("name"));
            if (!isIdentifier(name))
                reader.fail(prefix + "name", group.at("name"),
                            "expected a name of letters, digits and _");
            if (!names.insert(name).second)
                reader.fail(prefix + "name", group.at("name"), "a second group with this name");
            if (group.contains("description"))
                reader.string(prefix + "description", group.at("description"));
            auto [merged, prefixOf] = mergeGroup(group, prefix);
            prefixOf["name"] = "groups[" + std::to_string(i) + "] ('" + name + "')";
            GroupConfig g = readGroup(reader, merged, prefixOf, baseDir);
            g.name = name;
            g.samples = sampleCount(reader, g, group, prefix);
            config.groups.push_back(std::move(g));
        }
    } else {
        auto [merged, prefixOf] = mergeGroup(json::object(), "");
        GroupConfig g = readGroup(reader, merged, prefixOf, baseDir);
        g.name = "default";
        g.samples = sampleCount(reader, g, top, "");
        config.groups.push_back(std::move(g));
    }
    if (config.totalSamples() > 1000000)
        reader.fail(fmt::format("{} samples in all: at most 1000000", config.totalSamples()));
    return config;
}

}  // namespace phongfit
