#include "renderer.h"

#include <fmt/format.h>
#include <unistd.h>

#include <algorithm>

#include "defensive_sampler.h"
#include "error.h"
#include "interrupt.h"
#include "path_integrator.h"
#include "progress.h"
#include "rgb_film.h"
#include "tile_loop.h"

namespace phongfit {

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
    RgbFilm film(width, height, spp);
    Progress progress("render", std::uint64_t(spp) * width * height, "samples", options.quiet);
    RenderStats stats = traceTiles(TileLoop{.integrator = integrator,
                                            .camera = camera_,
                                            .sensor = scene_.sensor,
                                            .seed = options.seed,
                                            .threads = options.threads,
                                            .samples = spp,
                                            .stop = interruptRequested,
                                            .progress = &progress},
                                   film);
    progress.finish();
    stats.spp = spp;
    return film.result(std::move(stats));
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
    const auto pixelIndex = [&](int x, int y) { return std::uint32_t(y) * width + x; };
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
                            const std::uint32_t p = pixelIndex(x, y);
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
                where[pixelIndex(x, y)] = {std::uint32_t(t), local++};
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
