#include "path_set_film.h"

#include <malloc.h>

#include <algorithm>
#include <limits>

namespace phongfit {

namespace {

// A stretch of a tile's record whose pixels do not decrease, being copied into the set.
struct RecordRun {
    std::size_t begin, end;                 // terms
    std::size_t firstVertex;                // the run's
    std::size_t next, nextVertex;           // the first term, and vertex, not yet copied
    std::size_t termsFreed, verticesFreed;  // where the next hand-back starts
};

// The record's runs: its passes one after the other, each over the tile's pixels in order.
template <typename Terms>
std::vector<RecordRun> recordRuns(const Terms& terms) {
    std::vector<RecordRun> runs;
    for (std::size_t i = 0; i < terms.size(); ++i) {
        if (i > 0 && terms[i].pixel >= terms[i - 1].pixel) continue;
        if (!runs.empty()) runs.back().end = i;
        const std::size_t v = terms[i].firstVertex;
        runs.push_back({i, terms.size(), v, i, v, i, v});
    }
    return runs;
}

}  // namespace

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

double PathSetFilm::rescale(std::size_t p) const {
    return kept_[p] > 0 && kept_[p] != std::uint32_t(paths_[p]) ? double(paths_[p]) / kept_[p]
                                                                : 1.0;
}

void PathSetFilm::copyRecord(TileRecord& record, PathSet& set, std::vector<std::uint32_t>& nextTerm,
                             std::vector<std::uint32_t>& nextVertex,
                             const std::function<void(std::size_t)>& handedBack) const {
    const std::size_t page = detail::pageBytes();
    const std::size_t termsAPage = page / sizeof(PathTerm) + 1;
    const std::size_t verticesAPage = page / sizeof(PathVertex) + 1;
    std::vector<RecordRun> runs = recordRuns(record.terms);
    for (;;) {
        std::uint32_t p = std::numeric_limits<std::uint32_t>::max();
        for (const RecordRun& run : runs)
            if (run.next < run.end) p = std::min(p, record.terms[run.next].pixel);
        if (p == std::numeric_limits<std::uint32_t>::max()) return;
        const double scale = rescale(p);
        for (RecordRun& run : runs) {
            for (; run.next < run.end && record.terms[run.next].pixel == p; ++run.next) {
                PathTerm term = record.terms[run.next];
                for (std::uint32_t v = 0; v < term.vertexCount; ++v)
                    set.vertices[nextVertex[p] + v] = record.vertices[term.firstVertex + v];
                run.nextVertex = term.firstVertex + term.vertexCount;
                term.firstVertex = nextVertex[p];
                nextVertex[p] += term.vertexCount;
                term.constant = (term.constant.cast<double>() * scale).cast<float>();
                set.terms[nextTerm[p]++] = term;
            }
            // What the run has copied goes back a few pages at a time, each time from a page
            // before where it went back last (that page may have been partly unread then).
            if ((run.next - run.termsFreed) * sizeof(PathTerm) +
                    (run.nextVertex - run.verticesFreed) * sizeof(PathVertex) <
                4 * page)
                continue;
            handedBack(record.terms.releaseWithin(run.termsFreed, run.next) +
                       record.vertices.releaseWithin(run.verticesFreed, run.nextVertex));
            run.termsFreed = std::max(run.begin, run.next - std::min(run.next, termsAPage));
            run.verticesFreed =
                std::max(run.firstVertex, run.nextVertex - std::min(run.nextVertex, verticesAPage));
        }
    }
}

PathSet PathSetFilm::assemble(int spp, int slots) {
    const std::size_t pixels = paths_.size();
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
    // the order they were traced, so they keep it (copyRecord). Vertices follow their terms.
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
    // The set's pages become resident as they are written (DefaultInitAllocator) while the records
    // hand back what has been copied (mapped blocks and pages leave the resident set at once, any
    // from the heap are handed back to the system every sixteenth of the paths): the peak stays
    // near one copy of the paths, not two.
    const std::size_t trimEvery = std::max<std::size_t>(
        (set.terms.size() * sizeof(PathTerm) + set.vertices.size() * sizeof(PathVertex)) / 16,
        std::size_t(1) << 20);
    std::size_t heapFreed = 0;
    const auto handedBack = [&](std::size_t heap) {
        heapFreed += heap;
        if (heapFreed >= trimEvery) {
            malloc_trim(0);
            heapFreed = 0;
        }
    };
    for (TileRecord& record : tiles_) {
        copyRecord(record, set, nextTerm, nextVertex, handedBack);
        handedBack(record.terms.releaseBefore(std::size_t(-1)) +
                   record.vertices.releaseBefore(std::size_t(-1)));
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
