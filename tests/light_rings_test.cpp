// The ring quadrature of a Phong lobe over an area light (light_rings.h) against values found
// independently: the irradiance of a sphere and of a polygon in closed form, and the lobe's
// integral by a fine polar grid about the mirror direction whose cells are tested for membership
// point by point (no arcs), n 1 to 1e6, with the light inside, across and beside the lobe and
// straddling the horizon.
#include "light_rings.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <vector>

namespace phongfit {
namespace {

LightCone capAbout(const Vec3d& axis, double halfAngle) {
    LightCone c;
    c.normals[0] = axis.normalized();
    c.offsets[0] = std::cos(halfAngle);
    c.planes = 1;
    return c;
}

// A square centred on `centre` (a direction at distance 1), half-side t, facing the origin.
LightCone square(const Vec3d& centre, double t, std::vector<Vec3d>* cornersOut = nullptr) {
    const Vec3d c = centre.normalized();
    const Vec3d s = Vec3d::UnitY().cross(c).normalized(), u = c.cross(s);  // x and y for c = z
    std::vector<Vec3d> corners = {
        (c - t * s - t * u).normalized(), (c + t * s - t * u).normalized(),
        (c + t * s + t * u).normalized(), (c - t * s + t * u).normalized()};
    LightCone cone;
    for (int k = 0; k < 4; ++k) {
        const Vec3d m = corners[k].cross(corners[(k + 1) % 4]);
        cone.normals[k] = (m.dot(c) < 0 ? -m : m).normalized();
    }
    cone.planes = 4;
    if (cornersOut) *cornersOut = corners;
    return cone;
}

bool inside(const LightCone& cone, const Vec3d& w) {
    for (int k = 0; k < cone.planes; ++k)
        if (w.dot(cone.normals[k]) < cone.offsets[k]) return false;
    return true;
}

// (n + 2) / (2 pi) times the integral of cos^n(alpha) cos(theta_i) over the light, above both
// horizons, by the rings.
double lobeByRings(const LightRings& rings, double n) {
    double sum = 0;
    rings.forEachNode(
        0.5, [&](double logCos, double weight, auto) { sum += std::exp(n * logCos) * weight; });
    return (n + 2) / (2 * kPi) * sum;
}

// The same by a polar grid about r: cells tested at their centres, alpha up to where the lobe has
// fallen below 1e-14 of its peak.
double lobeByGrid(const Vec3d& r, const Vec3d& ns, const Vec3d& ng, const LightCone& cone,
                  double farthest, double n) {
    const Frame<double> f(r);
    const double top = std::min({kPi / 2, std::sqrt(2 * 32.3 / n) * 1.2, farthest});
    constexpr int kAlpha = 3000, kPhi = 3000;
    double sum = 0;
    for (int i = 0; i < kAlpha; ++i) {
        const double a = top * (i + 0.5) / kAlpha;
        const double ring = std::pow(std::cos(a), n) * std::sin(a) * top / kAlpha;
        for (int j = 0; j < kPhi; ++j) {
            const double phi = 2 * kPi * (j + 0.5) / kPhi;
            const Vec3d w =
                std::cos(a) * r + std::sin(a) * (std::cos(phi) * f.s + std::sin(phi) * f.t);
            if (!inside(cone, w) || !(w.dot(ng) > 0) || !(w.dot(ns) > 0)) continue;
            sum += ring * w.dot(ns) * 2 * kPi / kPhi;
        }
    }
    return (n + 2) / (2 * kPi) * sum;
}

double irradianceByRings(const LightRings& rings) {
    double sum = 0;
    rings.forEachNode(0.5, [&](double, double weight, auto) { sum += weight; });
    return sum;
}

TEST(LightRings, TheWeightsSumToASpheresIrradiance) {
    // A sphere of angular radius delta, fully above the horizon: pi sin^2(delta) cos(theta).
    const Vec3d ns(0, 0, 1);
    for (double delta : {0.001, 0.04, 0.35})
        for (const Vec3d& axis : {Vec3d(0, 0, 1), Vec3d(0.3, -0.2, 1), Vec3d(1, 0.4, 1.2)})
            for (const Vec3d& r : {Vec3d(0, 0, 1), Vec3d(0.5, 0.1, 1), axis}) {
                const LightRings rings(r.normalized(), ns, ns, capAbout(axis, delta));
                const double exact = kPi * std::pow(std::sin(delta), 2) * axis.normalized().z();
                EXPECT_NEAR(irradianceByRings(rings), exact, 2e-8 * exact)
                    << "delta " << delta << " axis " << axis.transpose() << " r " << r.transpose();
            }
}

TEST(LightRings, TheWeightsSumToAPolygonsIrradiance) {
    // Lambert's formula: half the sum over edges of the edge's angle times cos(its plane, ns).
    const Vec3d ns = Vec3d(0.3, -0.2, 1).normalized();
    for (double t : {0.002, 0.04, 0.36})
        for (const Vec3d& r : {Vec3d(0, 0, 1), Vec3d(0.2, 0.1, 1), Vec3d(0.9, 0.3, 1)}) {
            std::vector<Vec3d> v;
            const LightCone cone = square(Vec3d(0.05, -0.03, 1), t, &v);
            double signedSum = 0;
            for (int k = 0; k < 4; ++k) {
                const Vec3d m = v[k].cross(v[(k + 1) % 4]).normalized();
                signedSum += 0.5 * std::acos(v[k].dot(v[(k + 1) % 4])) * m.dot(ns);
            }
            const double exact = std::abs(signedSum);
            const LightRings rings(r.normalized(), ns, ns, cone);
            EXPECT_NEAR(irradianceByRings(rings), exact, 2e-8 * exact)
                << "half-side " << t << " r " << r.transpose();
        }
}

TEST(LightRings, TheLobeMatchesAPolarGridFromN1To1e6) {
    struct Case {
        const char* what;
        Vec3d r, ns, ng;
        LightCone cone;
        double farthest;  // from r, of the light's points
    };
    auto angle = [](const Vec3d& a, const Vec3d& b) {
        return std::acos(a.normalized().dot(b.normalized()));
    };
    auto capCase = [&](const char* what, const Vec3d& r, const Vec3d& ns, const Vec3d& ng,
                       const Vec3d& axis, double delta) {
        return Case{what,
                    r.normalized(),
                    ns.normalized(),
                    ng.normalized(),
                    capAbout(axis, delta),
                    angle(r, axis) + delta};
    };
    auto squareCase = [&](const char* what, const Vec3d& r, const Vec3d& ns, const Vec3d& ng,
                          const Vec3d& centre, double t) {
        std::vector<Vec3d> v;
        const LightCone cone = square(centre, t, &v);
        double far = 0;
        for (const Vec3d& c : v) far = std::max(far, angle(r, c));
        return Case{what, r.normalized(), ns.normalized(), ng.normalized(), cone, far};
    };
    const Vec3d up(0, 0, 1), tilted = Vec3d(0.3, -0.2, 1).normalized();
    const std::vector<Case> cases = {
        squareCase("r inside a 40-degree square", Vec3d(0.1, 0.05, 1), tilted, tilted,
                   Vec3d(0.05, -0.03, 1), 0.36),
        squareCase("r on a 5-degree square's edge", Vec3d(0.04, 0.0, 1), tilted, tilted, up, 0.04),
        squareCase("r beside a 5-degree square's corner", Vec3d(0.043, 0.045, 1), up, up, up, 0.04),
        capCase("r inside a 40-degree sphere", Vec3d(0.1, 0.2, 1), tilted, tilted, Vec3d(0, 0.1, 1),
                0.35),
        capCase("r on a 5-degree sphere's rim", Vec3d(std::tan(0.0437), 0, 1), up, up, up, 0.0437),
        capCase("a sphere across the horizon, normals apart", Vec3d(1, 0, 0.4), up,
                Vec3d(0.05, 0, 1), Vec3d(1, 0, 0.1), 0.3),
        squareCase("a square across the horizon", Vec3d(1, 0.1, 0.3), up, up, Vec3d(1, 0, 0.05),
                   0.25),
    };
    for (const Case& c : cases) {
        const LightRings rings(c.r, c.ns, c.ng, c.cone);
        for (double n : {1.0, 30.0, 1e3, 3e4, 1e6}) {
            const double grid = lobeByGrid(c.r, c.ns, c.ng, c.cone, c.farthest, n);
            const double byRings = lobeByRings(rings, n);
            // The grid's membership steps leave ~1e-5 relative at 3000^2 cells.
            EXPECT_NEAR(byRings, grid, 1e-4 * grid + 1e-12) << c.what << ", n " << n;
        }
    }
}

TEST(LightRings, DirectionsLieOnTheirRingInsideTheLight) {
    const Vec3d ns = Vec3d(0.3, -0.2, 1).normalized();
    const LightCone cone = square(Vec3d(0.05, -0.03, 1), 0.36);
    const Vec3d r = Vec3d(0.4, 0.05, 1).normalized();
    const LightRings rings(r, ns, ns, cone);
    int nodes = 0;
    rings.forEachNode(0.37, [&](double logCos, double, auto draw) {
        const Vec3d wi = draw();
        ++nodes;
        EXPECT_NEAR(wi.norm(), 1, 1e-12);
        EXPECT_NEAR(std::log(wi.dot(r)), logCos, 1e-9);
        for (int k = 0; k < cone.planes; ++k) EXPECT_GE(wi.dot(cone.normals[k]), -1e-12);
        EXPECT_GT(wi.dot(ns), 0);
    });
    EXPECT_GT(nodes, 10);
}

TEST(LightRings, AzimuthsAreDrawnByCosThetaI) {
    // On one ring the cos(theta_i)-weighted share of the arcs before azimuthAt(t) is t: checked by
    // summing cos(theta_i) over a fine azimuth grid.
    const Vec3d ns = Vec3d(0.6, -0.2, 1).normalized();
    const LightRings rings(Vec3d(0, 0, 1), ns, ns, square(Vec3d(0.05, -0.03, 1), 0.36));
    const LightRings::Ring ring = rings.ring(0.2);
    ASSERT_GT(ring.integral, 0);
    for (double t : {0.1, 0.35, 0.5, 0.8, 0.99}) {
        const double target = rings.azimuthAt(ring, t);
        double before = 0, all = 0;
        for (int i = 0; i < ring.arcCount; ++i) {
            const auto [p, q] = ring.arcs[i];
            constexpr int kSteps = 200000;
            for (int s = 0; s < kSteps; ++s) {
                const double phi = p + (q - p) * (s + 0.5) / kSteps;
                const double w = rings.direction(ring, phi).dot(ns) * (q - p) / kSteps;
                all += w;
                if (phi < target) before += w;
            }
        }
        EXPECT_NEAR(all, ring.integral, 1e-8 * ring.integral);
        EXPECT_NEAR(before / all, t, 1e-5) << "t " << t;
    }
}

TEST(LightRings, NothingBelowTheHorizonOrBeyondTheLobe) {
    const Vec3d up(0, 0, 1);
    // A light entirely below the horizon gives no node.
    const LightRings below(up, up, up, capAbout(Vec3d(1, 0, -0.5), 0.2));
    EXPECT_EQ(irradianceByRings(below), 0);
    EXPECT_EQ(below.nearest(), kPi / 2);
    // The nearest ring: 0 with r inside, the gap to the rim beside it.
    EXPECT_EQ(LightRings(up, up, up, capAbout(up, 0.1)).nearest(), 0);
    const Vec3d r = Vec3d(std::sin(0.5), 0, std::cos(0.5));
    EXPECT_NEAR(LightRings(r, up, up, capAbout(up, 0.1)).nearest(), 0.4, 1e-12);
}

}  // namespace
}  // namespace phongfit
