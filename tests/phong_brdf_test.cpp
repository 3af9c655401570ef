#include "phong_brdf.h"

#include <ceres/jet.h>
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <array>
#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "chi_square.h"
#include "error.h"
#include "rng.h"

namespace phongfit {
namespace {

using Jet = ceres::Jet<double, 7>;  // kd (3), ks (3), log n

constexpr double kDegree = kPi / 180;

Vec3d outgoing(double thetaDeg) {
    return Vec3d(std::sin(thetaDeg * kDegree), 0, std::cos(thetaDeg * kDegree));
}

PhongMaterial gray(double kd, double ks, double n) {
    PhongMaterial m;
    m.kd = Color3::Constant(kd);
    m.ks = Color3::Constant(ks);
    m.n = n;
    return m;
}

double value(double x) { return x; }
double value(float x) { return x; }

// ---------------------------------------------------------------------------------------------
// Closed-form values at normal incidence: wi = wo = n, cos(alpha) = 1, so
// f = kd / pi + ks (n + 2) / (2 pi).

template <typename T>
void expectEvaluateTable() {
    struct Row {
        double ks, kd, f;
    };
    const std::array<Row, 4> table = {
        {{0.5, 0.5, 7 / (2 * kPi)}, {0, 0, 0}, {0, 1, 1 / kPi}, {1, 0, 6 / kPi}}};
    const Vec3<T> normal(T(0), T(0), T(1));
    for (const Row& row : table) {
        PhongParams<T> p;
        p.kd = Color<T>::Constant(T(row.kd));
        p.ks = Color<T>::Constant(T(row.ks));
        p.n = T(10);
        const Color<T> f = phongEval(p, normal, normal);
        for (int c = 0; c < 3; ++c)
            EXPECT_NEAR(value(f[c]), row.f, 1e-6) << "ks=" << row.ks << " kd=" << row.kd;
    }
}

TEST(PhongBrdf, EvaluateTableAtNormalIncidenceDouble) { expectEvaluateTable<double>(); }
TEST(PhongBrdf, EvaluateTableAtNormalIncidenceFloat) { expectEvaluateTable<float>(); }

TEST(PhongBrdf, EvaluateTableAtNormalIncidenceJet) {
    const Vec3d normal(0, 0, 1);
    struct Row {
        double ks, kd, f;
    };
    for (const Row& row :
         {Row{0.5, 0.5, 7 / (2 * kPi)}, Row{0, 0, 0}, Row{0, 1, 1 / kPi}, Row{1, 0, 6 / kPi}}) {
        PhongParams<Jet> p;
        for (int c = 0; c < 3; ++c) {
            p.kd[c] = Jet(row.kd, c);
            p.ks[c] = Jet(row.ks, 3 + c);
        }
        p.n = Jet(10);
        const Color<Jet> f = phongEval(p, normal, normal);
        for (int c = 0; c < 3; ++c) {
            EXPECT_NEAR(f[c].a, row.f, 1e-6) << "ks=" << row.ks << " kd=" << row.kd;
            // f is linear in kd and ks: df/dkd = 1 / pi, df/dks = (n + 2) / (2 pi), per channel.
            EXPECT_NEAR(f[c].v[c], 1 / kPi, 1e-12);
            EXPECT_NEAR(f[c].v[3 + c], 6 / kPi, 1e-12);
        }
    }
}

TEST(PhongBrdf, ZeroOnAndBelowTheHorizon) {
    const PhongMaterial m = gray(0.3, 0.6, 10);
    const Vec3d above = outgoing(30), below(0.6, 0, -0.8), horizon(1, 0, 0);
    for (const Vec3d& w : {below, horizon}) {
        EXPECT_TRUE((phongEval(m, w, above) == 0).all());
        EXPECT_TRUE((phongEval(m, above, w) == 0).all());
    }
}

// The form the fitter replays recorded vertices with is the same function.
TEST(PhongBrdf, LogCosFormIsTheEvaluatedForm) {
    const PhongMaterial m = gray(0.2, 0.7, 55);
    const CounterRng rng(3, 0);
    for (int i = 0; i < 1000; ++i) {
        const Vec3d wo = outgoing(89 * rng.uniform(i, 0)),
                    wi = Vec3d(rng.uniform(i, 1) - 0.5, rng.uniform(i, 2) - 0.5, 0.9).normalized();
        const Color3 a = phongEval(m, wi, wo), b = phongEvalLogCos(m, logCosAlpha(wi, wo));
        EXPECT_TRUE((a == b).all()) << a.transpose() << " vs " << b.transpose();
    }
}

// ---------------------------------------------------------------------------------------------
// Reciprocity: f(wi, wo) = f(wo, wi), since |r(wo) - wi| = |r(wi) - wo|.

Vec3d randomUpperDirection(const CounterRng& rng, std::uint64_t i, std::uint32_t dim) {
    const double z = 1 - rng.uniform(i, dim), phi = 2 * kPi * rng.uniform(i, dim + 1);
    const double s = std::sqrt(std::max(0.0, 1 - z * z));
    return Vec3d(s * std::cos(phi), s * std::sin(phi), z);
}

TEST(PhongBrdf, Reciprocity) {
    const CounterRng rng(11, 0);
    for (int i = 0; i < 5000; ++i) {
        PhongMaterial m;
        m.kd = Color3(rng.uniform(i, 0), rng.uniform(i, 1), rng.uniform(i, 2)) * 0.5;
        m.ks = Color3(rng.uniform(i, 3), rng.uniform(i, 4), rng.uniform(i, 5)) * 0.5;
        m.n = std::pow(10.0, 4 * rng.uniform(i, 6));  // 1 to 1e4
        const Vec3d wi = randomUpperDirection(rng, i, 7), wo = randomUpperDirection(rng, i, 9);
        const Color3 a = phongEval(m, wi, wo), b = phongEval(m, wo, wi);
        for (int c = 0; c < 3; ++c) EXPECT_NEAR(a[c], b[c], 1e-12 * std::max(1.0, a[c]));
        PhongParams<float> mf;
        mf.kd = m.kd.cast<float>();
        mf.ks = m.ks.cast<float>();
        mf.n = float(m.n);
        const Color<float> af = phongEval(mf, Vec3f(wi.cast<float>()), Vec3f(wo.cast<float>()));
        const Color<float> bf = phongEval(mf, Vec3f(wo.cast<float>()), Vec3f(wi.cast<float>()));
        for (int c = 0; c < 3; ++c) EXPECT_NEAR(af[c], bf[c], 1e-5f * std::max(1.0f, af[c]));
    }
}

// ---------------------------------------------------------------------------------------------
// Directional albedo a(wo) = integral of f cos(theta_i) over wi, by quadrature in (h, phi)
// coordinates around the mirror direction (chi_square.h), which resolves lobes up to n = 1e4 and
// splits the integral exactly at the horizon.

std::vector<double> mirrorEdges(double n) {
    // Rows of equal lobe probability (h has CDF 1 - (1 - h)^(n + 1)), the lobe's kink at h = 1.
    std::vector<double> e = {0, 1, 2};
    for (const double q : {0.1, 0.3, 0.5, 0.7, 0.9, 0.99, 0.999, 0.9999})
        e.push_back(-std::expm1(std::log1p(-q) / (n + 1)));
    for (int k = 1; k < 8; ++k) e.push_back(k / 4.0);
    std::sort(e.begin(), e.end());
    e.erase(std::unique(e.begin(), e.end(), [](double a, double b) { return b - a < 1e-12; }),
            e.end());
    return e;
}

double albedo(const PhongMaterial& m, const Vec3d& wo, int channel = 0) {
    auto fCos = [&](const Vec3d& wi) { return phongEval(m, wi, wo)[channel] * wi.z(); };
    return integrateSphere(fCos, AxisCoordinates(reflectLocal(wo)), mirrorEdges(m.n),
                           Hemisphere::Upper, 1e-11);
}

constexpr std::array<double, 6> kExponents = {0, 1, 10, 100, 1000, 10000};

TEST(PhongBrdfAlbedo, DiffuseOnlyIsKd) {
    for (const double n : kExponents)
        for (const double theta : {0.0, 30.0, 60.0, 85.0, 89.9})
            EXPECT_NEAR(albedo(gray(0.7, 0, n), outgoing(theta)), 0.7, 1e-9)
                << "n=" << n << " theta_o=" << theta;
}

// At theta_o = 0 the lobe (n + 2) / (2 pi) cos^n(theta_i) cos(theta_i) integrates to
// (n + 2) / (2 pi) * 2 pi / (n + 2) = 1 exactly.
TEST(PhongBrdfAlbedo, SpecularOnlyAtNormalIncidenceIsOne) {
    for (const double n : kExponents)
        EXPECT_NEAR(albedo(gray(0, 1, n), outgoing(0)), 1, 1e-9) << "n=" << n;
}

// n = 0: the lobe is 1 / pi over the hemisphere alpha < 90 degrees around the mirror direction; the
// integral of cos(theta_i) over its part above the horizon is the projected area of that lune,
// pi (1 + cos theta_o) / 2 (the unit disk minus half the ellipse the lune's rim projects to).
TEST(PhongBrdfAlbedo, SpecularOnlyWithExponentZero) {
    for (const double theta : {0.0, 20.0, 45.0, 70.0, 89.9}) {
        const double expected = (1 + std::cos(theta * kDegree)) / 2;
        EXPECT_NEAR(albedo(gray(0, 1, 0), outgoing(theta)), expected, 1e-9) << theta;
    }
}

// Over the whole lobe (both sides of the horizon, cos(theta_i) signed), the azimuthal integral
// leaves cos(theta_o) (n + 2) / (2 pi) * 2 pi / (n + 2) = cos(theta_o): checks the lobe's
// normalisation and the quadrature for sharp lobes at grazing angles.
TEST(PhongBrdfAlbedo, WholeLobeWithSignedCosineIsCosThetaO) {
    for (const double n : kExponents)
        for (const double theta : {0.0, 45.0, 80.0, 89.9}) {
            const Vec3d wo = outgoing(theta);
            auto lobe = [&](const Vec3d& wi) {
                return (n + 2) / (2 * kPi) * phongPower(n, logCosAlpha(wi, wo)) * wi.z();
            };
            const AxisCoordinates coords(reflectLocal(wo));
            const double total =
                integrateSphere(lobe, coords, mirrorEdges(n), Hemisphere::Upper, 1e-11) +
                integrateSphere(lobe, coords, mirrorEdges(n), Hemisphere::Lower, 1e-11);
            EXPECT_NEAR(total, wo.z(), 1e-9) << "n=" << n << " theta_o=" << theta;
        }
}

// A sharp lobe far from the horizon loses nothing to it: the albedo is cos(theta_o).
TEST(PhongBrdfAlbedo, SharpLobeAwayFromTheHorizonIsCosThetaO) {
    for (const double theta : {10.0, 45.0, 60.0})
        EXPECT_NEAR(albedo(gray(0, 1, 10000), outgoing(theta)), std::cos(theta * kDegree), 1e-9)
            << theta;
}

// Energy conservation: kd + ks = 1 never reflects more than it receives, at any angle.
TEST(PhongBrdfAlbedo, AtMostOneWhenKdPlusKsIsOne) {
    double worst = 0;
    for (const double kd : {0.0, 0.2, 0.5, 1.0})
        for (const double n : kExponents)
            for (double theta = 0; theta < 90; theta += 7.5) {
                const double a = albedo(gray(kd, 1 - kd, n), outgoing(theta));
                worst = std::max(worst, a);
                EXPECT_LE(a, 1 + 1e-9) << "kd=" << kd << " n=" << n << " theta_o=" << theta;
            }
    EXPECT_NEAR(worst, 1, 1e-9);  // attained at normal incidence
}

// Cross-check of the mirror-frame quadrature against one in (theta_i, phi_i) around the normal, for
// lobes broad enough for it. The clamp of cos(alpha) at 0 is a kink that fools the error estimate
// of an adaptive rule, so each row is split where it crosses the lobe's rim dot(r, wi) = 0: cos(phi
// - pi) = -cot(theta_i) cot(theta_o), the mirror direction r being at azimuth pi.
TEST(PhongBrdfAlbedo, MatchesAQuadratureAroundTheNormal) {
    for (const double n : {1.0, 10.0})
        for (const double theta : {30.0, 60.0, 85.0}) {
            const PhongMaterial m = gray(0.2, 0.8, n);
            const Vec3d wo = outgoing(theta);
            const double tanThetaO = std::tan(theta * kDegree);
            auto row = [&](double thetaI) {
                auto g = [&](double phi) {
                    const Vec3d wi(std::sin(thetaI) * std::cos(phi),
                                   std::sin(thetaI) * std::sin(phi), std::cos(thetaI));
                    return phongEval(m, wi, wo)[0] * wi.z() * std::sin(thetaI);
                };
                const double c = -1 / (std::tan(thetaI) * tanThetaO);
                if (!(std::abs(c) < 1)) return integrateAdaptive(g, 0, 2 * kPi, 1e-13, 1e-12);
                const double a = kPi - std::acos(c), b = kPi + std::acos(c);
                return integrateAdaptive(g, 0, a, 1e-13, 1e-12) +
                       integrateAdaptive(g, a, b, 1e-13, 1e-12) +
                       integrateAdaptive(g, b, 2 * kPi, 1e-13, 1e-12);
            };
            const double rim = kPi / 2 - theta * kDegree;  // where rows start to cross the rim
            const double reference = integrateAdaptive(row, 0, rim, 1e-12, 1e-12) +
                                     integrateAdaptive(row, rim, kPi / 2, 1e-12, 1e-12);
            EXPECT_NEAR(albedo(m, wo), reference, 1e-9) << "n=" << n << " theta_o=" << theta;
        }
}

// ---------------------------------------------------------------------------------------------
// Stiff and extreme cases.

// A direction at angle alpha from the mirror of wo, rotated by phi about it.
Vec3d aroundMirror(const Vec3d& wo, double alpha, double phi) {
    return Frame<double>(reflectLocal(wo))
        .toWorld(Vec3d(std::sin(alpha) * std::cos(phi), std::sin(alpha) * std::sin(phi),
                       std::cos(alpha)));
}

TEST(PhongBrdfExtreme, EvalIsFiniteEverywhere) {
    const std::vector<double> alphas = {0, 1e-9, 1e-4, 0.1, 1.0, kPi / 2, 2.0, kPi};
    for (const double n : {0.0, 1e-6, 1e4, 1e6})
        for (const auto& [kd, ks] :
             {std::pair{0.3, 0.6}, {0.0, 0.6}, {0.3, 0.0}, {0.0, 0.0}, {0.4, 0.6}})
            for (const double theta : {0.0, 45.0, 89.999, 90.0, 120.0})
                for (const double alpha : alphas) {
                    const Vec3d wo = outgoing(theta), wi = aroundMirror(wo, alpha, 0.7);
                    const std::string where = fmt::format("n={} kd={} ks={} theta_o={} alpha={}", n,
                                                          kd, ks, theta, alpha);
                    const Color3 f = phongEval(gray(kd, ks, n), wi, wo);
                    EXPECT_TRUE(f.allFinite() && (f >= 0).all()) << where << ": " << f.transpose();
                    PhongParams<float> pf;
                    pf.kd = Color<float>::Constant(float(kd));
                    pf.ks = Color<float>::Constant(float(ks));
                    pf.n = float(n);
                    const Color<float> ff =
                        phongEval(pf, Vec3f(wi.cast<float>()), Vec3f(wo.cast<float>()));
                    EXPECT_TRUE(ff.allFinite() && (ff >= 0).all()) << where << " (float)";
                }
}

// The fitter's parameters as Jets: kd, ks (derivative slots 0-5) and n = exp(logN) (slot 6).
PhongParams<Jet> jetParams(const Color3& kd, const Color3& ks, double logN) {
    PhongParams<Jet> p;
    for (int c = 0; c < 3; ++c) {
        p.kd[c] = Jet(kd[c], c);
        p.ks[c] = Jet(ks[c], 3 + c);
    }
    p.n = exp(Jet(logN, 6));
    return p;
}

Color<Jet> evalJet(const Color3& kd, const Color3& ks, double logN, const Vec3d& wi,
                   const Vec3d& wo) {
    return phongEval(jetParams(kd, ks, logN), wi, wo);
}

// The 7 parameters as one vector, for finite differences.
Color3 evalParams(const Eigen::Matrix<double, 7, 1>& x, const Vec3d& wi, const Vec3d& wo) {
    PhongMaterial m;
    m.kd = x.head<3>();
    m.ks = x.segment<3>(3);
    m.n = std::exp(x[6]);
    return phongEval(m, wi, wo);
}

TEST(PhongBrdfExtreme, JetDerivativesAreFiniteAndMatchFiniteDifferences) {
    const Color3 kd(0.3, 0.1, 0.5), ks(0.6, 0.8, 0.5);
    int compared = 0;
    for (const double n : {1e-6, 1.0, 10.0, 1e4, 1e6})
        for (const double theta : {0.0, 45.0, 89.999})
            // Angles where the lobe is at its peak, on its flank, in its tail, and gone.
            for (const double nh : {0.0, 0.5, 3.0, 30.0, 1e9}) {
                const double h = std::min(nh / n, 1.5);
                const Vec3d wo = outgoing(theta), wi = aroundMirror(wo, std::acos(1 - h), 2.0);
                const std::string where = fmt::format("n={} theta_o={} n*h={}", n, theta, nh);
                const Color<Jet> f = evalJet(kd, ks, std::log(n), wi, wo);
                for (int c = 0; c < 3; ++c)
                    ASSERT_TRUE(std::isfinite(f[c].a) && f[c].v.allFinite()) << where;
                if (!(wi.z() > 1e-3)) continue;  // not smooth across the horizon
                Eigen::Matrix<double, 7, 1> x;
                x << kd, ks, std::log(n);
                for (int k = 0; k < 7; ++k) {
                    const double step = 1e-5;
                    Eigen::Matrix<double, 7, 1> lo = x, hi = x;
                    lo[k] -= step;
                    hi[k] += step;
                    const Color3 fd =
                        (evalParams(hi, wi, wo) - evalParams(lo, wi, wo)) / (2 * step);
                    for (int c = 0; c < 3; ++c) {
                        const double scale = std::max({std::abs(fd[c]), f[c].a, 1e-300});
                        EXPECT_NEAR(f[c].v[k], fd[c], 1e-6 * scale)
                            << where << " channel " << c << " parameter " << k;
                        ++compared;
                    }
                }
            }
    EXPECT_GT(compared, 500);
}

// n = 0 exactly (log n = -infinity): derivatives with respect to n itself stay finite.
TEST(PhongBrdfExtreme, JetDerivativesAtExponentZero) {
    for (const double theta : {0.0, 45.0, 89.999})
        for (const double alpha : {0.0, 0.5, 1.2, 2.0}) {
            const Vec3d wo = outgoing(theta), wi = aroundMirror(wo, alpha, 1.0);
            PhongParams<Jet> p;
            p.kd = Color<Jet>::Constant(Jet(0.4, 0));
            p.ks = Color<Jet>::Constant(Jet(0.6, 3));
            p.n = Jet(0.0, 6);
            const Color<Jet> f = phongEval(p, wi, wo);
            for (int c = 0; c < 3; ++c)
                EXPECT_TRUE(std::isfinite(f[c].a) && f[c].v.allFinite())
                    << "theta_o=" << theta << " alpha=" << alpha;
            if (!(wi.z() > 1e-3) || alpha >= kPi / 2) continue;
            // df/dn at n = 0: ks / (2 pi) (1 + 2 log cos alpha), against a one-sided difference.
            const double expected = 0.6 / (2 * kPi) * (1 + 2 * std::log(std::cos(alpha)));
            EXPECT_NEAR(f[0].v[6], expected, 1e-9) << "theta_o=" << theta << " alpha=" << alpha;
            const double forward = (phongEval(gray(0.4, 0.6, 1e-7), wi, wo)[0] -
                                    phongEval(gray(0.4, 0.6, 0), wi, wo)[0]) /
                                   1e-7;
            EXPECT_NEAR(f[0].v[6], forward, 1e-5) << "theta_o=" << theta << " alpha=" << alpha;
        }
}

// For alpha = 1e-4 and n = 1e6, cos^n(alpha) = exp(-5e-3): the stable form exp(n log1p(-h)) gets it
// in double (and even float), while the naive float power of a dot product that rounds to 1 does
// not.
TEST(PhongBrdfExtreme, StableCosPowerForTinyAnglesAndHugeExponents) {
    const double alpha = 1e-4, n = 1e6;
    const long double reference =
        0.5L * (n + 2) / (2 * std::numbers::pi_v<long double>)*std::pow(std::cos(1e-4L), n);
    for (const double theta : {0.0, 30.0, 70.0}) {
        const Vec3d wo = outgoing(theta), wi = aroundMirror(wo, alpha, 0.3);
        const double f = phongEval(gray(0, 0.5, n), wi, wo)[0];
        EXPECT_NEAR(f / double(reference), 1, 1e-6) << theta;

        PhongParams<float> pf;
        pf.ks = Color<float>::Constant(0.5f);
        pf.n = float(n);
        const Vec3f wiF = wi.cast<float>(), woF = wo.cast<float>();
        const float stableF = phongEval(pf, wiF, woF)[0];
        EXPECT_NEAR(stableF / double(reference), 1, 1e-4) << theta;

        const Vec3f r = reflectLocal(woF);
        const float naive = 0.5f * (pf.n + 2) / float(2 * kPi) * std::pow(r.dot(wiF), pf.n);
        EXPECT_GT(std::abs(naive / double(reference) - 1), 1e-3) << theta << ": naive " << naive;
    }
}

// expOrZero skips exp only where exp is exactly 0: the same bits as exp on both sides of its
// cut, for floats, doubles and Jets (value and derivatives, signs of zero included).
template <typename S>
void expectExpOrZeroIsExp(S from, S to) {
    for (S x = from; x <= to; x += S(0.0137)) {
        EXPECT_EQ(std::bit_cast<std::uint64_t>(double(expOrZero(x))),
                  std::bit_cast<std::uint64_t>(double(std::exp(x))))
            << x;
        const Jet j(x, Eigen::Matrix<double, 7, 1>(-1.5, 2, 0, -0.0, 3, -7, 1e300));
        const Jet a = expOrZero(j), b = ceres::exp(j);
        EXPECT_EQ(std::bit_cast<std::uint64_t>(a.a), std::bit_cast<std::uint64_t>(b.a)) << x;
        for (int k = 0; k < 7; ++k)
            EXPECT_EQ(std::bit_cast<std::uint64_t>(a.v[k]), std::bit_cast<std::uint64_t>(b.v[k]))
                << x << " " << k;
    }
}

TEST(PhongBrdfExtreme, ExpOrZeroIsExpBitForBit) {
    expectExpOrZeroIsExp<double>(-760, -700);
    expectExpOrZeroIsExp<float>(-110, -90);
    EXPECT_EQ(expOrZero(-1e6), 0.0);
    EXPECT_EQ(expOrZero(-1e6f), 0.0f);
    EXPECT_TRUE(std::isnan(expOrZero(std::numeric_limits<double>::quiet_NaN())));
    EXPECT_EQ(expOrZero(0.0), 1.0);
}

// phongEvalLogCos is the full formula with the lobe cut at kLobeTail: to the last bit above the
// cut (the lobe's arithmetic included) and the diffuse term alone below it, for floats, doubles
// and Jets (the fitter's: kd, ks and log n as parameters), at kd = 0 and ks = 0 too.
template <typename T, typename D>
void expectLobeCutAtItsTail(const PhongParams<T>& p, D logCos) {
    using std::exp;
    const T x = p.n * T(logCos);
    const bool cut = logCos == -std::numeric_limits<D>::infinity() || x < T(kLobeTail);
    const T power = cut ? T(0) : exp(x);
    const Color<T> full = p.kd * T(kInvPi) + p.ks * ((p.n + T(2)) * T(0.5 * kInvPi) * power);
    const Color<T> f = phongEvalLogCos(p, logCos);
    for (int c = 0; c < 3; ++c) {
        if constexpr (std::is_floating_point_v<T>) {
            EXPECT_EQ(std::bit_cast<std::uint64_t>(double(f[c])),
                      std::bit_cast<std::uint64_t>(double(full[c])))
                << logCos;
            if (cut) {
                EXPECT_EQ(f[c], p.kd[c] * T(kInvPi)) << logCos;
            }
        } else {
            EXPECT_EQ(std::bit_cast<std::uint64_t>(f[c].a), std::bit_cast<std::uint64_t>(full[c].a))
                << logCos;
            for (int k = 0; k < 7; ++k)
                EXPECT_EQ(std::bit_cast<std::uint64_t>(f[c].v[k]),
                          std::bit_cast<std::uint64_t>(full[c].v[k]))
                    << logCos << " " << k;
        }
    }
}

TEST(PhongBrdfExtreme, LobeIsTheFullFormulaCutAtItsTail) {
    const double inf = std::numeric_limits<double>::infinity();
    for (const auto& [kd, ks] : {std::pair{0.3, 0.5}, {0.0, 0.5}, {0.45, 0.0}, {0.0, 0.0}})
        for (const double n : {30.0, 3e4, 1e6}) {
            PhongParams<double> d;
            PhongParams<float> f;
            d.kd = Color3(kd, 0.5 * kd, 0.25 * kd);
            d.ks = Color3::Constant(ks);
            d.n = n;
            f.kd = d.kd.cast<float>();
            f.ks = d.ks.cast<float>();
            f.n = float(n);
            const PhongParams<Jet> j = jetParams(d.kd, d.ks, std::log(n));
            // n log(cos alpha) from -800 to 0: across the tail's cut and exp's own (-746).
            for (double x = -800; x <= 0; x += 0.37) {
                expectLobeCutAtItsTail(d, x / n);
                expectLobeCutAtItsTail(j, x / n);
                expectLobeCutAtItsTail(f, float(x / n));
            }
            expectLobeCutAtItsTail(d, -inf);
            expectLobeCutAtItsTail(j, -inf);
            expectLobeCutAtItsTail(f, -std::numeric_limits<float>::infinity());
        }
}

// What the cut leaves out of a term is below a twentieth of half an ulp of the lobe's peak (1 at
// alpha = 0), at every exponent; the cut falls where n log(cos alpha) crosses kLobeTail.
TEST(PhongBrdfExtreme, LobeTailCutIsBelowDoublePrecision) {
    EXPECT_LT(std::exp(kLobeTail), 0.5 * std::numeric_limits<double>::epsilon() / 20);
    for (const double n : {1.0, 30.0, 3e4, 1e6}) {
        const double above = (kLobeTail + 1e-9) / n, below = (kLobeTail - 1e-9) / n;
        EXPECT_EQ(phongPower(n, above), std::exp(n * above)) << n;
        EXPECT_EQ(phongPower(n, below), 0.0) << n;
    }
}

// ---------------------------------------------------------------------------------------------
// Material validation.

void expectRejected(const PhongMaterial& m, const std::vector<std::string>& mentions) {
    try {
        validatePhong(m, "bsdf 'ball' (scene.xml:12)");
        ADD_FAILURE() << "accepted an invalid material, expected an error mentioning "
                      << mentions.front();
    } catch (const Error& e) {
        const std::string message = e.what();
        EXPECT_NE(message.find("bsdf 'ball' (scene.xml:12)"), std::string::npos) << message;
        for (const std::string& m : mentions)
            EXPECT_NE(message.find(m), std::string::npos)
                << "'" << m << "' missing in: " << message;
        EXPECT_EQ(message.find('\n'), std::string::npos) << message;
    }
}

TEST(PhongValidation, RejectsValuesOutsideTheDomain) {
    const double nan = std::numeric_limits<double>::quiet_NaN();
    const double inf = std::numeric_limits<double>::infinity();
    PhongMaterial m = gray(0.3, 0.6, 10);
    m.kd[1] = -0.1;
    expectRejected(m, {"kd", "-0.1", "channel G", ">= 0"});
    m = gray(0.3, 0.6, 10);
    m.ks[2] = -0.25;
    expectRejected(m, {"ks", "-0.25", "channel B", ">= 0"});
    m = gray(0.5, 0.4, 10);
    m.ks[0] = 0.75;
    expectRejected(m, {"kd + ks", "0.5", "0.75", "1.25", "channel R", "<= 1"});
    m = gray(0.3, 0.6, -1);
    expectRejected(m, {"n = -1", ">= 0"});
    m = gray(0.3, 0.6, nan);
    expectRejected(m, {"n = nan", "finite"});
    m = gray(0.3, 0.6, inf);
    expectRejected(m, {"n = inf", "finite"});
    m = gray(0.3, 0.6, 10);
    m.kd[0] = nan;
    expectRejected(m, {"kd = nan", "finite"});
    m = gray(0.3, 0.6, 10);
    m.ks[1] = nan;
    expectRejected(m, {"ks = nan", "finite"});
}

TEST(PhongValidation, AcceptsTheBoundary) {
    for (const auto& [kd, ks] : {std::pair{0.3, 0.7},
                                 {0.1, 0.9},
                                 {1.0, 0.0},
                                 {0.0, 1.0},
                                 {0.0, 0.0},
                                 {0.7, 0.3},
                                 {0.2, 0.8}})
        EXPECT_NO_THROW(validatePhong(gray(kd, ks, 0), "m")) << kd << " + " << ks;
    EXPECT_NO_THROW(validatePhong(gray(0.5, 0.5, 1e6), "m"));
}

// A material on kd + ks = 1 written with 6 significant digits (printf's %g) sums to just above 1.
TEST(PhongValidation, AcceptsASumOnTheBoundaryRoundedToSixDigits) {
    EXPECT_NO_THROW(validatePhong(gray(0.942818, 0.0571824, 1), "m"));
    EXPECT_NO_THROW(validatePhong(gray(0.500001, 0.500000, 1), "m"));
    expectRejected(gray(0.500003, 0.5, 1), {"kd + ks", "0.500003", "<= 1"});
}

}  // namespace
}  // namespace phongfit
