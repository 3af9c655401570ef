// Importance samplers for the Modified Phong BRDF, selectable by name (DESIGN.md):
//   lafortune  u < kd: cosine lobe; kd <= u < kd + ks: Phong lobe around the mirror direction; else
//   absorb mixture    always a lobe, chosen in proportion to kd and ks (Mitsuba 0.5) cap        as
//   lafortune, the specular lobe uniform over the cap cos(theta) >= 1e-10^(1 / (n + 1)) cosine
//   cosine-weighted hemisphere uniform    uniform hemisphere
// kd and ks in the lobe choice are the means over the RGB channels.
//
// Random numbers go in explicitly (1D for the lobe choice, 2D for the direction), so sampling is a
// pure function that can be replayed. `pdf` is the density of the directions `sample` returns, over
// the whole mixture (not only the lobe picked); it is a sub-probability density for the absorbing
// samplers and where a lobe reaches below the horizon (those directions are not returned).
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "phong_brdf.h"

namespace phongfit {

enum class Lobe : std::uint8_t { Diffuse, Specular };

template <typename T>
struct PhongSample {
    Vec3<T> wi;
    T pdf;
    Color<T> weight;  // f * cos(theta_i) / pdf
    Lobe lobe;
};

template <typename T>
class PhongSampler {
public:
    virtual ~PhongSampler() = default;

    // Empty when the sampler absorbs or the direction falls on or below the horizon.
    virtual std::optional<PhongSample<T>> sample(const PhongParams<T>& m, const Vec3<T>& wo,
                                                 T uLobe, const Vec2<T>& u) const = 0;
    virtual T pdf(const PhongParams<T>& m, const Vec3<T>& wo, const Vec3<T>& wi) const = 0;
    // Probability of not absorbing, i.e. the integral of the density over the whole sphere
    // (directions below the horizon included): 1, or mean(kd) + mean(ks) for absorbing samplers.
    virtual T mass(const PhongParams<T>& m) const = 0;
    // Density over the whole sphere, before the horizon clip (for tests and diagnostics).
    virtual T unclippedPdf(const PhongParams<T>& m, const Vec3<T>& wo, const Vec3<T>& wi) const = 0;

    const std::string& name() const { return name_; }

protected:
    explicit PhongSampler(std::string name) : name_(std::move(name)) {}

private:
    std::string name_;
};

// The sampler called `name`; throws Error listing the allowed names otherwise.
template <typename T>
std::unique_ptr<PhongSampler<T>> makePhongSampler(std::string_view name);

const std::vector<std::string>& phongSamplerNames();

}  // namespace phongfit
