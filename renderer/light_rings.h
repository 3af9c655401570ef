// Direct light from an area light at a vertex on a fitted material, integrated over rings about the
// mirror direction r instead of sampled (docs/design/fitter.md, "Area lights by rings"). The
// lobe cos^n(alpha) is constant on a ring of angle alpha about r, so the light's integral is
// one-dimensional: per ring, cos(theta_i) integrated in closed form over the azimuths that meet the
// light above both horizons, and Gauss nodes in log(alpha) across every lobe width, n 1 to 1e6.
// Each node is an ordinary one-vertex term (log cos alpha, and its share of the irradiance): the
// terms sum to the light's exact irradiance, and no estimate of n decides where they fall.
#pragma once

#include <algorithm>
#include <array>
#include <cstdint>

#include "math.h"

namespace phongfit {

// The directions that meet a light from a point: dot(w, normals[k]) >= offsets[k] for every k
// (a parallelogram's four edge planes, or the cone about a sphere).
struct LightCone {
    std::array<Vec3d, 4> normals{Vec3d::Zero(), Vec3d::Zero(), Vec3d::Zero(), Vec3d::Zero()};
    std::array<double, 4> offsets{};
    int planes = 0;
};

class LightRings {
public:
    // r: the unit mirror direction; ns: the shading normal (cos theta_i); ng: the geometric
    // normal (materials are one-sided). All unit, in world space. Inside `innermost` one node
    // takes the disc about r (innermostFor).
    LightRings(const Vec3d& r, const Vec3d& ns, const Vec3d& ng, const LightCone& cone,
               double innermost = kInnermost);

    // The innermost ring for a recording at exponent n0: the disc inside it holds 0.5% of a lobe
    // 100x sharper (n a^2 / 2 = 0.005), which its one node gets to 1e-8.
    static double innermostFor(double n0) {
        return std::clamp(0.01 / std::sqrt(std::max(n0, 1.0)), kInnermost, 0.01);
    }

    // The angle from r of the nearest ring that meets the light; pi/2 when none does.
    double nearest() const { return nearest_; }

    // Calls f(logCos, weight, draw) once per node: log(cos alpha), the node's share of the light's
    // irradiance (sum of weights = integral of cos theta_i over the light, for radiance 1), and
    // draw(), which returns a direction on its ring drawn with density proportional to
    // cos(theta_i) from u_k = frac(u + k * golden ratio) for the k-th node (for a visibility test).
    template <typename F>
    void forEachNode(double u, F&& f) const;

    static constexpr int kMaxArcs = 8;
    struct Ring {
        double cosAlpha, sinAlpha;
        std::array<std::array<double, 2>, kMaxArcs> arcs;  // azimuth intervals inside the light
        int arcCount = 0;
        // cos(theta_i) = c0 + c1 cos(phi) + c2 sin(phi) along the ring
        double c0 = 0, c1 = 0, c2 = 0;
        double integral = 0;  // of cos(theta_i) over the arcs

        // The integral of cos(theta_i) over azimuths [p, q].
        double cosIntegral(double p, double q) const {
            return c0 * (q - p) + c1 * (std::sin(q) - std::sin(p)) -
                   c2 * (std::cos(q) - std::cos(p));
        }
    };
    Ring ring(double alpha) const;
    // The direction at azimuth phi on a ring.
    Vec3d direction(const Ring& ring, double phi) const;
    // The azimuth where the cos(theta_i)-weighted arc length reaches t * ring.integral.
    double azimuthAt(const Ring& ring, double t) const;

    static constexpr int kGaussNodes = 12;      // a sub-segment (docs/design/fitter.md)
    static constexpr double kSubSegment = 4;    // the ratio of a sub-segment's ends
    static constexpr double kInnermost = 1e-6;  // rad: 1e-3 of the width of a lobe of n 1e6

private:
    // dot(w, m) >= offset, with m's components along r, e1 and e2: on the ring of angle alpha,
    // dot(w(phi), m) = cos(alpha) a + sin(alpha) (b1 cos(phi) + b2 sin(phi)).
    struct Constraint {
        double a, b1, b2;
        double offset;
    };
    Frame<double> frame_;  // about r
    Vec3d ns_;
    std::array<Constraint, 6> constraints_;
    int constraintCount_ = 0;
    std::array<double, 64> cuts_;  // ring angles where the arcs change shape, ascending
    int cutCount_ = 0;
    std::uint64_t live_ = 0;  // bit j: the rings between cuts j and j + 1 meet the light
    double innermost_;
    double nearest_ = kPi / 2;
};

namespace detail {
struct GaussRule {
    std::array<double, LightRings::kGaussNodes> x, w;
};
const GaussRule& gaussLegendre();
}  // namespace detail

template <typename F>
void LightRings::forEachNode(double u, F&& f) const {
    constexpr double kGolden = 0.6180339887498949;
    const detail::GaussRule& g = detail::gaussLegendre();
    int k = 0;
    auto node = [&](double alpha, const Ring& rg, double weight) {
        double uk = u + kGolden * double(k++);
        uk -= std::floor(uk);
        const double h = 2 * std::pow(std::sin(0.5 * alpha), 2);  // 1 - cos(alpha)
        f(std::log1p(-h), weight, [&] { return direction(rg, azimuthAt(rg, uk)); });
    };
    if (live_ & 1 && cuts_[0] == innermost_) {
        // The disc inside the innermost ring: one node at its middle in alpha^2, its whole solid
        // angle (1 - cos).
        const double alpha = innermost_ / std::sqrt(2.0);
        const Ring rg = ring(alpha);
        if (rg.integral > 0)
            node(alpha, rg, 2 * std::pow(std::sin(0.5 * innermost_), 2) * rg.integral);
    }
    for (int j = 0; j + 1 < cutCount_; ++j) {
        const double u0 = std::log(cuts_[j]), u1 = std::log(cuts_[j + 1]);
        if (!(live_ >> j & 1)) continue;
        const int sub = std::max(1, int(std::ceil((u1 - u0) / std::log(kSubSegment))));
        for (int q = 0; q < sub; ++q) {
            const double a0 = u0 + (u1 - u0) * q / sub, a1 = u0 + (u1 - u0) * (q + 1) / sub;
            for (int i = 0; i < kGaussNodes; ++i) {
                // alpha = exp(a0 + (a1 - a0) (1 - cos th) / 2): nodes crowd both ends, where the
                // arcs open and close as square roots.
                const double th = 0.5 * kPi * (1 + g.x[i]);
                const double alpha = std::exp(a0 + (a1 - a0) * 0.5 * (1 - std::cos(th)));
                const double dAlpha = 0.5 * kPi * g.w[i] * (a1 - a0) * 0.5 * std::sin(th) * alpha;
                const Ring rg = ring(alpha);
                const double weight = rg.sinAlpha * rg.integral * dAlpha;
                if (weight > 0) node(alpha, rg, weight);
            }
        }
    }
}

}  // namespace phongfit
