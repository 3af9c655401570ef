// The lat-long radiance map of an `envmap` emitter, read and checked: any image readImage reads
// (EXR scanline or tiled, mip-mapped files at their full resolution, half or float), twice as
// wide as high, every texel finite and nonnegative.
#pragma once

#include <memory>
#include <string>

#include "image.h"

namespace phongfit {

// `context` (the scene file, line and element) starts every error message.
std::shared_ptr<const Image> loadEnvironmentMap(const std::string& path,
                                                const std::string& context);

}  // namespace phongfit
