#include "renderer.h"

#include <fmt/format.h>
#include <tbb/blocked_range.h>
#include <tbb/combinable.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <tuple>

#include "defensive_sampler.h"
#include "error.h"
#include "interrupt.h"
#include "path_integrator.h"
#include "progress.h"

namespace phongfit {
namespace {

constexpr int kTileSize = 16;

struct Tile {
    int x0, y0, x1, y1;
    int pixels() const { return (x1 - x0) * (y1 - y0); }
};

std::vector<Tile> makeTiles(int width, int height) {
    std::vector<Tile> tiles;
    for (int y = 0; y < height; y += kTileSize)
        for (int x = 0; x < width; x += kTileSize)
            tiles.push_back(
                {x, y, std::min(x + kTileSize, width), std::min(y + kTileSize, height)});
    return tiles;
}

// Where on the film a pixel sample lands. Box: uniform over the pixel. Gaussian: the filter is
// importance-sampled (Box-Muller around the pixel centre), so every sample still belongs to one
// pixel with weight 1 and no splatting is needed (as pbrt-v4).
Vec2d filmPosition(const SensorDesc& sensor, int x, int y, double u0, double u1) {
    if (sensor.filter == SensorDesc::Filter::Box) return Vec2d(x + u0, y + u1);
    const double r = sensor.gaussianStddev * std::sqrt(-2 * std::log1p(-u0));
    return Vec2d(x + 0.5 + r * std::cos(2 * kPi * u1), y + 0.5 + r * std::sin(2 * kPi * u1));
}

std::uint32_t pixelIndex(int x, int y, int width) { return std::uint32_t(y) * width + x; }

struct RadianceSink {
    Color3 sum = Color3::Zero();
    void add(const Color3& c, std::span<const PathVertex>) { sum += c; }
};

// A sample must stay finite in the float image, not only in double.
bool representable(const Color3& c) {
    return (c.abs() <= double(std::numeric_limits<float>::max())).all();
}

// Replays a sample to find the vertex at which its sum stopped being representable.
struct DiagnosingSink {
    NonFiniteSample& where;  // gets depth and bsdf
    Color3 sum = Color3::Zero();
    int depth = 0, bsdf = -1;  // of the vertex being traced
    bool found = false;
    void vertex(int d, int b) { depth = d, bsdf = b; }
    void add(const Color3& c, std::span<const PathVertex>) {
        sum += c;
        if (found || representable(sum)) return;
        found = true;
        where.depth = depth;
        where.bsdf = bsdf;
    }
};

constexpr std::size_t kNonFiniteReported = 10;

bool pathOrder(const NonFiniteSample& a, const NonFiniteSample& b) {
    return std::tie(a.y, a.x, a.sample) < std::tie(b.y, b.x, b.sample);
}

// Keeps the first kNonFiniteReported samples in path order, whatever order they arrive in.
void keepFirst(std::vector<NonFiniteSample>& list, const NonFiniteSample& s) {
    list.insert(std::upper_bound(list.begin(), list.end(), s, pathOrder), s);
    if (list.size() > kNonFiniteReported) list.pop_back();
}

template <typename F>
void runInArena(int threads, F&& f) {
    tbb::task_arena arena(threads > 0 ? threads : tbb::task_arena::automatic);
    arena.execute(std::forward<F>(f));
}

}  // namespace

Renderer::Renderer(Scene scene)
    : scene_(std::move(scene)),
      geometry_(std::make_unique<EmbreeScene>(scene_)),
      lights_(std::make_unique<LightSet>(scene_, *geometry_)),
      camera_(scene_.sensor) {}

Renderer::~Renderer() = default;

int Renderer::effectiveMaxDepth(int requested) const {
    if (requested != -2) return requested;
    return scene_.integrator.type == "direct" ? 2 : scene_.integrator.maxDepth;
}

RenderResult Renderer::render(const RenderOptions& options) const {
    const int spp = options.spp > 0 ? options.spp : scene_.sensor.sampleCount;
    const auto sampler = makePhongSampler<double>(options.sampler);
    std::vector<PhongMaterial> materials;
    for (const BsdfDesc& b : scene_.bsdfs) materials.push_back(b.params);
    const PathIntegrator integrator(
        scene_, *geometry_, *lights_, materials, std::vector<int>(materials.size(), -1), *sampler,
        *sampler, {effectiveMaxDepth(options.maxDepth), scene_.integrator.rrDepth, options.mis});

    const int width = camera_.width(), height = camera_.height();
    const std::size_t pixels = std::size_t(width) * height;
    std::vector<double> sum(3 * pixels, 0.0), sumSq(3 * pixels, 0.0);
    std::vector<std::uint32_t> count(pixels, 0);
    tbb::combinable<std::uint64_t> rays([] { return std::uint64_t(0); });
    tbb::combinable<std::uint64_t> nonFinite([] { return std::uint64_t(0); });
    tbb::combinable<std::vector<NonFiniteSample>> nonFiniteFirst;
    const std::vector<Tile> tiles = makeTiles(width, height);

    // Passes over the whole image, so an interrupt leaves every pixel with samples: the first pass
    // (one sample per pixel) always completes; later passes grow to spp / 8 and stop at the next
    // tile on an interrupt. Each pixel is the mean of its own samples.
    Progress progress("render", std::uint64_t(spp) * pixels, "samples", options.quiet);
    const auto start = std::chrono::steady_clock::now();
    bool interrupted = false;
    for (int s0 = 0, passSize = 1; s0 < spp && !interrupted;
         s0 += passSize, passSize = std::min(2 * passSize, std::max(1, spp / 8))) {
        const int s1 = std::min(spp, s0 + passSize);
        const bool interruptible = s0 > 0;
        runInArena(options.threads, [&] {
            tbb::parallel_for(
                tbb::blocked_range<std::size_t>(0, tiles.size(), 1), [&](const auto& range) {
                    std::uint64_t& rayCount = rays.local();
                    for (std::size_t t = range.begin(); t != range.end(); ++t) {
                        if (interruptible && interruptRequested()) return;
                        const Tile& tile = tiles[t];
                        for (int y = tile.y0; y < tile.y1; ++y)
                            for (int x = tile.x0; x < tile.x1; ++x) {
                                const std::uint32_t p = pixelIndex(x, y, width);
                                const CounterRng rng(options.seed, p);
                                for (int s = s0; s < s1; ++s) {
                                    const Vec2d film = filmPosition(
                                        scene_.sensor, x, y, rng.uniform(s, 0), rng.uniform(s, 1));
                                    RadianceSink sink;
                                    integrator.trace(camera_.generateRay(film.x(), film.y()), rng,
                                                     s, sink, rayCount);
                                    if (!representable(sink.sum)) {
                                        ++nonFinite.local();
                                        NonFiniteSample where{x, y, s};
                                        DiagnosingSink diagnosis{where};
                                        std::uint64_t replayRays = 0;
                                        integrator.trace(camera_.generateRay(film.x(), film.y()),
                                                         rng, s, diagnosis, replayRays);
                                        keepFirst(nonFiniteFirst.local(), where);
                                        continue;
                                    }
                                    for (int c = 0; c < 3; ++c) {
                                        sum[3 * p + c] += sink.sum[c];
                                        sumSq[3 * p + c] += sink.sum[c] * sink.sum[c];
                                    }
                                    ++count[p];
                                }
                            }
                        progress.advance(std::uint64_t(s1 - s0) * tile.pixels());
                    }
                });
        });
        interrupted = interruptRequested();
    }
    progress.finish();

    RenderResult result;
    result.width = width;
    result.height = height;
    result.rgb.resize(3 * pixels);
    result.variance.resize(3 * pixels);
    result.sampleCount = count;
    for (std::size_t p = 0; p < pixels; ++p) {
        const double n = count[p];
        for (int c = 0; c < 3; ++c) {
            const double mean = n > 0 ? sum[3 * p + c] / n : 0;
            const double var =
                n > 1 ? std::max(0.0, sumSq[3 * p + c] / n - mean * mean) / (n - 1) : 0;
            result.rgb[3 * p + c] = float(mean);
            result.variance[3 * p + c] = float(var);
        }
        result.stats.samples += count[p];
    }
    result.stats.seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    result.stats.rays = rays.combine(std::plus<>());
    result.stats.nonFinite = nonFinite.combine(std::plus<>());
    nonFiniteFirst.combine_each([&](const std::vector<NonFiniteSample>& list) {
        for (const NonFiniteSample& s : list) keepFirst(result.stats.nonFiniteFirst, s);
    });
    result.stats.spp = spp;
    result.stats.interrupted = interrupted;
    return result;
}

namespace {

// One tile's recorded terms, pixels in the tile's row-major order.
struct TileRecord {
    std::vector<Color<float>> background;
    std::vector<std::uint32_t> termStart;  // per tile pixel, plus one
    std::vector<PathTerm> terms;
    std::vector<PathVertex> vertices;
};

struct RecordingSink {
    TileRecord& out;
    Color3& background;
    double scale;  // 1 / spp
    void add(const Color3& c, std::span<const PathVertex> vertices) {
        if (vertices.empty()) {
            background += c * scale;
            return;
        }
        out.terms.push_back(PathTerm{0, std::uint32_t(out.vertices.size()),
                                     std::uint32_t(vertices.size()), (c * scale).cast<float>()});
        out.vertices.insert(out.vertices.end(), vertices.begin(), vertices.end());
    }
};

// Counts what a path would record, keeping nothing.
struct CountingSink {
    std::uint64_t terms = 0, vertices = 0;
    void add(const Color3&, std::span<const PathVertex> v) {
        if (v.empty()) return;
        ++terms;
        vertices += v.size();
    }
};

// Bytes a recording needs at its peak (the tiles' records and the assembled set coexist), from a
// pilot of one path in each of up to 4096 pixels spread over the film.
double recordingBytes(const PathIntegrator& integrator, const Camera& camera,
                      const SensorDesc& sensor, std::uint64_t seed, int spp) {
    const std::size_t pixels = std::size_t(camera.width()) * camera.height();
    const std::size_t pilots = std::min<std::size_t>(pixels, 4096);
    CountingSink sink;
    std::uint64_t rays = 0;
    for (std::size_t k = 0; k < pilots; ++k) {
        const std::size_t p = k * pixels / pilots;
        const int x = int(p % camera.width()), y = int(p / camera.width());
        const CounterRng rng(seed, std::uint32_t(p));
        const Vec2d film = filmPosition(sensor, x, y, rng.uniform(0, 0), rng.uniform(0, 1));
        integrator.trace(camera.generateRay(film.x(), film.y()), rng, 0, sink, rays);
    }
    const double perSample =
        (double(sink.terms) * sizeof(PathTerm) + double(sink.vertices) * sizeof(PathVertex)) /
        double(pilots);
    const double perPixel = 2 * sizeof(Color<float>) + 3 * sizeof(std::uint32_t) + 8;
    return double(pixels) * (perPixel + 2 * perSample * spp);
}

}  // namespace

PathSet Renderer::record(const RecordOptions& options) const {
    if (options.fittedBsdfs.size() != options.theta0.size())
        throw Error("record: one starting material per fitted bsdf is needed");
    std::vector<PhongMaterial> materials;
    for (const BsdfDesc& b : scene_.bsdfs) materials.push_back(b.params);
    std::vector<int> slots(materials.size(), -1);
    for (std::size_t k = 0; k < options.fittedBsdfs.size(); ++k) {
        slots[options.fittedBsdfs[k]] = int(k);
        materials[options.fittedBsdfs[k]] = options.theta0[k];
    }
    const auto sampler = makePhongSampler<double>("lafortune");
    const DefensiveSampler defensive(options.defensive);
    const PathIntegrator integrator(
        scene_, *geometry_, *lights_, materials, slots, *sampler, defensive,
        {effectiveMaxDepth(options.maxDepth), scene_.integrator.rrDepth, true});

    // Refuse what would exhaust memory before trying: half the machine's is the budget.
    const double bytes = recordingBytes(integrator, camera_, scene_.sensor, options.seed,
                                        std::max(options.spp, options.directSpp));
    const double budget = 0.5 * double(sysconf(_SC_PHYS_PAGES)) * double(sysconf(_SC_PAGE_SIZE));
    if (bytes > budget)
        throw Error(fmt::format(
            "recording {} paths per pixel of the {}x{} film would take about {:.1f} GB, more than "
            "half of this machine's memory ({:.1f} GB): lower --spp, or the film size",
            options.spp, camera_.width(), camera_.height(), bytes / 1e9, 2 * budget / 1e9));

    const int width = camera_.width(), height = camera_.height();
    const std::vector<Tile> tiles = makeTiles(width, height);
    std::vector<TileRecord> records(tiles.size());
    // Fixed per pixel, not decided by the pixel's own samples, so every pixel's estimate stays
    // unbiased.
    const auto pathsAt = [&](int x, int y) {
        if (options.directSpp <= options.spp) return options.spp;
        const std::optional<Hit> hit = geometry_->intersect(camera_.generateRay(x + 0.5, y + 0.5));
        const int bsdf = hit ? scene_.shapes[hit->shape].bsdf : -1;
        return bsdf >= 0 && slots[bsdf] >= 0 ? options.directSpp : options.spp;
    };
    runInArena(options.threads, [&] {
        tbb::parallel_for(
            tbb::blocked_range<std::size_t>(0, tiles.size(), 1), [&](const auto& range) {
                std::uint64_t rays = 0;
                for (std::size_t t = range.begin(); t != range.end(); ++t) {
                    const Tile& tile = tiles[t];
                    TileRecord& rec = records[t];
                    rec.termStart.push_back(0);
                    for (int y = tile.y0; y < tile.y1; ++y)
                        for (int x = tile.x0; x < tile.x1; ++x) {
                            const std::uint32_t p = pixelIndex(x, y, width);
                            const CounterRng rng(options.seed, p);
                            Color3 background = Color3::Zero();
                            const int paths = pathsAt(x, y);
                            const double scale = 1.0 / paths;
                            for (int s = 0; s < paths; ++s) {
                                const Vec2d film = filmPosition(
                                    scene_.sensor, x, y, rng.uniform(s, 0), rng.uniform(s, 1));
                                const std::size_t termsBefore = rec.terms.size();
                                const std::size_t verticesBefore = rec.vertices.size();
                                const Color3 backgroundBefore = background;
                                RecordingSink sink{rec, background, scale};
                                integrator.trace(camera_.generateRay(film.x(), film.y()), rng, s,
                                                 sink, rays);
                                // A non-finite sample is dropped whole, as in rendering.
                                bool finite = background.allFinite();
                                for (std::size_t k = termsBefore; k < rec.terms.size(); ++k)
                                    finite = finite && rec.terms[k].constant.allFinite();
                                if (!finite) {
                                    rec.terms.resize(termsBefore);
                                    rec.vertices.resize(verticesBefore);
                                    background = backgroundBefore;
                                }
                            }
                            for (std::size_t k = rec.termStart.back(); k < rec.terms.size(); ++k)
                                rec.terms[k].pixel = p;
                            rec.background.push_back(background.cast<float>());
                            rec.termStart.push_back(std::uint32_t(rec.terms.size()));
                        }
                }
            });
    });

    // Assemble in global pixel order: terms of a pixel are contiguous, pixels ascending.
    PathSet set;
    set.width = width;
    set.height = height;
    set.spp = options.spp;
    set.slots = int(options.fittedBsdfs.size());
    const std::size_t pixels = std::size_t(width) * height;
    set.background.resize(pixels);
    set.pixelStart.assign(pixels + 1, 0);
    struct Where {
        std::uint32_t tile, local;
    };
    std::vector<Where> where(pixels);
    for (std::size_t t = 0; t < tiles.size(); ++t) {
        std::uint32_t local = 0;
        for (int y = tiles[t].y0; y < tiles[t].y1; ++y)
            for (int x = tiles[t].x0; x < tiles[t].x1; ++x)
                where[pixelIndex(x, y, width)] = {std::uint32_t(t), local++};
    }
    for (std::size_t p = 0; p < pixels; ++p) {
        const TileRecord& rec = records[where[p].tile];
        const std::uint32_t l = where[p].local;
        set.background[p] = rec.background[l];
        set.pixelStart[p + 1] = set.pixelStart[p] + (rec.termStart[l + 1] - rec.termStart[l]);
    }
    set.terms.resize(set.pixelStart[pixels]);
    for (std::size_t p = 0; p < pixels; ++p) {
        const TileRecord& rec = records[where[p].tile];
        const std::uint32_t l = where[p].local;
        std::uint32_t out = set.pixelStart[p];
        for (std::uint32_t k = rec.termStart[l]; k < rec.termStart[l + 1]; ++k, ++out) {
            PathTerm term = rec.terms[k];
            term.firstVertex = std::uint32_t(set.vertices.size());
            set.vertices.insert(set.vertices.end(), rec.vertices.begin() + rec.terms[k].firstVertex,
                                rec.vertices.begin() + rec.terms[k].firstVertex + term.vertexCount);
            set.terms[out] = term;
        }
    }
    return set;
}

}  // namespace phongfit
