#include "path_growth.h"

#include <limits>

#include "path_importance.h"

namespace phongfit {

std::vector<PixelPaths> pathsPerPixel(const std::vector<PathSet>& sets) {
    std::vector<PixelPaths> paths;
    for (const PathSet& s : sets) paths.push_back({std::uint32_t(s.spp), s.pixelPaths});
    return paths;
}

double mostPathGain(const std::vector<std::vector<float>>& importance,
                    const std::vector<PixelPaths>& base, double pathFactor) {
    // Summed pixel by pixel, without a copy of the counts: the fit's state is held to 200 bytes
    // a used pixel (docs/design/fitter.md, "Memory").
    double now = 0, most = 0;
    for (std::size_t v = 0; v < importance.size(); ++v) {
        const std::vector<float>& weights = importance[v];
        std::vector<int> extra;
        if (pathFactor > 1) {
            double baseSum = 0;
            for (std::size_t p = 0; p < weights.size(); ++p)
                if (weights[p] > 0) baseSum += base[v].at(p);
            extra = allocatePaths(weights, (pathFactor - 1) * baseSum, kMostExtraPaths);
        }
        for (std::size_t p = 0; p < weights.size(); ++p) {
            if (!(weights[p] > 0)) continue;
            const double squared = double(weights[p]) * weights[p];
            const std::uint32_t paths =
                base[v].at(p) + (extra.empty() ? 0u : std::uint32_t(extra[p]));
            if (paths > 0) now += squared / paths;
            most += squared / (base[v].at(p) + kMostExtraPaths);
        }
    }
    return most > 0 ? now / most : std::numeric_limits<double>::infinity();
}

}  // namespace phongfit
