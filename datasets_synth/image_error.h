// How far a noisy render is from a reference, over all pixels and the three channels.
#pragma once

#include <vector>

namespace phongfit {

struct ImageError {
    double rmse = 0;    // sqrt(mean((x - ref)^2))
    double relmse = 0;  // mean((x - ref)^2 / (ref^2 + kRelMseEpsilon))
};

// Keeps relMSE finite on black pixels (the background of the sphere scenes).
inline constexpr double kRelMseEpsilon = 1e-2;

// `image` and `reference` hold 3 floats per pixel, the same count.
ImageError imageError(const std::vector<float>& image, const std::vector<float>& reference);

}  // namespace phongfit
