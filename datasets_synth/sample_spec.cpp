#include "sample_spec.h"

#include <fmt/format.h>

#include <cmath>

#include "rng.h"

namespace phongfit {
namespace {

// Random dimensions of a sample; the config's defines follow kFirstDefine in name order.
enum Dimension : std::uint32_t {
    kAlbedo,
    kKsShare,
    kExponent,
    kKdTint,  // three channels
    kKsTint = kKdTint + 3,
    kPhase = kKsTint + 3,
    kAzimuth,
    kDistance,
    kRenderSeed,
    kFirstDefine,
};

double uniformIn(const Range& r, double u) { return r.lo + (r.hi - r.lo) * u; }

// Integers lo..hi inclusive when both ends were written as integers.
double drawNumber(const Range& r, double u) {
    if (r.integer && r.lo < r.hi) return std::min(r.hi, r.lo + std::floor((r.hi - r.lo + 1) * u));
    return uniformIn(r, u);
}

double logUniformIn(const Range& r, double u) {
    if (r.lo == r.hi) return r.lo;
    return std::exp(std::log(r.lo) + (std::log(r.hi) - std::log(r.lo)) * u);
}

// Shortest text that reads back as exactly `v`.
std::string text(double v) { return fmt::format("{}", v); }

std::string colorText(const Color3& c) {
    if (c[0] == c[1] && c[1] == c[2]) return text(c[0]);
    return fmt::format("{}, {}, {}", c[0], c[1], c[2]);
}

}  // namespace

std::string sampleName(int index, int total) {
    const int digits = std::max(4, int(std::to_string(std::max(total - 1, 0)).size()));
    return fmt::format("sample_{:0{}}", index, digits);
}

SampleSpec drawSample(const SynthConfig& config, int index) {
    SampleSpec s;
    s.index = index;
    s.name = sampleName(index, config.totalSamples());
    int first = 0;  // the group's first index
    while (index - first >= config.groups[s.group].samples)
        first += config.groups[s.group++].samples;
    const GroupConfig& g = config.groups[s.group];
    const int local = index - first;
    s.scene = g.grid ? local / g.grid->cells() : local % int(g.scenes.size());

    const CounterRng rng(config.seed, std::uint64_t(index));
    auto u = [&](std::uint32_t dimension) { return rng.uniform(0, dimension); };
    // Total and split rather than kd and ks on their own: kd + ks <= albedo <= 1 by construction,
    // and the ranges say directly how bright and how glossy the samples are.
    if (g.grid) {
        const int cell = local % g.grid->cells();
        const GridSpec::Material& m = g.grid->materials[cell % g.grid->materials.size()];
        s.material.kd = m.kd;
        s.material.ks = m.ks;
        s.material.n = g.grid->n[cell / g.grid->materials.size()];
    } else {
        const double albedo = uniformIn(g.albedo, u(kAlbedo));
        const double share = uniformIn(g.ksShare, u(kKsShare));
        for (int c = 0; c < 3; ++c) {
            s.material.kd[c] =
                albedo * (1 - share) * (g.colour ? uniformIn(g.tint, u(kKdTint + c)) : 1);
            s.material.ks[c] = albedo * share * (g.colour ? uniformIn(g.tint, u(kKsTint + c)) : 1);
        }
        s.material.n = logUniformIn(g.n, u(kExponent));
    }
    s.defines["kd"] = colorText(s.material.kd);
    s.defines["ks"] = colorText(s.material.ks);
    s.defines["n"] = text(s.material.n);
    s.defines["spp"] = text(g.spp);

    if (g.light) {
        LightPlacement l;
        l.phaseDeg = uniformIn(g.light->phaseDeg, u(kPhase));
        l.azimuthDeg = uniformIn(g.light->azimuthDeg, u(kAzimuth));
        l.distance = uniformIn(g.light->distance, u(kDistance));
        const double phase = l.phaseDeg * kPi / 180, azimuth = l.azimuthDeg * kPi / 180;
        l.position = l.distance * Vec3d(std::sin(phase) * std::cos(azimuth),
                                        std::sin(phase) * std::sin(azimuth), std::cos(phase));
        s.defines["light_x"] = text(l.position.x());
        s.defines["light_y"] = text(l.position.y());
        s.defines["light_z"] = text(l.position.z());
        s.light = l;
    }
    std::uint32_t dimension = kFirstDefine;
    for (const auto& [name, spec] : g.defines) {
        s.defines[name] = spec.text ? *spec.text : text(drawNumber(spec.range, u(dimension)));
        ++dimension;
    }
    s.renderSeed = rng.bits(0, kRenderSeed);
    return s;
}

}  // namespace phongfit
