// Whether more paths can still make the estimate more precise. The recorder shares a round's
// extra paths by importance (allocatePaths), at most kMostExtraPaths more than the first round's
// in a pixel: once the pixels that hold the information are near that cap, more paths go where
// they inform little, and FitOptions::precision's growth stops (docs/design/fitter.md, "Paths at
// their cap").
#pragma once

#include <cstdint>
#include <vector>

#include "path_set.h"

namespace phongfit {

// The most extra paths a recording puts in one pixel (PathRecorder's importance share).
inline constexpr int kMostExtraPaths = 1024;

// Below this many times less variance, at the cap, than another round at the same paths, more
// paths are not worth a round.
inline constexpr double kLeastPathGain = 2;

// A recording's paths per pixel: `spp` in every pixel, or `perPixel` where they differ (a copy of
// PathSet::pixelPaths, empty for a uniform recording).
struct PixelPaths {
    std::uint32_t spp = 0;
    std::vector<std::uint32_t> perPixel;
    std::uint32_t at(std::size_t p) const { return perPixel.empty() ? spp : perPixel[p]; }
};

// Per view, the paths per pixel of `sets`.
std::vector<PixelPaths> pathsPerPixel(const std::vector<PathSet>& sets);

// The recordings' variance of the estimate as pathImportance weighs it, sum_p importance_p^2 /
// paths_p over the pixels with importance (and paths), for a recording at `pathFactor`
// (PathRecorder's) shared by `importance`: the first round's paths `base`, and in the pixels with
// importance (pathFactor - 1) times their mean base more on average, shared by allocatePaths
// within kMostExtraPaths (a recording's --adaptive-spp paths, the same at every factor from 1 on,
// are left out). Returns how many times smaller it is with every such pixel at the cap: the most
// more paths can give; infinite where no pixel has importance.
double mostPathGain(const std::vector<std::vector<float>>& importance,
                    const std::vector<PixelPaths>& base, double pathFactor);

}  // namespace phongfit
