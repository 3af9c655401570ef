#include "path_growth.h"

#include <limits>

#include "path_importance.h"

namespace phongfit {

std::vector<std::vector<std::uint32_t>> pathsPerPixel(const std::vector<PathSet>& sets) {
    std::vector<std::vector<std::uint32_t>> paths;
    for (const PathSet& s : sets)
        paths.push_back(!s.pixelPaths.empty()
                            ? s.pixelPaths
                            : std::vector<std::uint32_t>(std::size_t(s.width) * s.height,
                                                         std::uint32_t(s.spp)));
    return paths;
}

double weighedPathVariance(const std::vector<std::vector<float>>& importance,
                           const std::vector<std::vector<std::uint32_t>>& paths) {
    double variance = 0;
    for (std::size_t v = 0; v < importance.size(); ++v)
        for (std::size_t p = 0; p < importance[v].size(); ++p)
            if (importance[v][p] > 0 && paths[v][p] > 0)
                variance += double(importance[v][p]) * importance[v][p] / paths[v][p];
    return variance;
}

std::vector<std::vector<std::uint32_t>> plannedPaths(
    const std::vector<std::vector<float>>& importance,
    const std::vector<std::vector<std::uint32_t>>& base, double pathFactor) {
    std::vector<std::vector<std::uint32_t>> paths = base;
    if (!(pathFactor > 1)) return paths;
    for (std::size_t v = 0; v < paths.size(); ++v) {
        double baseSum = 0;
        for (std::size_t p = 0; p < paths[v].size(); ++p)
            if (importance[v][p] > 0) baseSum += base[v][p];
        const std::vector<int> extra =
            allocatePaths(importance[v], (pathFactor - 1) * baseSum, kMostExtraPaths);
        for (std::size_t p = 0; p < paths[v].size(); ++p) paths[v][p] += std::uint32_t(extra[p]);
    }
    return paths;
}

double mostPathGain(const std::vector<std::vector<float>>& importance,
                    const std::vector<std::vector<std::uint32_t>>& base, double pathFactor) {
    std::vector<std::vector<std::uint32_t>> capped = base;
    for (std::size_t v = 0; v < capped.size(); ++v)
        for (std::size_t p = 0; p < capped[v].size(); ++p)
            if (importance[v][p] > 0) capped[v][p] += kMostExtraPaths;
    const double now = weighedPathVariance(importance, plannedPaths(importance, base, pathFactor)),
                 most = weighedPathVariance(importance, capped);
    return most > 0 ? now / most : std::numeric_limits<double>::infinity();
}

}  // namespace phongfit
