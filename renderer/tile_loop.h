// The one loop over passes, tiles, pixels and samples that rendering and path recording share (as
// pbrt-v4's ImageTileIntegrator::Render). What differs, what is kept of a sample, is a film the
// loop feeds (rgb_film.h, path_set_film.h); the policies are written once, here:
// - every random number is keyed by (seed, pixel, sample, dimension), and a pixel's samples arrive
//   in order, so results are bit-identical for a seed whatever the thread count;
// - passes over the whole film, so a stop leaves every pixel with samples: the first pass (one
//   sample per pixel) always completes; later passes grow to a pass of samples / 8 and end at the
//   next tile once `stop` says so;
// - a sample whose value is not representable in float is dropped whole, counted, and replayed to
//   find the vertex where it arose.
#pragma once

#include <tbb/blocked_range.h>
#include <tbb/combinable.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <span>
#include <vector>

#include "camera.h"
#include "film_window.h"
#include "path_integrator.h"
#include "progress.h"
#include "render_stats.h"

namespace phongfit {

struct Tile {
    int x0, y0, x1, y1;
    int pixels() const { return (x1 - x0) * (y1 - y0); }
};

// 16 x 16 tiles in row-major order; films number their tiles by this list.
std::vector<Tile> makeTiles(int width, int height);

// Where on the film a pixel sample lands, from its random dimensions 0 and 1.
Vec2d filmPosition(const SensorDesc& sensor, int x, int y, double u0, double u1);

// Whether a sample's value stays finite in float, not only in double.
bool representable(const Color3& c);

// Replays a dropped sample to find the vertex at which its sum stopped being representable.
NonFiniteSample diagnoseNonFinite(const PathIntegrator& integrator, const Ray& ray,
                                  const PixelSampler& rng, int x, int y, int sample);

// Adds `s` to `list`, which keeps the first few in path order whatever order they arrive in.
void keepFirstNonFinite(std::vector<NonFiniteSample>& list, const NonFiniteSample& s);

template <typename F>
void runInArena(int threads, F&& f) {
    tbb::task_arena arena(threads > 0 ? threads : tbb::task_arena::automatic);
    arena.execute(std::forward<F>(f));
}

struct TileLoop {
    const PathIntegrator& integrator;
    const Camera& camera;
    const SensorDesc& sensor;
    FilmWindow window;  // what is traced; its films are this size
    PixelSamplerType pixelSampler = PixelSamplerType::Independent;
    std::uint64_t seed = 0;
    int threads = 0;               // 0: all hardware threads
    int samples = 0;               // the most any pixel takes: the passes run up to it
    std::function<bool()> stop;    // polled at tile boundaries after the first pass, and per pass
    Progress* progress = nullptr;  // advanced per tile by the samples traced, if given
};

namespace detail {
// Sums a sample's contributions for the loop's checks, passing them on to the film.
template <typename FilmSample>
struct SummingSink {
    FilmSample& film;
    Color3 sum = Color3::Zero();
    void add(const Color3& c, std::span<const PathVertex> vertices) {
        sum += c;
        film.add(c, vertices);
    }
};

// The tiles with samples in [s0, s1), the most first. Threads take them in this order, one at a
// time: where a fit's recording spends most of its paths in a few tiles' pixels, those start
// first instead of ending a pass on one thread.
template <typename Film>
std::vector<std::size_t> passOrder(const std::vector<Tile>& tiles, const FilmWindow& window,
                                   const Film& film, int s0, int s1) {
    std::vector<std::uint64_t> work(tiles.size(), 0);
    std::vector<std::size_t> order;
    for (std::size_t t = 0; t < tiles.size(); ++t) {
        for (int y = tiles[t].y0; y < tiles[t].y1; ++y)
            for (int x = tiles[t].x0; x < tiles[t].x1; ++x) {
                const int n = film.samples(std::uint32_t(y) * window.width + std::uint32_t(x));
                work[t] += std::uint64_t(std::clamp(n, s0, s1) - s0);
            }
        if (work[t] > 0) order.push_back(t);
    }
    std::stable_sort(order.begin(), order.end(),
                     [&](std::size_t a, std::size_t b) { return work[a] > work[b]; });
    return order;
}
}  // namespace detail

// Feeds `film`, which provides, for pixel p = y * width + x of the loop's window (x, y from its
// corner):
//   int samples(std::uint32_t p) const: how many samples p takes in all (at most loop.samples);
//   startSample(std::size_t tile, std::uint32_t p, int s): a sink for sample s of p in tile `tile`
//     (an index into makeTiles), add(const Color3&, std::span<const PathVertex>) as the
//     integrator calls it, then keep(const Color3& value) or drop().
// Each pixel lies in one tile, so a film may write its per-pixel state without locks.
template <typename Film>
RenderStats traceTiles(const TileLoop& loop, Film& film) {
    const auto start = std::chrono::steady_clock::now();
    const FilmWindow& window = loop.window;
    const std::vector<Tile> tiles = makeTiles(window.width, window.height);
    tbb::combinable<std::uint64_t> rays([] { return std::uint64_t(0); });
    tbb::combinable<std::uint64_t> kept([] { return std::uint64_t(0); });
    tbb::combinable<std::uint64_t> dropped([] { return std::uint64_t(0); });
    tbb::combinable<std::vector<NonFiniteSample>> droppedFirst;
    const auto stopRequested = [&] { return loop.stop && loop.stop(); };

    bool stopped = false;
    runInArena(loop.threads, [&] {
        for (int s0 = 0, passSize = 1; s0 < loop.samples && !stopped;
             s0 += passSize, passSize = std::min(2 * passSize, std::max(1, loop.samples / 8))) {
            const int s1 = std::min(loop.samples, s0 + passSize);
            const bool stoppable = s0 > 0;
            const std::vector<std::size_t> order = detail::passOrder(tiles, window, film, s0, s1);
            std::atomic<std::size_t> next{0};
            tbb::parallel_for(
                tbb::blocked_range<int>(0, tbb::this_task_arena::max_concurrency(), 1),
                [&](const auto&) {
                    std::uint64_t& rayCount = rays.local();
                    for (std::size_t i = next++; i < order.size(); i = next++) {
                        if (stoppable && stopRequested()) return;
                        const std::size_t t = order[i];
                        const Tile& tile = tiles[t];
                        std::uint64_t traced = 0;
                        for (int y = window.y0 + tile.y0; y < window.y0 + tile.y1; ++y)
                            for (int x = window.x0 + tile.x0; x < window.x0 + tile.x1; ++x) {
                                const std::uint32_t p =
                                    std::uint32_t(y - window.y0) * window.width +
                                    std::uint32_t(x - window.x0);
                                const PixelSampler rng(
                                    loop.pixelSampler, loop.seed,
                                    std::uint32_t(y) * loop.camera.width() + std::uint32_t(x));
                                const int end = std::min(s1, film.samples(p));
                                for (int s = s0; s < end; ++s, ++traced) {
                                    const Vec2d u = rng.get2D(s, 0);
                                    const Vec2d at = filmPosition(loop.sensor, x, y, u.x(), u.y());
                                    const Ray ray = loop.camera.generateRay(at.x(), at.y());
                                    auto sample = film.startSample(t, p, s);
                                    detail::SummingSink<decltype(sample)> sink{sample};
                                    loop.integrator.trace(ray, rng, s, sink, rayCount);
                                    if (representable(sink.sum)) {
                                        sample.keep(sink.sum);
                                        ++kept.local();
                                        continue;
                                    }
                                    sample.drop();
                                    ++dropped.local();
                                    keepFirstNonFinite(
                                        droppedFirst.local(),
                                        diagnoseNonFinite(loop.integrator, ray, rng, x, y, s));
                                }
                            }
                        if (loop.progress) loop.progress->advance(traced);
                    }
                });
            stopped = stopRequested();
        }
    });

    RenderStats stats;
    stats.rays = rays.combine(std::plus<>());
    stats.samples = kept.combine(std::plus<>());
    stats.interrupted = stopped;
    stats.nonFinite = dropped.combine(std::plus<>());
    droppedFirst.combine_each([&](const std::vector<NonFiniteSample>& list) {
        for (const NonFiniteSample& s : list) keepFirstNonFinite(stats.nonFiniteFirst, s);
    });
    stats.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return stats;
}

}  // namespace phongfit
