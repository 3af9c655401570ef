#include "envmap_file.h"

#include <fmt/format.h>

#include <cmath>

#include "error.h"

namespace phongfit {

std::shared_ptr<const Image> loadEnvironmentMap(const std::string& path,
                                                const std::string& context) {
    Image map;
    try {
        map = readImage(path);
    } catch (const Error& e) {
        throw Error(fmt::format("{}: envmap: {}", context, e.what()));
    }
    if (map.width != 2 * map.height)
        throw Error(
            fmt::format("{}: envmap '{}' is {}x{} (allowed: a lat-long map twice as wide "
                        "as high, e.g. 1024x512)",
                        context, path, map.width, map.height));
    for (int y = 0; y < map.height; ++y)
        for (int x = 0; x < map.width; ++x)
            for (int c = 0; c < 3; ++c) {
                const float v = map.rgb[3 * map.index(x, y) + c];
                if (!std::isfinite(v) || v < 0)
                    throw Error(
                        fmt::format("{}: envmap '{}' has texel ({}, {}) channel {} = {} "
                                    "(allowed: finite radiance >= 0)",
                                    context, path, x, y, "RGB"[c], v));
            }
    return std::make_shared<const Image>(std::move(map));
}

}  // namespace phongfit
