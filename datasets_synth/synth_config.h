// The configuration of `phongfit synth` (datasets_synth/README.md): which base scenes, how many
// samples, the ranges their parameters are drawn from, the seed. Read and checked in full before
// anything is rendered; every error names the file, the key, the value and what is allowed.
#pragma once

#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "math.h"

namespace phongfit {

// A number, or [lo, hi] to draw from (lo == hi for a fixed value).
struct Range {
    double lo = 0, hi = 0;
    bool integer = false;  // both ends written as integers: draw integers
};

// A scene default set per sample: fixed text, or a number drawn uniformly from a range.
struct DefineSpec {
    std::optional<std::string> text;
    Range range;
};

// The point light's position from its direction as seen from the origin: `phaseDeg` is the angle
// between the light and the +z axis (the camera's side in the sphere scenes: 0 lights the sphere
// head-on, near 180 from behind), `azimuthDeg` turns it about +z from +x towards +y.
struct LightSpec {
    Range phaseDeg, azimuthDeg, distance;
};

// Every listed exponent with every listed material, instead of drawn values: a matrix of cases.
struct GridSpec {
    struct Material {
        Color3 kd, ks;
    };
    std::vector<double> n;
    std::vector<Material> materials;
    int cells() const { return int(n.size() * materials.size()); }
};

// Samples of one kind; a config without "groups" is a single group named "default".
struct GroupConfig {
    std::string name;
    int samples = 0;
    std::vector<std::string> scenes;      // as written in the config
    std::vector<std::string> scenePaths;  // resolved against the config's directory
    std::string material;                 // id of the phong bsdf the scenes sample
    int spp = 0;
    Range albedo;                    // kd + ks (per channel, before any tint)
    Range ksShare;                   // ks / (kd + ks)
    Range n;                         // log-uniform
    bool colour = false;             // kd and ks tinted per channel
    Range tint;                      // per-channel factor of kd and ks, with colour
    std::optional<LightSpec> light;  // sets the defaults light_x, light_y, light_z
    // With a grid, sample i of the group is scene i / cells, then exponent and material in that
    // order; samples = scenes x cells, and albedo, ks_share, n, colour and tint are not used.
    std::optional<GridSpec> grid;
    std::map<std::string, DefineSpec> defines;
};

struct SynthConfig {
    std::string path;
    std::uint64_t seed = 0;
    std::vector<GroupConfig> groups;
    nlohmann::json json;  // as read, to tell a resumed run whether the config changed

    int totalSamples() const;
};

// Reads `path`, checks every key and the scenes it names (each must parse, have the phong bsdf
// `material` taking its values from $kd, $ks, $n, and declare every default the config sets).
// Throws Error naming the key on the first problem.
SynthConfig loadSynthConfig(const std::string& path);

}  // namespace phongfit
