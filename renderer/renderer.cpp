#include "renderer.h"

#include <fmt/format.h>
#include <unistd.h>

#include <algorithm>
#include <numeric>

#include "defensive_sampler.h"
#include "error.h"
#include "interrupt.h"
#include "path_integrator.h"
#include "path_set_film.h"
#include "progress.h"
#include "rgb_film.h"
#include "tile_loop.h"

namespace phongfit {
namespace {

// Throws unless a per-pixel list that `command` was given, `count` entries of `what`, holds one
// entry per pixel of a width x height film and `entriesValid`; `each` names what every entry must
// be, where that is checked too.
void checkPerPixel(const char* command, std::size_t count, const char* what, int width, int height,
                   bool entriesValid = true, const char* each = nullptr) {
    if (count == std::size_t(width) * std::size_t(height) && entriesValid) return;
    throw Error(fmt::format("{}: {} {} given for a {}x{} film{}", command, count, what, width,
                            height, each ? fmt::format(", {}", each) : ""));
}

// Counts what a path would record, keeping nothing.
struct CountingSink {
    std::uint64_t terms = 0, vertices = 0;
    void add(const Color3&, std::span<const PathVertex> v) {
        if (v.empty()) return;
        ++terms;
        vertices += v.size();
    }
};

// Bytes a recording needs at its peak, from a pilot of one path in each of up to 4096 pixels
// spread over the film, each standing for its share of the film at its pixel's paths.
double recordingBytes(const PathIntegrator& integrator, const Camera& camera,
                      const SensorDesc& sensor, const FilmWindow& window, PixelSamplerType type,
                      std::uint64_t seed, const std::vector<int>& paths, bool ringed) {
    const std::size_t pixels = window.pixels();
    const std::size_t pilots = std::min<std::size_t>(pixels, 4096);
    double terms = 0, vertices = 0;
    std::uint64_t rays = 0;
    for (std::size_t k = 0; k < pilots; ++k) {
        const std::size_t p = k * pixels / pilots;
        if (paths[p] == 0) continue;
        const int x = window.x0 + int(p % std::size_t(window.width)),
                  y = window.y0 + int(p / std::size_t(window.width));
        const PixelSampler rng(type, seed, std::uint32_t(y) * camera.width() + std::uint32_t(x));
        const Vec2d u = rng.get2D(0, 0);
        const Vec2d film = filmPosition(sensor, x, y, u.x(), u.y());
        CountingSink sink;
        integrator.trace(camera.generateRay(film.x(), film.y()), rng, 0, sink, rays);
        terms += double(sink.terms) * paths[p];
        vertices += double(sink.vertices) * paths[p];
    }
    const double share = double(pixels) / double(pilots);
    return PathSetFilm::peakBytes(pixels, terms * share, vertices * share, ringed);
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

bool Renderer::recordsByRings(int requested) const {
    if (effectiveMaxDepth(requested) != 2) return false;
    for (int l = 0; l < lights_->size(); ++l)
        if (lights_->hasCone(l)) return true;
    return false;
}

TileLoop Renderer::tileLoop(const PathIntegrator& integrator, const SensorDesc& sensor,
                            const FilmWindow& window, std::optional<PixelSamplerType> pixelSampler,
                            std::uint64_t seed, int threads, int samples) const {
    return TileLoop{.integrator = integrator,
                    .camera = camera_,
                    .sensor = sensor,
                    .window = window,
                    .pixelSampler = pixelSampler.value_or(scene_.sensor.pixelSampler),
                    .seed = seed,
                    .threads = threads,
                    .samples = samples,
                    .stop = interruptRequested};
}

FilmWindow Renderer::filmWindow(const FilmWindow& window, const char* command) const {
    if (window.width == 0) return {0, 0, camera_.width(), camera_.height()};
    if (window.x0 < 0 || window.y0 < 0 || window.width <= 0 || window.height <= 0 ||
        window.x0 + window.width > camera_.width() || window.y0 + window.height > camera_.height())
        throw Error(fmt::format("{}: window {}x{} at ({}, {}) is not within the {}x{} film",
                                command, window.width, window.height, window.x0, window.y0,
                                camera_.width(), camera_.height()));
    return window;
}

std::vector<PhongMaterial> Renderer::materialsWith(const std::vector<int>& bsdfs,
                                                   const std::vector<PhongMaterial>& params,
                                                   const char* command) const {
    if (bsdfs.size() != params.size())
        throw Error(fmt::format("{}: one material per bsdf replaced is needed", command));
    std::vector<PhongMaterial> materials;
    for (const BsdfDesc& b : scene_.bsdfs) materials.push_back(b.params);
    for (std::size_t k = 0; k < bsdfs.size(); ++k) {
        if (bsdfs[k] < 0 || std::size_t(bsdfs[k]) >= materials.size())
            throw Error(fmt::format("{}: bsdf {} is not one of the scene's {}", command, bsdfs[k],
                                    materials.size()));
        materials[std::size_t(bsdfs[k])] = params[k];
    }
    return materials;
}

RenderResult Renderer::render(const RenderOptions& options) const {
    const int spp = options.spp > 0 ? options.spp : scene_.sensor.sampleCount;
    const auto sampler = makePhongSampler<double>(options.sampler);
    const std::vector<PhongMaterial> materials =
        materialsWith(options.bsdfs, options.bsdfParams, "render");
    const PathIntegrator integrator(
        scene_, *geometry_, *lights_, materials, std::vector<int>(materials.size(), -1), *sampler,
        *sampler, {effectiveMaxDepth(options.maxDepth), scene_.integrator.rrDepth, options.mis});

    const FilmWindow window = filmWindow(options.window, "render");
    const int width = window.width, height = window.height;
    const std::size_t pixels = window.pixels();
    if (!options.rendered.empty())
        checkPerPixel("render", options.rendered.size(), "rendered-pixel flags", width, height);
    const std::size_t renderedPixels =
        options.rendered.empty()
            ? pixels
            : std::size_t(std::count_if(options.rendered.begin(), options.rendered.end(),
                                        [](std::uint8_t r) { return r != 0; }));
    RgbFilm film(width, height, spp, options.rendered);
    Progress progress("render", std::uint64_t(spp) * renderedPixels, "samples", options.quiet);
    SensorDesc sensor = scene_.sensor;
    if (options.pixelFilter) {
        const double w = options.pixelFilter->width;
        if (pixelFilterName(options.pixelFilter->filter).width != nullptr && !filterWidthAllowed(w))
            throw Error(
                fmt::format("render: pixel filter width {} is not in (0, {}]", w, kMaxFilterWidth));
        setPixelFilter(sensor, *options.pixelFilter);
    }
    TileLoop loop = tileLoop(integrator, sensor, window, options.pixelSampler, options.seed,
                             options.threads, spp);
    loop.progress = &progress;
    RenderStats stats = traceTiles(loop, film);
    progress.finish();
    stats.spp = spp;
    return film.result(std::move(stats));
}

std::vector<std::uint8_t> seesAny(const std::vector<int>& bsdfSeen, const std::vector<int>& bsdfs) {
    std::vector<std::uint8_t> sees(bsdfSeen.size());
    for (std::size_t p = 0; p < bsdfSeen.size(); ++p)
        sees[p] = std::find(bsdfs.begin(), bsdfs.end(), bsdfSeen[p]) != bsdfs.end();
    return sees;
}

std::vector<int> Renderer::bsdfSeen(int threads) const {
    const int width = camera_.width(), height = camera_.height();
    std::vector<int> seen(std::size_t(width) * std::size_t(height), -1);
    runInArena(threads, [&] {
        tbb::parallel_for(0, height, [&](int y) {
            for (int x = 0; x < width; ++x)
                if (const std::optional<Hit> hit =
                        geometry_->intersect(camera_.generateRay(x + 0.5, y + 0.5)))
                    seen[std::size_t(y) * width + x] = scene_.shapes[hit->shape].bsdf;
        });
    });
    return seen;
}

RecordResult Renderer::record(const RecordOptions& options) const {
    const std::vector<PhongMaterial> materials =
        materialsWith(options.fittedBsdfs, options.theta0, "record");
    std::vector<int> slots(materials.size(), -1);
    for (std::size_t k = 0; k < options.fittedBsdfs.size(); ++k)
        slots[std::size_t(options.fittedBsdfs[k])] = int(k);
    const auto sampler = makePhongSampler<double>(options.sampler);
    const DefensiveSampler defensive(options.defensive);
    // Rings only where the recording is direct light alone: with indirect light the fit's n also
    // leans on glossy reflections of other surfaces, whose paths stay sampled, and a Cornell box
    // under a 40-degree light then drifted to n 3.8e5 for 3000 (docs/design/fitter.md, "Area
    // lights by rings").
    const int maxDepth = effectiveMaxDepth(options.maxDepth);
    const bool rings = options.lightRings && recordsByRings(options.maxDepth);
    const std::uint32_t ringed =
        rings ? std::uint32_t(std::max(options.spp, options.directSpp)) : 0;
    const PathIntegrator integrator(scene_, *geometry_, *lights_, materials, slots, *sampler,
                                    defensive, {maxDepth, scene_.integrator.rrDepth, true, ringed});

    const FilmWindow window = filmWindow(options.window, "record");
    // Paths per pixel, fixed before tracing rather than decided by the pixel's own samples, so
    // every pixel's estimate stays unbiased.
    const int width = window.width, height = window.height;
    const std::size_t pixels = window.pixels();
    std::vector<int> paths(pixels, options.spp);
    if (options.directSpp > options.spp) {
        std::vector<std::uint8_t> found;
        if (options.direct.empty())
            found = cropped(seesAny(bsdfSeen(options.threads), options.fittedBsdfs),
                            camera_.width(), window);
        const std::span<const std::uint8_t> direct = found.empty() ? options.direct : found;
        checkPerPixel("record", direct.size(), "direct-pixel flags", width, height);
        for (std::size_t p = 0; p < pixels; ++p)
            if (direct[p]) paths[p] = options.directSpp;
    }
    if (!options.extraPaths.empty()) {
        checkPerPixel("record", options.extraPaths.size(), "extra path counts", width, height,
                      *std::min_element(options.extraPaths.begin(), options.extraPaths.end()) >= 0,
                      "each >= 0");
        for (std::size_t p = 0; p < pixels; ++p) paths[p] += options.extraPaths[p];
    }
    if (!options.recorded.empty()) {
        checkPerPixel("record", options.recorded.size(), "pixel flags", width, height);
        for (std::size_t p = 0; p < pixels; ++p)
            if (!options.recorded[p]) paths[p] = 0;
    }

    // A Sobol scene records on padded Sobol points: at the few paths a pixel a fit records, each
    // pair stratified on its own does better (docs/design/sampling.md, "Recordings").
    PixelSamplerType pixelSampler = options.pixelSampler.value_or(scene_.sensor.pixelSampler);
    if (pixelSampler == PixelSamplerType::Sobol) pixelSampler = PixelSamplerType::Padded;

    const int most = *std::max_element(paths.begin(), paths.end());
    // A pixel that takes more paths than are ringed weights the two kinds (path_set.h): only then
    // does the film keep them apart.
    const std::uint32_t filmRinged = most > int(ringed) ? ringed : 0;

    // Refuse what would exhaust memory before trying: half the machine's is the budget.
    const std::size_t recordedPixels =
        pixels - std::size_t(std::count(paths.begin(), paths.end(), 0));
    const double meanPaths = std::accumulate(paths.begin(), paths.end(), 0.0) /
                             double(std::max<std::size_t>(recordedPixels, 1));
    const double bytes = recordingBytes(integrator, camera_, scene_.sensor, window, pixelSampler,
                                        options.seed, paths, filmRinged > 0);
    const std::string what =
        fmt::format("recording {:.0f} paths per pixel of the {}x{} film{}", meanPaths,
                    camera_.width(), camera_.height(),
                    recordedPixels < std::size_t(camera_.width()) * std::size_t(camera_.height())
                        ? fmt::format(" (in {} of its pixels)", recordedPixels)
                        : std::string());
    const double half = 0.5 * double(sysconf(_SC_PHYS_PAGES)) * double(sysconf(_SC_PAGE_SIZE));
    if (bytes > half)
        throw Error(fmt::format(
            "{} would take about {:.1f} GB, more than half of this machine's memory ({:.1f} GB): "
            "lower --spp, or the film size",
            what, bytes / 1e9, 2 * half / 1e9));
    if (options.memoryBudget > 0 && bytes > options.memoryBudget)
        throw Error(fmt::format(
            "{} would take about {:.3f} GB, more than the {:.3f} GB left for it: lower --spp, or "
            "the film size, or raise --max-memory",
            what, bytes / 1e9, options.memoryBudget / 1e9));

    PathSetFilm film(width, height, std::move(paths), makeTiles(width, height).size(), filmRinged);
    RecordResult result;
    result.stats = traceTiles(tileLoop(integrator, scene_.sensor, window, pixelSampler,
                                       options.seed, options.threads, most),
                              film);
    result.stats.spp = options.spp;
    result.paths = film.assemble(options.spp, int(options.fittedBsdfs.size()));
    return result;
}

}  // namespace phongfit
