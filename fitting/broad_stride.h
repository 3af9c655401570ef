// Where the next round records when a round's recordings cannot see the broader lobe its estimate
// went towards. A recording resolves n only within about a factor 3 of the n it was made at,
// whatever its paths (the Cornell box under a 40-degree light, n 300: one round at 4 paths a pixel
// recorded at n 300 gives 297.8 +- 8.9, at n 1000 stays at 1000 +- 2920, at n 3000 with 64 paths
// a pixel gives 2639 +- 7630). Growing the paths there buys little; recording broader does.
// docs/design/fitter.md, "A broad stride".
#pragma once

#include <optional>
#include <vector>

#include "fitter.h"

namespace phongfit {

// A stride records at the recorded n over this factor (or at the estimate, if broader).
inline constexpr double kBroadStride = 4;

// Whether a round's material `m`, recorded at exponent `recordedN`, strides: its n free and
// unresolved by a factor 3 (standard error at least 2 n), its lobe standing out (ks at least 3
// standard errors, over the channels' means), its estimate broader than its recording.
bool stridesBroader(const MaterialFit& m, double recordedN);

// `next` (where the next round would record) with the n of each material of `solved` that strides
// from `recorded` at min(its estimate, recorded n / kBroadStride); nullopt where none strides.
std::optional<std::vector<PhongMaterial>> broadStride(const std::vector<MaterialFit>& solved,
                                                      const std::vector<PhongMaterial>& recorded,
                                                      std::vector<PhongMaterial> next);

}  // namespace phongfit
