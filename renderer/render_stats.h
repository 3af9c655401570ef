// What a pass of the tile loop (tile_loop.h) reports, for an image and for a path recording alike.
#pragma once

#include <cstdint>
#include <vector>

namespace phongfit {

// A sample dropped for a non-finite value, and where on its path the value arose.
struct NonFiniteSample {
    int x = 0, y = 0;  // pixel
    int sample = 0;    // index within the pixel
    int depth = 0;     // path vertex, Mitsuba's count (1 = the surface the camera sees)
    int bsdf = -1;     // Scene::bsdfs index of the surface there; -1: the path had left the scene
};

struct RenderStats {
    double seconds = 0;
    std::uint64_t rays = 0;
    std::uint64_t samples = 0;  // pixel samples kept
    int spp = 0;                // requested
    bool interrupted = false;
    std::uint64_t nonFinite = 0;  // samples dropped: NaN, or infinite or beyond float range
    std::vector<NonFiniteSample> nonFiniteFirst;  // the first few, by pixel then sample
};

}  // namespace phongfit
