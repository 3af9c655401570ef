// The pixels that enter the fit, chosen once per round from the observations and the path sets.
#pragma once

#include <cstddef>
#include <cstdint>
#include <map>
#include <span>
#include <string>
#include <vector>

#include "exposure_block.h"
#include "observation.h"
#include "phong_brdf.h"
#include "round_paths.h"

namespace phongfit {

// A pixel that enters the fit: observed, finite, and seen through a fitted material, or next to
// one that is.
// 16 bytes: the fit keeps one per used pixel (docs/design/fitter.md, "Memory"); its observed
// value and weight are read from the observation (pixelObserved, pixelWeight).
struct UsedPixel {
    std::uint32_t view, pixel;
    // Into UsedPixels::slots: the blocks the vertices of the pixel and its neighbours use.
    std::uint32_t slotBegin;
    std::uint16_t slotCount;
    // Its own paths (in either set) have a vertex on a fitted material, or with a fitted exposure
    // any light: its residual depends on the parameters.
    bool seesMaterial;
};

inline Color3 pixelObserved(const Observation& o, std::uint32_t pixel) {
    const float* rgb = o.rgb.data() + 3 * std::size_t(pixel);
    return Color3(rgb[0], rgb[1], rgb[2]);
}

// The weight that multiplies the pixel's residual (Observation::weight).
inline double pixelWeight(const Observation& o, std::uint32_t pixel) {
    return o.weight.empty() ? 1.0 : double(o.weight[pixel]);
}

// Parameter blocks a fit can have (UsedPixel::slotCount's range).
inline constexpr int kMaxSlots = 65535;

struct UsedPixels {
    // Those that see a material first (seeingMaterial of them): the others' residuals do not
    // depend on the parameters.
    std::vector<UsedPixel> pixels;
    std::vector<int> widths, heights;  // per view
    // Per view and pixel (y * width + x): its index in `pixels`, or -1 where it is not used.
    std::vector<std::vector<std::int32_t>> index;
    std::vector<std::uint32_t> slots;            // sorted per pixel
    std::vector<bool> slotSeen;                  // per block: some used pixel lists it
    std::map<std::string, std::size_t> leftOut;  // "masked", "non_finite", "no_fitted_material"
    std::size_t seeingMaterial = 0;
    // Over the pixels that see a material, and channels:
    double meanObserved = 0;
    double rmsObserved = 0;  // of weight * observation

    std::span<const std::uint32_t> slotsOf(const UsedPixel& u) const {
        return {slots.data() + u.slotBegin, u.slotCount};
    }
};

// `slots`: the number of blocks. A pixel enters when a fitted material is seen through a pixel at
// most `radius` away in any of `sets` (the instruments' smoothing radius; 0 for least squares).
// With a fitted `exposure`, every pixel with light in a set also sees the exposure's block (its
// background alone constrains it). A pixel where only one set sees the material enters whatever
// the other holds: selecting A's residuals by A's own noise would bias them. Throws Error when no
// pixel is left, or when `slots` exceeds kMaxSlots.
UsedPixels selectUsedPixels(const std::vector<Observation>& observations, const SetLists& sets,
                            int slots, int radius, const ExposureBlock& exposure);

}  // namespace phongfit
