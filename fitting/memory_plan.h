// What a fit holds beyond its images and recorded paths (docs/design/fitter.md, "Memory"): at most
// kStateBytesPerPixel a used pixel. A fit that cannot fit fails before it records; a round whose
// paths would not fit is not started.
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include "observation.h"

namespace phongfit {

inline constexpr std::size_t kStateBytesPerPixel = 200;

// The least a recording takes a pixel (its background and its first term's index, PathSet).
inline constexpr std::size_t kLeastRecordedBytesPerPixel = 16;

// Bytes the fit may still allocate: `limit` (FitOptions::memoryLimit, the whole process' bytes)
// less what the process holds, or without a limit what the machine has available; nothing where
// neither can be read.
std::optional<std::size_t> fitMemoryAvailable(std::size_t limit);

// The state of every pixel of the views (any may be used): what a recording must leave the solve.
std::size_t stateBytes(const std::vector<Observation>& observations);

// The least the first round needs: the state and two recordings of every pixel of the views.
std::size_t leastFirstRoundBytes(const std::vector<Observation>& observations);

// What a later round needs: `recordedBytes` (the last round's paths) times `growth`, and the
// state of the `pixelsUsed` pixels the last round used.
double nextRoundBytes(std::size_t recordedBytes, double growth, std::size_t pixelsUsed);

// Throws Error, naming what is needed, what is available and why, when `need` exceeds what
// fitMemoryAvailable(limit) gives.
void requireMemory(std::size_t need, std::size_t limit, const std::string& what);

}  // namespace phongfit
