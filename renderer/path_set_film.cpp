#include "path_set_film.h"

#include <malloc.h>

#include <algorithm>

namespace phongfit {

PathSetFilm::PathSetFilm(int width, int height, std::vector<int> paths, std::size_t tiles)
    : width_(width),
      height_(height),
      paths_(std::move(paths)),
      background_(paths_.size(), Color3::Zero()),
      kept_(paths_.size(), 0),
      tiles_(tiles) {}

PathSetFilm::Sample::Sample(PathSetFilm& film, std::size_t tile, std::uint32_t pixel)
    : film_(film),
      record_(film.tiles_[tile]),
      pixel_(pixel),
      scale_(1.0 / film.paths_[pixel]),
      termsBefore_(record_.terms.size()),
      verticesBefore_(record_.vertices.size()),
      backgroundBefore_(film.background_[pixel]) {}

void PathSetFilm::Sample::add(const Color3& c, std::span<const PathVertex> vertices) {
    if (vertices.empty()) {
        film_.background_[pixel_] += c * scale_;
        return;
    }
    record_.terms.push_back(PathTerm{pixel_, std::uint32_t(record_.vertices.size()),
                                     std::uint32_t(vertices.size()), (c * scale_).cast<float>()});
    record_.vertices.append(vertices);
}

void PathSetFilm::Sample::drop() {
    record_.terms.truncate(termsBefore_);
    record_.vertices.truncate(verticesBefore_);
    film_.background_[pixel_] = backgroundBefore_;
}

PathSet PathSetFilm::assemble(int spp, int slots) {
    const std::size_t pixels = paths_.size();
    // Terms were scaled by 1 / paths; a pixel that kept fewer is rescaled to their mean (a factor
    // of 1 changes no bit).
    const auto rescale = [&](std::size_t p) {
        return kept_[p] > 0 && kept_[p] != std::uint32_t(paths_[p]) ? double(paths_[p]) / kept_[p]
                                                                    : 1.0;
    };

    PathSet set;
    set.width = width_;
    set.height = height_;
    set.spp = spp;
    set.slots = slots;
    set.background.resize(pixels);
    for (std::size_t p = 0; p < pixels; ++p)
        set.background[p] = (background_[p] * rescale(p)).cast<float>();
    background_ = {};
    if (std::any_of(kept_.begin(), kept_.end(),
                    [&](std::uint32_t k) { return k != std::uint32_t(spp); }))
        set.pixelPaths = kept_;

    // A counting sort by pixel, stable: a pixel lies in one tile, whose record holds its terms in
    // the order they were traced, so they keep it. Vertices follow their terms.
    set.pixelStart.assign(pixels + 1, 0);
    std::vector<std::uint32_t> nextVertex(pixels + 1, 0);
    for (const TileRecord& record : tiles_)
        for (std::size_t i = 0; i < record.terms.size(); ++i) {
            const PathTerm& term = record.terms[i];
            ++set.pixelStart[term.pixel + 1];
            nextVertex[term.pixel + 1] += term.vertexCount;
        }
    for (std::size_t p = 0; p < pixels; ++p) {
        set.pixelStart[p + 1] += set.pixelStart[p];
        nextVertex[p + 1] += nextVertex[p];
    }
    set.terms.resize(set.pixelStart[pixels]);
    set.vertices.resize(nextVertex[pixels]);
    std::vector<std::uint32_t> nextTerm(set.pixelStart.begin(), set.pixelStart.end() - 1);
    // The set's pages become resident as they are written (DefaultInitAllocator), in tile order,
    // while each record hands back its blocks once copied (mapped ones leave the resident set at
    // once, any from the heap are handed back to the system every sixteenth of the paths): the
    // peak stays near one copy of the paths, not two.
    const std::size_t trimEvery = std::max<std::size_t>(
        (set.terms.size() * sizeof(PathTerm) + set.vertices.size() * sizeof(PathVertex)) / 16,
        std::size_t(1) << 20);
    std::size_t heapFreed = 0;
    const auto handBack = [&](TileRecord& record, std::size_t terms, std::size_t vertices) {
        heapFreed += record.terms.releaseBefore(terms) + record.vertices.releaseBefore(vertices);
        if (heapFreed >= trimEvery) {
            malloc_trim(0);
            heapFreed = 0;
        }
    };
    for (TileRecord& record : tiles_) {
        for (std::size_t i = 0; i < record.terms.size(); ++i) {
            PathTerm term = record.terms[i];
            const std::uint32_t p = term.pixel;
            // Vertices follow their terms in a record: those before this term's end are copied.
            const std::size_t copied = std::size_t(term.firstVertex) + term.vertexCount;
            for (std::uint32_t v = 0; v < term.vertexCount; ++v)
                set.vertices[nextVertex[p] + v] = record.vertices[term.firstVertex + v];
            term.firstVertex = nextVertex[p];
            nextVertex[p] += term.vertexCount;
            term.constant = (term.constant.cast<double>() * rescale(p)).cast<float>();
            set.terms[nextTerm[p]++] = term;
            if ((i + 1) % BlockArray<PathTerm>::kBlock == 0) handBack(record, i + 1, copied);
        }
        handBack(record, std::size_t(-1), std::size_t(-1));
    }
    tiles_.clear();
    return set;
}

double PathSetFilm::peakBytes(std::size_t pixels, double terms, double vertices) {
    // Per pixel: paths, background and kept count here, the background in double while tracing;
    // background, pixelStart and two cursors in assembly. Terms and vertices: once in the tiles'
    // records, once in the set.
    const double perPixel = sizeof(int) + sizeof(Color3) + sizeof(std::uint32_t) +
                            sizeof(Color<float>) + 3 * sizeof(std::uint32_t);
    return double(pixels) * perPixel +
           2 * (terms * sizeof(PathTerm) + vertices * sizeof(PathVertex));
}

}  // namespace phongfit
