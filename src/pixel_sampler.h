// The numbers a pixel's samples consume, by (sample, dimension): independent (CounterRng), Sobol
// (Joe and Kuo's sequence over all dimensions, Owen-scrambled per pixel and dimension by Burley
// 2020's hash, "Practical Hash-based Owen Scrambling"; Mitsuba's `sobol`) or padded Sobol (2D
// points independent of each other; Mitsuba's `ldsampler`, pbrt-v4's PaddedSobolSampler). All are
// counter-based: a value is a pure function of (seed, pixel, sample, dimension), so any pixel
// sample is regenerated on its own, on any thread, and a recorded path can be replayed.
//
// Sobol: dimension d of sample i is the sequence's dimension d at index i, scrambled, so a pixel's
// power-of-two prefixes are nets in all dimensions jointly; beyond kDimensions it pads.
// Padded: every 1D or 2D request draws from the first one or two dimensions of the sequence (a
// (0,2)-sequence), its sample index shuffled and its values scrambled by hashes of (seed, pixel,
// dimension), so that each request is stratified on its own and requests are independent of each
// other. The integrator's dimension layout (path_integrator.h) asks for 2D pairs where two numbers
// warp one point (film position, BRDF direction, light point). docs/design/sampling.md.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "math.h"
#include "rng.h"

namespace phongfit {

enum class PixelSamplerType { Independent, Padded, Sobol };

// Mitsuba's <sampler type> names: independent; sobol; ldsampler, padded.
inline const std::vector<std::string>& pixelSamplerNames() {
    static const std::vector<std::string> names = {"independent", "sobol", "ldsampler"};
    return names;
}
inline PixelSamplerType pixelSamplerType(std::string_view name) {
    if (name == "independent") return PixelSamplerType::Independent;
    return name == "ldsampler" ? PixelSamplerType::Padded : PixelSamplerType::Sobol;
}
inline std::string pixelSamplerName(PixelSamplerType type) {
    if (type == PixelSamplerType::Independent) return "independent";
    return type == PixelSamplerType::Padded ? "ldsampler" : "sobol";
}

namespace sobol {

constexpr std::uint32_t reverseBits(std::uint32_t x) {
    x = (x << 16) | (x >> 16);
    x = ((x & 0x00ff00ffu) << 8) | ((x & 0xff00ff00u) >> 8);
    x = ((x & 0x0f0f0f0fu) << 4) | ((x & 0xf0f0f0f0u) >> 4);
    x = ((x & 0x33333333u) << 2) | ((x & 0xccccccccu) >> 2);
    return ((x & 0x55555555u) << 1) | ((x & 0xaaaaaaaau) >> 1);
}

// Burley's hash-based Laine-Karras permutation: each bit depends only on the bits below it.
constexpr std::uint32_t laineKarras(std::uint32_t x, std::uint32_t seed) {
    x += seed;
    x ^= x * 0x6c50b47cu;
    x ^= x * 0xb82f1e52u;
    x ^= x * 0xc7afe638u;
    x ^= x * 0x8d22f6e6u;
    return x;
}

// Owen scrambling of a binary fraction (bit 31 first): each digit flipped by a hash of those above.
constexpr std::uint32_t owenScramble(std::uint32_t x, std::uint32_t seed) {
    return reverseBits(laineKarras(reverseBits(x), seed));
}

// Dimension 0 of the Sobol sequence: the van der Corput sequence.
constexpr std::uint32_t dimension0(std::uint32_t i) { return reverseBits(i); }

// Joe and Kuo's Sobol sequence (new-joe-kuo-6.21201, direction numbers from Boost.Random) in its
// first kDimensions dimensions, bit-reversed (bit 0 first, as Owen scrambling takes it), as tables
// of the contribution of each byte of the index: dimension d's table for byte b at
// [(4 * d + b) * 256].
constexpr std::uint32_t kDimensions = 256;
const std::uint32_t* reversedByteTables();

// Point `i` of the dimension whose byte tables start at `t`, bit-reversed.
inline std::uint32_t reversedSample(std::uint32_t i, const std::uint32_t* t) {
    std::uint32_t x = t[i & 0xff];
    for (i >>= 8; i; i >>= 8) x ^= (t += 256)[i & 0xff];
    return x;
}

}  // namespace sobol

class PixelSampler {
public:
    PixelSampler(PixelSamplerType type, std::uint64_t seed, std::uint64_t pixel)
        : rng_(seed, pixel),
          type_(type),
          key_(rng_.bits(0, 0)),
          tables_(type == PixelSamplerType::Independent ? nullptr : sobol::reversedByteTables()) {}

    PixelSamplerType type() const { return type_; }

    // Uniform in [0, 1) for `dimension` of `sample`.
    double get1D(std::uint64_t sample, std::uint32_t dimension) const {
        if (type_ == PixelSamplerType::Independent) return rng_.uniform(sample, dimension);
        if (type_ == PixelSamplerType::Sobol && dimension < sobol::kDimensions)
            return global(sample, dimension);
        const std::uint64_t h = scrambles(dimension);
        const std::uint32_t i = sobol::owenScramble(std::uint32_t(sample), std::uint32_t(h));
        return toUnit(sobol::owenScramble(sobol::dimension0(i), std::uint32_t(h >> 32)));
    }

    // A point in [0, 1)^2 for dimensions `dimension` and `dimension + 1` of `sample`.
    Vec2d get2D(std::uint64_t sample, std::uint32_t dimension) const {
        if (type_ == PixelSamplerType::Independent)
            return Vec2d(rng_.uniform(sample, dimension), rng_.uniform(sample, dimension + 1));
        if (type_ == PixelSamplerType::Sobol && dimension + 1 < sobol::kDimensions)
            return Vec2d(global(sample, dimension), global(sample, dimension + 1));
        const std::uint64_t h = scrambles(dimension), g = mix64(h);
        const std::uint32_t i = sobol::owenScramble(std::uint32_t(sample), std::uint32_t(h));
        return Vec2d(toUnit(sobol::owenScramble(sobol::dimension0(i), std::uint32_t(h >> 32))),
                     toUnit(sobol::reverseBits(
                         sobol::laineKarras(sobol::reversedSample(i, tables_ + 1024), g))));
    }

private:
    // Dimension `dimension` of the Sobol sequence, Owen-scrambled by a hash of (seed, pixel,
    // dimension); the sample index is the same in every dimension, so the dimensions stay a net.
    double global(std::uint64_t sample, std::uint32_t dimension) const {
        const std::uint32_t x =
            sobol::reversedSample(std::uint32_t(sample), tables_ + 1024 * std::size_t(dimension));
        return toUnit(
            sobol::reverseBits(sobol::laineKarras(x, std::uint32_t(scrambles(dimension) >> 32))));
    }

    // Seeds of the index shuffle (low half) and of the first value's scramble (high half).
    constexpr std::uint64_t scrambles(std::uint32_t dimension) const {
        return mix64(key_ + (std::uint64_t(dimension) + 1) * 0x9e3779b97f4a7c15ULL);
    }

    // The middle of the scrambled value's 2^-32 cell: never 0 or 1, and the mean stays 1/2.
    static constexpr double toUnit(std::uint32_t x) { return (double(x) + 0.5) * 0x1.0p-32; }

    CounterRng rng_;
    PixelSamplerType type_;
    std::uint64_t key_;            // of the scrambles: the pixel's, seeded
    const std::uint32_t* tables_;  // but for independent: sobol::reversedByteTables()
};

}  // namespace phongfit
