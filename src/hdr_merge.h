// Bracketed 8-bit exposures of one scene with an unknown camera response, merged to one linear HDR
// image (Debevec & Malik 1997, through OpenCV's CalibrateDebevec and MergeDebevec).
#pragma once

#include <string>
#include <vector>

#include "image.h"

namespace phongfit {

// `seconds`: exposure times, one per image, in the same order. Linear up to one scale
// factor. Throws Error naming the file or value: fewer than two images, a time that is not finite
// and > 0, an image that is not 8-bit PNG/JPEG/TIFF content or not the first one's size.
Image mergeExposures(const std::vector<std::string>& images, const std::vector<double>& seconds);

}  // namespace phongfit
