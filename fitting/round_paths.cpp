#include "round_paths.h"

namespace phongfit {

PathSet pool(const PathSet& a, const PathSet& b) {
    PathSet out;
    out.width = a.width;
    out.height = a.height;
    out.spp = a.spp + b.spp;
    out.slots = a.slots;
    const std::size_t pixels = a.background.size();
    out.background.resize(pixels);
    out.terms.reserve(a.terms.size() + b.terms.size());
    out.vertices.reserve(a.vertices.size() + b.vertices.size());
    out.pixelStart.reserve(pixels + 1);
    out.pixelStart.push_back(0);
    for (std::size_t p = 0; p < pixels; ++p) {
        out.background[p] = 0.5f * (a.background[p] + b.background[p]);
        for (const PathSet* set : {&a, &b}) {
            for (std::uint32_t t = set->pixelStart[p]; t < set->pixelStart[p + 1]; ++t) {
                PathTerm term = set->terms[t];
                const auto first = set->vertices.begin() + term.firstVertex;
                term.firstVertex = std::uint32_t(out.vertices.size());
                term.constant *= 0.5f;
                out.vertices.insert(out.vertices.end(), first, first + term.vertexCount);
                out.terms.push_back(term);
            }
        }
        out.pixelStart.push_back(std::uint32_t(out.terms.size()));
    }
    return out;
}

std::size_t recordedBytes(const std::vector<PathSet>& sets) {
    std::size_t bytes = 0;
    for (const PathSet& p : sets)
        bytes += p.terms.size() * sizeof(PathTerm) + p.vertices.size() * sizeof(PathVertex) +
                 p.background.size() * sizeof(Color<float>) +
                 p.pixelStart.size() * sizeof(std::uint32_t);
    return bytes;
}

const std::vector<PathSet>& RoundPaths::leastSquaresSets() {
    if (exact()) return *first_;
    if (pooled_.empty())
        for (std::size_t v = 0; v < first_->size(); ++v)
            pooled_.push_back(pool((*first_)[v], (*second_)[v]));
    return pooled_;
}

}  // namespace phongfit
