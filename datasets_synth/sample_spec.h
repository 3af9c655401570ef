// One sample of a synth dataset: everything drawn for it, as a pure function of the config and the
// sample's index (counter-based random numbers keyed by the config's seed and the index), so a
// sample can be redrawn on its own, in any order, and a resumed run redraws exactly what an
// uninterrupted one would.
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <string>

#include "phong_brdf.h"
#include "synth_config.h"

namespace phongfit {

struct LightPlacement {
    double phaseDeg = 0, azimuthDeg = 0, distance = 0;
    Vec3d position = Vec3d::Zero();
};

struct SampleSpec {
    int index = 0;
    std::string name;  // the sample's folder, e.g. "sample_0007"
    int group = 0;     // into SynthConfig::groups
    int scene = 0;     // into the group's scenes
    PhongMaterial material;
    std::optional<LightPlacement> light;
    // Every scene default the sample sets (kd, ks, n, spp, light_*, the config's defines), as
    // the text baked into its scene file.
    std::map<std::string, std::string> defines;
    std::uint64_t renderSeed = 0;
};

// Sample `index` (0 <= index < config.totalSamples()); groups take consecutive indices in order.
SampleSpec drawSample(const SynthConfig& config, int index);

// "sample_0007": zero-padded to at least 4 digits, more when `total` needs them.
std::string sampleName(int index, int total);

}  // namespace phongfit
