// The path tracer: next-event estimation on every light, multiple importance sampling (power
// heuristic) against the BRDF's own sampler, Russian roulette after rrDepth, Mitsuba's depth count
// (1 = emitters seen directly, 2 = direct illumination, ...).
//
// Contributions go to a sink as `constant * prod f(v)` over the vertices on fitted materials (see
// path_set.h). When no material is fitted every vertex folds into the constant and the sink just
// sums radiance: rendering and path recording are the same code.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "embree_scene.h"
#include "lights.h"
#include "path_set.h"
#include "phong_sampler.h"
#include "pixel_sampler.h"

namespace phongfit {

struct IntegratorSettings {
    int maxDepth = -1;  // -1: unbounded
    int rrDepth = 5;
    bool mis = true;  // false: area and environment light only through BRDF sampling
    // In a pixel's first ringedSamples paths, at vertices on fitted materials, spherical and
    // parallelogram lights whose nearest point is within kRingReach of the mirror direction are
    // integrated by rings (light_rings.h), not sampled. Paths beyond them sample every light.
    std::uint64_t ringedSamples = 0;
};

class PathIntegrator {
public:
    // `materials` per scene bsdf; `slots` per scene bsdf: the fitted slot or -1. Vertices on fitted
    // materials sample with `fittedSampler`, the others with `sampler`.
    PathIntegrator(const Scene& scene, const EmbreeScene& geometry, const LightSet& lights,
                   std::vector<PhongMaterial> materials, std::vector<int> slots,
                   const PhongSampler<double>& sampler, const PhongSampler<double>& fittedSampler,
                   IntegratorSettings settings);

    // Random dimensions 0 and 1 are the caller's (the position in the pixel, a 2D pair). Then per
    // bounce: the lobe choice (1D), the BRDF direction (2D), the roulette (1D), and per light a
    // point on it (2D).
    static constexpr std::uint32_t kFirstDimension = 2;
    // rad: beyond it a lobe sharp enough for sampling to miss has nothing left (cos^300(0.3) <
    // 2e-6), and the sampled paths do well (docs/design/fitter.md, "Area lights by rings").
    static constexpr double kRingReach = 0.3;

    // Traces one camera path. sink.add(const Color3& constant, std::span<const PathVertex>) gets
    // every contribution; `rays` counts the rays traced.
    template <typename Sink>
    void trace(const Ray& cameraRay, const PixelSampler& rng, std::uint64_t sample, Sink& sink,
               std::uint64_t& rays) const;

private:
    // Light `light` at a fitted vertex recorded at exponent n0, by rings about the mirror
    // direction; false where the light is not one rings cover or lies beyond kRingReach (it is
    // then sampled).
    template <typename Sink>
    bool integrateByRings(int light, const Hit& hit, const Vec3d& mirror, double n0, double u,
                          const Color3& constant, PathVertex* prefix, int prefixSize, int slot,
                          Sink& sink, std::uint64_t& rays) const;

    const Scene& scene_;
    const EmbreeScene& geometry_;
    const LightSet& lights_;
    std::vector<PhongMaterial> materials_;
    std::vector<int> slots_;
    const PhongSampler<double>& sampler_;
    const PhongSampler<double>& fittedSampler_;
    IntegratorSettings settings_;
    std::uint32_t dimensionsPerBounce_;
    // One sphere and at most one emitting shape: no light can be hidden from a point on the
    // sphere (its own horizon aside), so the rings need no visibility rays.
    bool nothingOccludes_;
    int areaLights_ = 0;  // lights on shapes
};

}  // namespace phongfit

#include "path_integrator_impl.h"
