// One observed image as the fitter sees it: plain arrays, so the fitter does not depend on how
// images are read (EXR, PNG, masks).
#pragma once

#include <cstdint>
#include <vector>

namespace phongfit {

struct Observation {
    int width = 0, height = 0;
    std::vector<float> rgb;  // 3 per pixel, row-major (pixel y * width + x), linear
    std::vector<std::uint8_t>
        valid;                  // per pixel, 0 = left out (mask, saturation); empty = all valid
    std::vector<float> weight;  // per pixel, multiplies the residual; empty = all 1
};

}  // namespace phongfit
