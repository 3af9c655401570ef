// Renders a scene description to an image, or records its paths for the fitter. Builds the Embree
// scene once; both run the one tile loop (tile_loop.h) on TBB, which polls interruptRequested();
// every random number is keyed by (seed, pixel, sample, dimension), so an image or a recording is
// bit-identical for a seed whatever the thread count.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "camera.h"
#include "film_window.h"
#include "lights.h"
#include "path_set.h"
#include "render_stats.h"
#include "scene.h"
#include "tile_loop.h"

namespace phongfit {

class PathIntegrator;
struct TileLoop;

struct RenderOptions {
    int spp = 0;  // 0: the scene's sampleCount
    std::uint64_t seed = 0;
    int threads = 0;  // 0: all hardware threads
    std::string sampler = "mixture";
    std::optional<PixelSamplerType> pixelSampler;  // unset: the scene's
    int maxDepth = -2;  // -2: the scene's; otherwise as in Mitsuba (-1 unbounded)
    bool mis = true;
    bool quiet = false;  // no progress output
    // The part of the film rendered (width 0: all of it); `rendered` and the result are the
    // window's size, pixels numbered from its corner (film_window.h).
    FilmWindow window;
    // Per pixel (of the window): 0 traces no sample there (mean 0, sample count 0), as for the
    // pixels a fit's comparison greys out; empty: every pixel. Viewed, not copied: the caller keeps
    // it alive through render().
    std::span<const std::uint8_t> rendered;
    // Scene bsdf indices rendered with `bsdfParams` (one each) instead of the scene's own, as a
    // recording's fittedBsdfs and theta0: a fit renders at its estimate without a scene of its own.
    std::vector<int> bsdfs;
    std::vector<PhongMaterial> bsdfParams;
    // The pixel filter in place of the film's (unset: the film's): an image's edges compared with
    // other filters without a scene of their own (edge_agreement.h).
    std::optional<PixelFilter> pixelFilter;
};

struct RenderResult {
    int width = 0, height = 0;
    std::vector<float> rgb;       // 3 per pixel, row 0 top: the mean of the pixel's samples
    std::vector<float> variance;  // 3 per pixel: variance of that mean (sample variance / count)
    std::vector<std::uint32_t> sampleCount;  // per pixel (less than spp after an interrupt)
    RenderStats stats;
};

struct RecordOptions {
    int spp = 4;
    // Paths per pixel where the pixel's centre sees a fitted material directly, when more than
    // spp: those pixels carry what the images say about the material.
    int directSpp = 0;
    // Per pixel (width x height, each >= 0), paths on top of spp and directSpp; empty: none.
    std::vector<int> extraPaths;
    // Per pixel (width x height): 0 records no path there (a pixel the fit leaves out); empty:
    // every pixel records. Viewed, not copied: the caller keeps it alive through record().
    std::span<const std::uint8_t> recorded;
    // Per pixel (width x height): 1 where the centre sees a fitted material (bsdfSeen), the
    // pixels directSpp applies to. Empty: found anew when directSpp asks.
    std::span<const std::uint8_t> direct;
    // The part of the film recorded (width 0: all of it). The set, and every per-pixel input above,
    // is the window's size, pixels numbered from its corner.
    FilmWindow window;
    std::uint64_t seed = 0;
    std::optional<PixelSamplerType> pixelSampler;  // unset: the scene's
    int threads = 0;
    int maxDepth = -2;
    std::vector<int> fittedBsdfs;       // scene bsdf indices, in slot order
    std::vector<PhongMaterial> theta0;  // per slot: the parameters to record at
    double defensive = 0.2;             // share of cosine sampling at fitted vertices
    std::string sampler = "mixture";    // at vertices on materials that are not fitted
    // In a recording of direct light alone (max depth 2), in each pixel's first max(spp,
    // directSpp) paths, spherical and parallelogram lights near a fitted vertex's mirror
    // direction by rings (IntegratorSettings::ringedSamples); the extra paths, other depths, and
    // every path when false, sample them as a render does.
    bool lightRings = true;
    // Bytes the recording may take at its peak (0: no more than half the machine's memory, which
    // also caps a budget given): one forecast above it is refused before tracing.
    double memoryBudget = 0;
};

struct RecordResult {
    PathSet paths;
    // As a render's: non-finite samples dropped (each pixel the mean of those it kept); after an
    // interrupt every pixel still holds the mean of the paths it got (at least one), fewer than
    // asked.
    RenderStats stats;
};

// Per pixel of a Renderer::bsdfSeen map: 1 where the bsdf seen is one of `bsdfs`.
std::vector<std::uint8_t> seesAny(const std::vector<int>& bsdfSeen, const std::vector<int>& bsdfs);

class Renderer {
public:
    explicit Renderer(Scene scene);
    ~Renderer();

    const Scene& scene() const { return scene_; }
    RenderResult render(const RenderOptions& options) const;
    RecordResult record(const RecordOptions& options) const;

    // The depth the options ask for, resolved against the scene's integrator.
    int effectiveMaxDepth(int requested) const;

    // Whether a recording at `requested` depth integrates some area light by rings
    // (RecordOptions::lightRings): direct light alone, and a light with a cone.
    bool recordsByRings(int requested) const;

    // Per pixel of the film (row-major), the scene bsdf index of the shape the ray through the
    // pixel's centre first hits; -1 where it hits none.
    std::vector<int> bsdfSeen(int threads) const;

private:
    // `window` checked against the film; width 0: the whole film. `command` names the caller.
    FilmWindow filmWindow(const FilmWindow& window, const char* command) const;

    // The scene's bsdf parameters, those of `bsdfs` replaced by `params` (one each).
    std::vector<PhongMaterial> materialsWith(const std::vector<int>& bsdfs,
                                             const std::vector<PhongMaterial>& params,
                                             const char* command) const;

    // The tile loop over `sensor`, this scene's film or one with another filter; `pixelSampler`
    // unset: the scene's.
    TileLoop tileLoop(const PathIntegrator& integrator, const SensorDesc& sensor,
                      const FilmWindow& window, std::optional<PixelSamplerType> pixelSampler,
                      std::uint64_t seed, int threads, int samples) const;

    Scene scene_;
    std::unique_ptr<EmbreeScene> geometry_;
    std::unique_ptr<LightSet> lights_;
    Camera camera_;
};

}  // namespace phongfit
