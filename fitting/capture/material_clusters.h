// The materials of an object with several (`fit --capture --albedo per-pixel --materials K`).
#pragma once

#include <cstdint>
#include <vector>

#include "albedo_map_fit.h"

namespace phongfit {

// Materials by k-means on the albedo map of one shared lobe (the lobe taken out, which a
// Lambertian albedo would keep as a grey sheen where highlights fall): chromaticity and
// kBrightnessWeight times log brightness (clamped to its 1st-99th percentiles), so that shading
// left in the albedo, and a few black pixels, weigh less than colour. Only fitted pixels take
// part; the others are material 0. Seeded: the same capture gives the same materials. Numbered by
// brightness, darkest first.
// Throws Error if fewer pixels were fitted than there are materials.
std::vector<std::uint8_t> clusterMaterials(const AlbedoMapFit& shared, int materials);

}  // namespace phongfit
