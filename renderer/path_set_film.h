// The film a path recording is made on (path_set.h): per pixel the background, in double until the
// end, and the terms of the paths that reach a fitted material, each scaled to the pixel's mean.
// What is summed while tracing is kept for the pixels that take paths alone (a fit's window holds
// pixels it does not record).
// Fed by the tile loop (tile_loop.h); tiles record on their own, and assemble() sorts the terms
// into pixel order.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <span>
#include <vector>

#include "block_array.h"
#include "path_set.h"

namespace phongfit {

class PathSetFilm {
    struct TileRecord {
        // In blocks: the records of all tiles grow side by side, and are copied into the set
        // block by block (block_array.h).
        BlockArray<PathTerm> terms;       // in the order traced;
        BlockArray<PathVertex> vertices;  // firstVertex into these
    };

    // What a pixel's ringed samples (its first `ringed`) hold apart from the others: per group
    // (PathGroups; kRinged, kSampled) its kept samples' count, and the sum and squares of their
    // values (the mean over channels), for the group's variance. The counts lie together, after
    // the doubles: one count beside each group's doubles would pad the part to 80 bytes.
    static constexpr std::size_t kRinged = 0, kSampled = 1;
    struct RingedPart {
        std::array<double, 2> sum{}, squares{};
        Color3 background = Color3::Zero();
        std::array<std::uint32_t, 2> kept{};
        std::uint32_t terms = 0;
    };
    static_assert(sizeof(RingedPart) == 72);

public:
    // `paths`: per pixel, how many samples it takes; `tiles`: how many tiles feed the film;
    // `ringed`: how many of a pixel's first samples ring area lights (the rest sample them).
    PathSetFilm(int width, int height, std::vector<int> paths, std::size_t tiles,
                std::uint32_t ringed = 0);

    int samples(std::uint32_t pixel) const { return paths_[pixel]; }

    class Sample {
    public:
        Sample(PathSetFilm& film, std::size_t tile, std::uint32_t pixel, int sample);
        void add(const Color3& c, std::span<const PathVertex> vertices);
        void keep(const Color3& value);
        // Undoes everything the sample added.
        void drop();

    private:
        PathSetFilm& film_;
        TileRecord& record_;
        std::uint32_t pixel_;
        std::uint32_t at_;  // the pixel's index among those that take paths
        bool ringed_;       // one of the pixel's ringed samples
        double scale_;      // 1 / the pixel's paths
        std::size_t termsBefore_, verticesBefore_;
        Color3 backgroundBefore_;
    };
    Sample startSample(std::size_t tile, std::uint32_t pixel, int sample) {
        return {*this, tile, pixel, sample};
    }

    // The path set, terms sorted by pixel, each pixel the mean of the samples it kept (fewer
    // than it takes after a stop or a dropped sample). Consumes the film.
    PathSet assemble(int spp, int slots);

    // Bytes a recording holding `terms` terms with `vertices` vertices in all needs at its peak: an
    // upper bound, as if the tiles' records and the assembled set coexisted in full (assemble
    // frees the records as it goes: about 1.0x the paths measured, see RecordingMemory); `ringed`:
    // whether some samples ring area lights.
    static double peakBytes(std::size_t pixels, double terms, double vertices, bool ringed);

private:
    // Terms were scaled by 1 / paths; a pixel that kept fewer is rescaled to their mean (a factor
    // of 1 changes no bit).
    double rescale(std::size_t pixel) const;
    // Pixel p's index among the pixels that take paths, kNotTraced where it takes none.
    static constexpr std::uint32_t kNotTraced = ~std::uint32_t(0);
    // Fills set.background and, where some pixel kept both groups, set.groups; returns per pixel
    // that takes paths the factors of its ringed and its sampled terms: where it kept both, each
    // group's mean weighted by the inverse of its variance, pooled over the pixel's neighbours
    // (not its own samples: weights that depend on them would bias it); else rescale's. Empty
    // where no pixel kept both. Consumes the backgrounds and ringed parts, handing them back row
    // by row as the rows still to come no longer read them.
    std::vector<std::array<double, 2>> weigh(PathSet& set);
    // The factor of pixel p's ringed or sampled terms: from weigh's, else rescale's (1 where
    // it takes no paths, and has neither terms nor background).
    double factor(const std::vector<std::array<double, 2>>& factors, std::size_t p,
                  bool ringed) const;
    // Copies a tile's record into `set` at the pixels' cursors, pixel by pixel and each pixel's
    // terms in the order traced, handing back (through `handedBack`, with the bytes that went to
    // the heap) what has been copied as it goes. The record holds its passes one after the other,
    // each over the tile's pixels: copied in that order, every pixel of the tile kept a page of
    // each of the set's arrays partly written, and resident, at once; pixel by pixel the set is
    // written front to back.
    void copyRecord(TileRecord& record, PathSet& set, std::vector<std::uint32_t>& nextTerm,
                    std::vector<std::uint32_t>& nextVertex,
                    const std::vector<std::array<double, 2>>& factors,
                    const std::function<void(std::size_t)>& handedBack) const;

    int width_, height_;
    std::vector<int> paths_;
    std::vector<std::uint32_t> traced_;  // per pixel, its index among those that take paths
    // Per pixel that takes paths (traced_): the background, summed in double in sample order, as
    // traced, and where ringed_ > 0 the ringed part.
    BlockArray<Color3> background_;
    BlockArray<RingedPart> ringedParts_;
    std::vector<std::uint32_t> kept_;  // per pixel
    std::uint32_t ringed_;
    std::vector<TileRecord> tiles_;
};

}  // namespace phongfit
