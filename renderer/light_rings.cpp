#include "light_rings.h"

#include <Eigen/Geometry>
#include <algorithm>

#include "warp.h"

namespace phongfit {

namespace detail {

const GaussRule& gaussLegendre() {
    static const GaussRule rule = [] {
        constexpr int k = LightRings::kGaussNodes;
        GaussRule g;
        for (int i = 0; i < k; ++i) {
            double z = std::cos(kPi * (i + 0.75) / (k + 0.5)), dp = 1;
            for (int it = 0; it < 100; ++it) {
                double p1 = 1, p2 = 0;
                for (int j = 1; j <= k; ++j) {
                    const double p3 = p2;
                    p2 = p1;
                    p1 = ((2 * j - 1) * z * p2 - (j - 1) * p3) / j;
                }
                dp = k * (z * p1 - p2) / (z * z - 1);
                const double step = p1 / dp;
                z -= step;
                if (std::abs(step) < 1e-16) break;
            }
            g.x[i] = z;
            g.w[i] = 2 / ((1 - z * z) * dp * dp);
        }
        return g;
    }();
    return rule;
}

}  // namespace detail

namespace {

double angleBetween(const Vec3d& a, const Vec3d& b) {
    return std::atan2(a.cross(b).norm(), a.dot(b));
}

}  // namespace

LightRings::LightRings(const Vec3d& r, const Vec3d& ns, const Vec3d& ng, const LightCone& cone,
                       double innermost)
    : frame_(r), ns_(ns), innermost_(innermost) {
    std::array<Vec3d, 6> normals;
    std::array<double, 6> offsets;
    auto add = [&](const Vec3d& m, double offset) {
        normals[constraintCount_] = m;
        offsets[constraintCount_] = offset;
        constraints_[constraintCount_++] = {r.dot(m), frame_.s.dot(m), frame_.t.dot(m), offset};
    };
    for (int k = 0; k < cone.planes; ++k) add(cone.normals[k], cone.offsets[k]);
    add(ns, 0);
    if ((ng - ns).squaredNorm() > 1e-24) add(ng, 0);

    // Cuts: where a ring touches a constraint's circle, and where it passes a point on two.
    std::array<double, 64> cand;
    int n = 0;
    cand[n++] = innermost_;
    cand[n++] = kPi / 2;
    for (int i = 0; i < constraintCount_; ++i) {
        const double rho = std::acos(std::clamp(offsets[i], -1.0, 1.0));
        const double gamma = angleBetween(r, normals[i]);
        cand[n++] = std::abs(gamma - rho);
        cand[n++] = gamma + rho;
    }
    for (int i = 0; i < constraintCount_; ++i)
        for (int j = i + 1; j < constraintCount_; ++j) {
            const Vec3d& m1 = normals[i];
            const Vec3d& m2 = normals[j];
            const double d = m1.dot(m2), det = 1 - d * d;
            if (!(det > 1e-14)) continue;
            const double c1 = (offsets[i] - d * offsets[j]) / det;
            const double c2 = (offsets[j] - d * offsets[i]) / det;
            const Vec3d w0 = c1 * m1 + c2 * m2;
            const double t2 = (1 - w0.squaredNorm()) / det;
            if (!(t2 >= 0)) continue;
            const Vec3d across = std::sqrt(t2) * m1.cross(m2);
            for (const Vec3d& w : {Vec3d(w0 + across), Vec3d(w0 - across)}) {
                bool inside = true;
                for (int k = 0; k < constraintCount_; ++k)
                    if (k != i && k != j && normals[k].dot(w) < offsets[k] - 1e-9) inside = false;
                if (inside) cand[n++] = angleBetween(r, w);
            }
        }
    std::sort(cand.begin(), cand.begin() + n);
    for (int i = 0; i < n; ++i) {
        const double a = cand[i];
        if (!(a >= innermost_ && a <= kPi / 2)) continue;
        if (cutCount_ > 0 && a <= cuts_[cutCount_ - 1] * (1 + 1e-12)) continue;
        cuts_[cutCount_++] = a;
    }
    for (int j = 0; j + 1 < cutCount_; ++j)
        if (ring(std::sqrt(cuts_[j] * cuts_[j + 1])).integral > 0) {
            live_ |= std::uint64_t(1) << j;
            if (nearest_ == kPi / 2) nearest_ = j == 0 ? 0 : cuts_[j];
        }
}

LightRings::Ring LightRings::ring(double alpha) const {
    Ring rg;
    rg.cosAlpha = std::cos(alpha);
    rg.sinAlpha = std::sin(alpha);
    rg.arcs[0] = {0, 2 * kPi};
    rg.arcCount = 1;
    for (int c = 0; c < constraintCount_ && rg.arcCount > 0; ++c) {
        const Constraint& k = constraints_[c];
        // dot(w(phi), m) - offset = A + B cos(phi - phi0) >= 0
        const double A = rg.cosAlpha * k.a - k.offset;
        const double b1 = rg.sinAlpha * k.b1, b2 = rg.sinAlpha * k.b2;
        const double B = std::hypot(b1, b2);
        if (A >= B) continue;
        if (A <= -B) {
            rg.arcCount = 0;
            break;
        }
        const double phi0 = std::atan2(b2, b1), h = std::acos(-A / B);
        std::array<std::array<double, 2>, kMaxArcs> kept;
        int count = 0;
        for (int i = 0; i < rg.arcCount; ++i)
            for (int shift = 0; shift <= 1; ++shift) {
                const double lo = std::max(rg.arcs[i][0], phi0 - h + 2 * kPi * shift);
                const double hi = std::min(rg.arcs[i][1], phi0 + h + 2 * kPi * shift);
                if (hi > lo && count < kMaxArcs) kept[count++] = {lo, hi};
            }
        rg.arcs = kept;
        rg.arcCount = count;
    }
    rg.c0 = rg.cosAlpha * frame_.n.dot(ns_);
    rg.c1 = rg.sinAlpha * frame_.s.dot(ns_);
    rg.c2 = rg.sinAlpha * frame_.t.dot(ns_);
    for (int i = 0; i < rg.arcCount; ++i)
        rg.integral += rg.cosIntegral(rg.arcs[i][0], rg.arcs[i][1]);
    return rg;
}

Vec3d LightRings::direction(const Ring& ring, double phi) const {
    return frame_.toWorld(sphericalDirection(ring.sinAlpha, ring.cosAlpha, phi));
}

double LightRings::azimuthAt(const Ring& ring, double t) const {
    double rest = std::clamp(t, 0.0, 1.0) * ring.integral;
    for (int i = 0; i < ring.arcCount; ++i) {
        const auto [p, q] = ring.arcs[i];
        const double whole = ring.cosIntegral(p, q);
        if (rest > whole && i + 1 < ring.arcCount) {
            rest -= whole;
            continue;
        }
        // Newton on the monotone cumulative, kept inside a shrinking bracket.
        double lo = p, hi = q, phi = whole > 0 ? p + (q - p) * std::min(rest / whole, 1.0) : p;
        for (int it = 0; it < 60 && hi - lo > 1e-13; ++it) {
            const double miss = ring.cosIntegral(p, phi) - rest;
            if (miss > 0)
                hi = phi;
            else
                lo = phi;
            const double slope = ring.c0 + ring.c1 * std::cos(phi) + ring.c2 * std::sin(phi);
            const double next = slope > 0 ? phi - miss / slope : 0.5 * (lo + hi);
            phi = next > lo && next < hi ? next : 0.5 * (lo + hi);
            if (std::abs(miss) <= 1e-14 * whole) break;
        }
        return phi;
    }
    return ring.arcCount > 0 ? ring.arcs[0][0] : 0;
}

}  // namespace phongfit
