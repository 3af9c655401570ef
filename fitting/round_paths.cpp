#include "round_paths.h"

namespace phongfit {

std::size_t recordedBytes(const std::vector<PathSet>& sets) {
    std::size_t bytes = 0;
    for (const PathSet& p : sets)
        bytes += p.terms.size() * sizeof(PathTerm) + p.vertices.size() * sizeof(PathVertex) +
                 p.background.size() * sizeof(Color<float>) +
                 (p.pixelStart.size() + p.pixelPaths.size()) * sizeof(std::uint32_t) +
                 p.groups.size() * sizeof(PathGroups);
    return bytes;
}

}  // namespace phongfit
