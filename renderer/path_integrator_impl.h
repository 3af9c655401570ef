// Template body of PathIntegrator::trace; included by path_integrator.h only.
#pragma once

#include <algorithm>
#include <bit>

namespace phongfit {

namespace detail {
inline double powerHeuristic(double pdfA, double pdfB) {
    const double a = pdfA * pdfA, b = pdfB * pdfB;
    return a + b > 0 ? a / (a + b) : 0;
}
}  // namespace detail

template <typename Sink>
void PathIntegrator::trace(const Ray& cameraRay, const PixelSampler& rng, std::uint64_t sample,
                           Sink& sink, std::uint64_t& rays) const {
    // Fitted vertices of the current path prefix (a fixed small capacity keeps this
    // allocation-free).
    constexpr int kMaxFittedVertices = 64;
    PathVertex prefix[kMaxFittedVertices + 1];
    int prefixSize = 0;

    Color3 constant = Color3::Ones();  // throughput without f at fitted vertices
    Color3 fittedF = Color3::Ones();   // product of f(theta0) at fitted vertices (for roulette)
    double bsdfPdf = 0;                // pdf of the direction that led to the current vertex
    // Lights the previous vertex integrated by rings: the BRDF-sampled ray's emission from them is
    // already counted.
    std::uint64_t ringedBefore = 0;
    Ray ray = cameraRay;
    const int maxDepth = settings_.maxDepth;

    for (int depth = 1;; ++depth) {
        ++rays;
        const std::optional<Hit> hit = geometry_.intersect(ray);
        // Diagnostic sinks learn which vertex the following contributions come from.
        if constexpr (requires { sink.vertex(depth, 0); })
            sink.vertex(depth, hit ? scene_.shapes[hit->shape].bsdf : -1);
        if (!hit) {
            if (lights_.environment() >= 0) {
                const EnvironmentMap::Lookup env = lights_.environmentLookup(ray.dir);
                const double w =
                    depth == 1 || !settings_.mis ? 1.0 : detail::powerHeuristic(bsdfPdf, env.pdf);
                const Color3 le = env.radiance * w;
                if ((le > 0).any())
                    sink.add(constant * le, std::span<const PathVertex>(prefix, prefixSize));
            }
            return;
        }
        // Emission reached by BRDF sampling (or seen directly), weighted against light sampling.
        if (const int hitLight = lights_.lightOfShape(hit->shape);
            hitLight >= 0 && !(hitLight < 64 && (ringedBefore >> hitLight & 1))) {
            const Color3 le = lights_.emitted(*hit, ray.dir);
            if ((le > 0).any()) {
                double w = 1;
                if (depth > 1 && settings_.mis)
                    w = detail::powerHeuristic(bsdfPdf,
                                               lights_.pdfArea(hitLight, ray.origin, *hit));
                sink.add(constant * le * w, std::span<const PathVertex>(prefix, prefixSize));
            }
        }
        if (maxDepth >= 0 && depth >= maxDepth) return;

        const ShapeDesc& shape = scene_.shapes[hit->shape];
        const PhongMaterial& m = materials_[shape.bsdf];
        const int slot = slots_[shape.bsdf];
        const PhongSampler<double>& sampler = slot >= 0 ? fittedSampler_ : sampler_;
        const Frame<double> frame(hit->ns);
        const Vec3d wo = frame.toLocal(-ray.dir);
        if (!(wo.z() > 0) || !(hit->ng.dot(-ray.dir) > 0)) return;  // one-sided materials
        const std::uint32_t dim = kFirstDimension + std::uint32_t(depth - 1) * dimensionsPerBounce_;
        // At the last vertex that can reflect, on a diffuse surface under area and delta lights,
        // light sampling alone covers every emitter and does best: the BRDF-sampled ray, which
        // could only find emission, is not traced. An environment keeps MIS: cosine sampling is
        // what lights a diffuse surface under a sky (docs/design/sampling.md).
        const bool lastReflection = maxDepth >= 0 && depth + 1 >= maxDepth;
        const bool lightSamplingOnly = lastReflection && settings_.mis && slot < 0 &&
                                       !(m.ks > 0).any() && lights_.environment() < 0;

        // Next-event estimation on every light.
        std::uint64_t ringed = 0;
        for (int l = 0; l < lights_.size(); ++l) {
            const std::uint32_t d = dim + 4 + 2 * std::uint32_t(l);
            if (slot >= 0 && sample < settings_.ringedSamples && l < 64 &&
                integrateByRings(l, *hit, frame.toWorld(reflectLocal(wo)), m.n,
                                 rng.get2D(sample, d).x(), constant, prefix, prefixSize, slot, sink,
                                 rays)) {
                ringed |= std::uint64_t(1) << l;
                continue;
            }
            const auto ls = lights_.sample(l, hit->p, rng.get2D(sample, d));
            if (!ls || (!ls->delta && !settings_.mis)) continue;
            const Vec3d wi = frame.toLocal(ls->wi);
            if (!(wi.z() > 0) || !(hit->ng.dot(ls->wi) > 0)) continue;
            Color3 c = constant * ls->radiance * (wi.z() / ls->pdf);
            if (!ls->delta && !lightSamplingOnly)
                c *= detail::powerHeuristic(ls->pdf, sampler.pdf(m, wo, wi));
            if (slot < 0) c *= phongEval(m, wi, wo);
            if (!(c > 0).any()) continue;
            // Stop short of the light's own surface (relative margin: float intersection error).
            const Vec3d origin = offsetRayOrigin(hit->p, hit->ng, ls->wi);
            const double reach = std::isfinite(ls->distance)
                                     ? (hit->p + ls->distance * ls->wi - origin).norm() * (1 - 1e-4)
                                     : ls->distance;
            const Ray shadow{origin, ls->wi, reach};
            ++rays;
            if (geometry_.occluded(shadow)) continue;
            if (slot < 0) {
                sink.add(c, std::span<const PathVertex>(prefix, prefixSize));
            } else {
                prefix[prefixSize] = PathVertex{float(logCosAlpha(wi, wo)), std::uint32_t(slot)};
                sink.add(c, std::span<const PathVertex>(prefix, prefixSize + 1));
            }
        }

        // Nor is it where rings took every area light and no environment shines: it could only
        // find emission they already counted.
        if (lightSamplingOnly ||
            (lastReflection && ringed != 0 && std::popcount(ringed) == areaLights_ &&
             lights_.environment() < 0))
            return;

        // Continue the path by sampling the BRDF.
        const auto s = sampler.sample(m, wo, rng.get1D(sample, dim), rng.get2D(sample, dim + 1));
        if (!s) return;
        const Vec3d wiWorld = frame.toWorld(s->wi);
        if (!(hit->ng.dot(wiWorld) > 0)) return;
        if (slot < 0) {
            constant *= s->weight;
        } else {
            if (prefixSize == kMaxFittedVertices) return;
            constant *= s->wi.z() / s->pdf;
            fittedF *= phongEval(m, s->wi, wo);
            prefix[prefixSize++] = PathVertex{float(logCosAlpha(s->wi, wo)), std::uint32_t(slot)};
        }
        bsdfPdf = s->pdf;
        ringedBefore = ringed;
        ray = Ray{offsetRayOrigin(hit->p, hit->ng, wiWorld), wiWorld};

        if (depth + 1 >= settings_.rrDepth) {
            const double q = std::min(0.95, (constant * fittedF).maxCoeff());
            if (!(rng.get1D(sample, dim + 3) < q)) return;
            constant /= q;
        }
    }
}

template <typename Sink>
bool PathIntegrator::integrateByRings(int light, const Hit& hit, const Vec3d& mirror, double n0,
                                      double u, const Color3& constant, PathVertex* prefix,
                                      int prefixSize, int slot, Sink& sink,
                                      std::uint64_t& rays) const {
    const std::optional<LightCone> cone = lights_.cone(light, hit.p);
    if (!cone) return false;
    const LightRings rings(mirror, hit.ns, hit.ng, *cone, LightRings::innermostFor(n0));
    if (!(rings.nearest() < kRingReach)) return false;
    const Color3 c = constant * lights_.radiance(light);
    rings.forEachNode(u, [&](double logCos, double weight, auto draw) {
        if (!nothingOccludes_) {
            // Visibility along one direction of the ring, drawn by cos(theta_i): exact where
            // nothing stands between, and unbiased where something does.
            const Vec3d wi = draw();
            const Vec3d origin = offsetRayOrigin(hit.p, hit.ng, wi);
            const double reach =
                (hit.p + lights_.distanceTo(light, hit.p, wi) * wi - origin).norm();
            ++rays;
            if (geometry_.occluded(Ray{origin, wi, reach * (1 - 1e-4)})) return;
        }
        prefix[prefixSize] = PathVertex{float(logCos), std::uint32_t(slot)};
        sink.add(c * weight, std::span<const PathVertex>(prefix, prefixSize + 1));
    });
    return true;
}

}  // namespace phongfit
