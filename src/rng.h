// Counter-based random numbers: a value is a pure function of (seed, stream, sample, dimension), so
// any pixel sample can be regenerated on its own, in any order, on any thread (as pbrt-v4's
// IndependentSampler). An image is then bit-identical for a seed whatever the thread count, and a
// recorded path can be replayed.
#pragma once

#include <cstdint>

namespace phongfit {

// SplitMix64's finalizer: a bijective 64-bit mix with full avalanche.
constexpr std::uint64_t mix64(std::uint64_t x) {
    x ^= x >> 30;
    x *= 0xbf58476d1ce4e5b9ULL;
    x ^= x >> 27;
    x *= 0x94d049bb133111ebULL;
    x ^= x >> 31;
    return x;
}

class CounterRng {
public:
    // `stream` is typically the pixel index; `seed` the user's seed.
    constexpr CounterRng(std::uint64_t seed, std::uint64_t stream)
        : key_(mix64(mix64(seed ^ 0x9e3779b97f4a7c15ULL) + stream)) {}

    // 64 random bits for (sample, dimension).
    constexpr std::uint64_t bits(std::uint64_t sample, std::uint32_t dimension) const {
        // SplitMix64's Weyl sequence over dimensions, started at a per-sample point.
        return mix64(mix64(key_ ^ sample) + (std::uint64_t(dimension) + 1) * 0x9e3779b97f4a7c15ULL);
    }

    // Uniform in [0, 1), 53 random bits.
    constexpr double uniform(std::uint64_t sample, std::uint32_t dimension) const {
        return double(bits(sample, dimension) >> 11) * 0x1.0p-53;
    }

private:
    std::uint64_t key_;
};

}  // namespace phongfit
