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

// A recording's paths per pixel, per view (PathSet::spp where pixelPaths is empty).
std::vector<std::vector<std::uint32_t>> pathsPerPixel(const std::vector<PathSet>& sets);

// The recordings' variance of the estimate as pathImportance weighs it, sum_p importance_p^2 /
// paths_p over every view's pixels that have importance (and paths).
double weighedPathVariance(const std::vector<std::vector<float>>& importance,
                           const std::vector<std::vector<std::uint32_t>>& paths);

// Per view, the paths per pixel of a recording at `pathFactor` (PathRecorder's): the first round's
// `base`, and in the pixels with importance (pathFactor - 1) times their mean base more on average,
// shared by allocatePaths within kMostExtraPaths (a recording's --adaptive-spp paths, the same at
// every factor from 1 on, are left out).
std::vector<std::vector<std::uint32_t>> plannedPaths(
    const std::vector<std::vector<float>>& importance,
    const std::vector<std::vector<std::uint32_t>>& base, double pathFactor);

// How many times smaller the weighed variance is with every pixel that has importance at the cap
// than with a recording at `pathFactor` shared by the same importance: the most more paths can
// give. Infinite where no pixel has importance.
double mostPathGain(const std::vector<std::vector<float>>& importance,
                    const std::vector<std::vector<std::uint32_t>>& base, double pathFactor);

}  // namespace phongfit
