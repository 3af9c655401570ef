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
    record_.vertices.insert(record_.vertices.end(), vertices.begin(), vertices.end());
}

void PathSetFilm::Sample::drop() {
    record_.terms.resize(termsBefore_);
    record_.vertices.resize(verticesBefore_);
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
        for (const PathTerm& term : record.terms) {
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
    // while each tile's record is freed once copied (mapped records leave the resident set at
    // once, the small ones from the heap are handed back to the system every sixteenth of the
    // paths): the peak stays near one copy of the paths, not two.
    const std::size_t trimEvery = std::max<std::size_t>(
        (set.terms.size() * sizeof(PathTerm) + set.vertices.size() * sizeof(PathVertex)) / 16,
        std::size_t(1) << 20);
    std::size_t freed = 0;
    for (TileRecord& record : tiles_) {
        for (PathTerm term : record.terms) {
            const std::uint32_t p = term.pixel;
            const auto first = record.vertices.begin() + term.firstVertex;
            std::copy(first, first + term.vertexCount, set.vertices.begin() + nextVertex[p]);
            term.firstVertex = nextVertex[p];
            nextVertex[p] += term.vertexCount;
            term.constant = (term.constant.cast<double>() * rescale(p)).cast<float>();
            set.terms[nextTerm[p]++] = term;
        }
        freed += heapCapacityBytes(record.terms) + heapCapacityBytes(record.vertices);
        record = {};
        if (freed >= trimEvery) {
            malloc_trim(0);
            freed = 0;
        }
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
