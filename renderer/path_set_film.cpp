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

// The least weight either group of a pixel's paths gets (PathGroups): every path keeps a share,
// so its weight can be undone (replayPathCovariance).
constexpr double kLeastGroupWeight = 1e-3;

// How far the neighbours a pixel's group variances are pooled over may reach: 1 (3 x 3), then 2.
constexpr int kMostPoolRadius = 2;

}  // namespace

PathSetFilm::PathSetFilm(int width, int height, std::vector<int> paths, std::size_t tiles,
                         std::uint32_t ringed)
    : width_(width),
      height_(height),
      paths_(std::move(paths)),
      traced_(paths_.size(), kNotTraced),
      kept_(paths_.size(), 0),
      ringed_(ringed),
      tiles_(tiles) {
    std::uint32_t count = 0;
    for (std::size_t p = 0; p < paths_.size(); ++p)
        if (paths_[p] > 0) traced_[p] = count++;
    for (std::uint32_t i = 0; i < count; ++i) {
        background_.push_back(Color3::Zero());
        if (ringed > 0) ringedParts_.push_back(RingedPart{});
    }
}

PathSetFilm::Sample::Sample(PathSetFilm& film, std::size_t tile, std::uint32_t pixel, int sample)
    : film_(film),
      record_(film.tiles_[tile]),
      pixel_(pixel),
      at_(film.traced_[pixel]),
      ringed_(std::uint32_t(sample) < film.ringed_),
      scale_(1.0 / film.paths_[pixel]),
      termsBefore_(record_.terms.size()),
      verticesBefore_(record_.vertices.size()),
      backgroundBefore_(ringed_ ? film.ringedParts_[at_].background : film.background_[at_]) {}

void PathSetFilm::Sample::add(const Color3& c, std::span<const PathVertex> vertices) {
    if (vertices.empty()) {
        (ringed_ ? film_.ringedParts_[at_].background : film_.background_[at_]) += c * scale_;
        return;
    }
    record_.terms.push_back(PathTerm{pixel_, std::uint32_t(record_.vertices.size()),
                                     std::uint32_t(vertices.size()), (c * scale_).cast<float>()});
    record_.vertices.append(vertices);
}

void PathSetFilm::Sample::keep(const Color3& value) {
    ++film_.kept_[pixel_];
    if (film_.ringed_ == 0) return;
    RingedPart& part = film_.ringedParts_[at_];
    const std::size_t group = ringed_ ? kRinged : kSampled;
    const double y = value.mean();
    ++part.kept[group];
    part.sum[group] += y;
    part.squares[group] += y * y;
    if (ringed_) part.terms += std::uint32_t(record_.terms.size() - termsBefore_);
}

void PathSetFilm::Sample::drop() {
    record_.terms.truncate(termsBefore_);
    record_.vertices.truncate(verticesBefore_);
    (ringed_ ? film_.ringedParts_[at_].background : film_.background_[at_]) = backgroundBefore_;
}

double PathSetFilm::rescale(std::size_t p) const {
    return kept_[p] > 0 && kept_[p] != std::uint32_t(paths_[p]) ? double(paths_[p]) / kept_[p]
                                                                : 1.0;
}

std::vector<std::array<double, 2>> PathSetFilm::weigh(PathSet& set) {
    const std::size_t pixels = paths_.size();
    const auto keptBoth = [](const RingedPart& part) {
        return part.kept[kRinged] > 0 && part.kept[kSampled] > 0;
    };
    // Only ringed recordings whose pixels took more paths than they ring weight any: the others
    // keep rescale's factors, computed as the terms are copied (a vector of them would add 16
    // bytes a pixel to the recording's peak).
    bool weighted = false;
    for (std::size_t i = 0; i < ringedParts_.size() && !weighted; ++i)
        weighted = keptBoth(ringedParts_[i]);
    // A group's variance a path, pooled over the pixel's neighbours within `radius` that kept
    // two of its samples; negative where none did.
    const auto pooled = [&](int x, int y, int radius, std::size_t group) {
        double squares = 0, freedom = 0;
        for (int v = std::max(y - radius, 0); v <= std::min(y + radius, height_ - 1); ++v)
            for (int u = std::max(x - radius, 0); u <= std::min(x + radius, width_ - 1); ++u) {
                const std::uint32_t at =
                    traced_[std::size_t(v) * std::size_t(width_) + std::size_t(u)];
                if ((u == x && v == y) || at == kNotTraced) continue;
                const RingedPart& part = ringedParts_[at];
                const std::uint32_t kept = part.kept[group];
                if (kept < 2) continue;
                const double sum = part.sum[group];
                squares += std::max(part.squares[group] - sum * sum / kept, 0.0);
                freedom += kept - 1;
            }
        return freedom > 0 ? squares / freedom : -1.0;
    };
    const auto variance = [&](int x, int y, std::size_t group) {
        double v = -1;
        for (int radius = 1; radius <= kMostPoolRadius && v < 0; ++radius)
            v = pooled(x, y, radius, group);
        return v;
    };
    std::vector<std::array<double, 2>> factors(weighted ? ringedParts_.size() : 0);
    if (weighted) set.groups.assign(pixels, PathGroups{});
    set.background.resize(pixels);
    std::vector<std::uint32_t> rowStart(std::size_t(height_), 0);  // each row's first traced pixel
    std::uint32_t traced = 0;
    for (int y = 0; y < height_; ++y) {
        rowStart[std::size_t(y)] = traced;
        for (std::size_t p = std::size_t(y) * std::size_t(width_);
             p < std::size_t(y + 1) * std::size_t(width_); ++p) {
            const std::uint32_t at = traced_[p];
            if (at == kNotTraced) {
                set.background[p] = Color<float>::Zero();
                continue;
            }
            ++traced;
            const RingedPart* part = ringed_ > 0 ? &ringedParts_[at] : nullptr;
            if (weighted) {
                factors[at] = {rescale(p), rescale(p)};
                set.groups[p].ringedTerms = part->terms;
            }
            if (weighted && keptBoth(*part)) {
                const int x = int(p % std::size_t(width_));
                const double ringedVariance = variance(x, y, kRinged),
                             sampledVariance = variance(x, y, kSampled);
                // The ringed mean's weight, by the inverse of the variances of the two means;
                // where a variance is not known, the ringed mean's (the sampled paths are the
                // ones whose noise can be far larger).
                const double ringedKept = part->kept[kRinged], sampledKept = part->kept[kSampled];
                const double a = ringedVariance / ringedKept, b = sampledVariance / sampledKept;
                const double w =
                    ringedVariance < 0 || sampledVariance < 0 || !(a + b > 0)
                        ? 1 - kLeastGroupWeight
                        : std::clamp(b / (a + b), kLeastGroupWeight, 1 - kLeastGroupWeight);
                const double kept = double(kept_[p]);
                factors[at] = {paths_[p] * w / ringedKept, paths_[p] * (1 - w) / sampledKept};
                set.groups[p].ringedScale = float(w * kept / ringedKept);
                set.groups[p].sampledScale = float((1 - w) * kept / sampledKept);
            }
            Color3 background = background_[at] * factor(factors, p, false);
            if (part != nullptr)
                background = part->background * factor(factors, p, true) + background;
            set.background[p] = background.cast<float>();
        }
        // No later pixel reads this row's backgrounds, nor pools over rows more than
        // kMostPoolRadius above the next.
        background_.releaseBefore(traced);
        if (y + 1 >= kMostPoolRadius)
            ringedParts_.releaseBefore(rowStart[std::size_t(y + 1 - kMostPoolRadius)]);
    }
    background_ = {};
    ringedParts_ = {};
    return factors;
}

double PathSetFilm::factor(const std::vector<std::array<double, 2>>& factors, std::size_t p,
                           bool ringed) const {
    if (factors.empty() || traced_[p] == kNotTraced) return rescale(p);
    return factors[traced_[p]][ringed ? 0 : 1];
}

void PathSetFilm::copyRecord(TileRecord& record, PathSet& set, std::vector<std::uint32_t>& nextTerm,
                             std::vector<std::uint32_t>& nextVertex,
                             const std::vector<std::array<double, 2>>& factors,
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
        const std::uint32_t ringedEnd =
            set.pixelStart[p] + (set.groups.empty() ? 0 : set.groups[p].ringedTerms);
        for (RecordRun& run : runs) {
            for (; run.next < run.end && record.terms[run.next].pixel == p; ++run.next) {
                PathTerm term = record.terms[run.next];
                const double scale = factor(factors, p, nextTerm[p] < ringedEnd);
                for (std::uint32_t v = 0; v < term.vertexCount; ++v)
                    set.vertices[nextVertex[p] + v] = record.vertices[term.firstVertex + v];
                run.nextVertex = term.firstVertex + term.vertexCount;
                term.firstVertex = nextVertex[p];
                nextVertex[p] += term.vertexCount;
                term.constant = (term.constant.cast<double>() * scale).cast<float>();
                set.terms[nextTerm[p]++] = term;
            }
            // What the run has copied goes back a page at a time (a record holds a run a pass,
            // each holding its unreturned pages), each time from a page before where it went
            // back last (that page may have been partly unread then).
            if ((run.next - run.termsFreed) * sizeof(PathTerm) +
                    (run.nextVertex - run.verticesFreed) * sizeof(PathVertex) <
                page)
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
    const std::vector<std::array<double, 2>> factors = weigh(set);
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
        copyRecord(record, set, nextTerm, nextVertex, factors, handedBack);
        handedBack(record.terms.releaseBefore(std::size_t(-1)) +
                   record.vertices.releaseBefore(std::size_t(-1)));
    }
    tiles_.clear();
    return set;
}

double PathSetFilm::peakBytes(std::size_t pixels, double terms, double vertices, bool ringed) {
    // Per pixel: paths, its traced index, background and kept count here, the background in double
    // while tracing (an upper bound: the pixels that take no paths hold neither);
    // background, pixelStart and two cursors in assembly; with ringed samples, their part, the
    // terms' two factors and the set's groups. Terms and vertices: once in the tiles' records,
    // once in the set.
    const double perPixel =
        sizeof(int) + 2 * sizeof(std::uint32_t) + sizeof(Color3) + sizeof(Color<float>) +
        3 * sizeof(std::uint32_t) +
        (ringed ? sizeof(RingedPart) + sizeof(std::array<double, 2>) + sizeof(PathGroups) : 0);
    return double(pixels) * perPixel +
           2 * (terms * sizeof(PathTerm) + vertices * sizeof(PathVertex));
}

}  // namespace phongfit
