#include "phong_sampler.h"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "chi_square.h"
#include "error.h"
#include "rng.h"
#include "warp.h"

namespace phongfit {
namespace {

constexpr double kDegree = kPi / 180;

Vec3d outgoing(double thetaDeg) {
    return Vec3d(std::sin(thetaDeg * kDegree), 0, std::cos(thetaDeg * kDegree));
}

PhongMaterial material(const Color3& kd, const Color3& ks, double n) {
    PhongMaterial m;
    m.kd = kd;
    m.ks = ks;
    m.n = n;
    return m;
}

PhongMaterial gray(double kd, double ks, double n) {
    return material(Color3::Constant(kd), Color3::Constant(ks), n);
}

std::string describe(const PhongMaterial& m, double thetaDeg) {
    return fmt::format("kd=({},{},{}) ks=({},{},{}) n={} theta_o={}", m.kd[0], m.kd[1], m.kd[2],
                       m.ks[0], m.ks[1], m.ks[2], m.n, thetaDeg);
}

// Row edges in h = 1 - cos(alpha) around the mirror direction, scaled to a Phong lobe of exponent
// n: rows of equal lobe probability (the lobe's h has CDF 1 - (1 - h)^(n + 1)), rows uniform over
// the `cap` sampler's cap (its density is uniform in h), rows uniform over the sphere for the
// diffuse part, and edges where the densities have kinks or jumps (h = 1 for the clamped lobe, the
// cap's rim).
std::vector<double> lobeEdges(double n) {
    constexpr int kLobeRows = 12, kCapRows = 6, kSphereRows = 16;
    const double hCap = phongCapHeight(n);
    std::vector<double> e = {0, 1, 2, hCap};
    for (int k = 1; k <= kLobeRows; ++k) {
        const double q = k < kLobeRows ? double(k) / kLobeRows : 1 - 1e-4;
        e.push_back(-std::expm1(std::log1p(-q) / (n + 1)));
    }
    for (int k = 1; k < kCapRows; ++k) e.push_back(hCap * k / kCapRows);
    for (int k = 1; k < kSphereRows; ++k) e.push_back(2.0 * k / kSphereRows);
    std::sort(e.begin(), e.end());
    e.erase(std::unique(e.begin(), e.end(), [](double a, double b) { return b - a < 1e-12; }),
            e.end());
    return e;
}

// ---------------------------------------------------------------------------------------------
// The chi-square helper itself (chi_square.h).

// Reference values of Q(a, x) from mpmath.gammainc(a, x, inf, regularized=True) at 30 digits; the
// first five are the 5% and 1% critical values of chi-square with 1, 1, 10, 100, 1000 dof.
TEST(ChiSquareHelper, RegularizedGammaMatchesReferenceValues) {
    struct Ref {
        double a, x, q;
    };
    for (const Ref& r :
         {Ref{0.5, 3.841458820694124 / 2, 0.05}, Ref{0.5, 6.634896601021214 / 2, 0.01},
          Ref{5, 23.20925115895435 / 2, 0.0100000000000000387871577906444},
          Ref{50, 135.8067162 / 2, 0.0100000107344382208930063520654},
          Ref{500, 1106.969 / 2, 0.0099999968539074449801618420939},
          Ref{2.5, 0.3, 0.988003242794093734501934315855},
          Ref{300, 280, 0.877392717328856864001189947206},
          Ref{300, 330, 0.0448902238700129670560343961555},
          Ref{0.5, 1e-8, 0.999887162083666575129333413394},
          Ref{10.5, 8, 0.769651111748700930235182229983},
          Ref{1e4, 1e4 + 300, 0.00147049489638568127590695297028}})
        EXPECT_NEAR(regularizedGammaQ(r.a, r.x), r.q, 1e-8 * r.q) << "a=" << r.a << " x=" << r.x;
    // Closed forms: Q(1, x) = exp(-x), Q(1/2, x) = erfc(sqrt(x)), Q(3, x) = exp(-x)(1 + x + x^2/2).
    for (const double x : {1e-3, 0.1, 1.0, 4.0, 30.0, 200.0}) {
        EXPECT_NEAR(regularizedGammaQ(1, x), std::exp(-x), 1e-13 * std::exp(-x)) << x;
        EXPECT_NEAR(regularizedGammaQ(0.5, x), std::erfc(std::sqrt(x)),
                    1e-12 * std::erfc(std::sqrt(x)))
            << x;
        const double q3 = std::exp(-x) * (1 + x + x * x / 2);
        EXPECT_NEAR(regularizedGammaQ(3, x), q3, 1e-12 * q3) << x;
    }
    EXPECT_EQ(regularizedGammaQ(2, 0), 1);
    EXPECT_NEAR(chiSquarePValue(3.841458820694124, 1), 0.05, 1e-12);
    EXPECT_NEAR(sidakSignificance(0.01, 1), 0.01, 1e-15);
    EXPECT_NEAR(1 - std::pow(1 - sidakSignificance(0.01, 112), 112), 0.01, 1e-15);
}

TEST(ChiSquareHelper, PearsonStatisticWithPooling) {
    // Exact counts: statistic 0, p = 1; four cells of 100, three tiny cells pooled into one of 6.
    const ChiSquareResult exact =
        chiSquareTest({100, 100, 100, 100, 1, 2, 3}, {100, 100, 100, 100, 1, 2, 3});
    EXPECT_EQ(exact.statistic, 0);
    EXPECT_EQ(exact.dof, 4);
    EXPECT_EQ(exact.pValue, 1);
    // (110-100)^2/100 + (90-100)^2/100 + (10-6)^2/6 with 3 dof.
    const ChiSquareResult off =
        chiSquareTest({110, 90, 100, 100, 4, 3, 3}, {100, 100, 100, 100, 1, 2, 3});
    EXPECT_NEAR(off.statistic, 2 + 16.0 / 6, 1e-12);
    EXPECT_EQ(off.dof, 4);
    EXPECT_NEAR(off.pValue, chiSquarePValue(2 + 16.0 / 6, 4), 1e-15);
    // Observations where nothing is expected reject outright.
    const ChiSquareResult impossible = chiSquareTest({100, 100, 1}, {100, 101, 0});
    EXPECT_EQ(impossible.impossible, 1);
    EXPECT_EQ(impossible.pValue, 0);
}

TEST(ChiSquareHelper, Quadrature) {
    EXPECT_NEAR(integrateAdaptive([](double x) { return std::sin(x); }, 0, kPi, 1e-13, 1e-13), 2,
                1e-12);
    EXPECT_NEAR(integrateAdaptive([](double x) { return std::sqrt(x); }, 0, 1, 1e-12, 1e-12),
                2.0 / 3, 1e-10);
    auto one = [](const Vec3d&) { return 1.0; };
    auto z = [](const Vec3d& w) { return w.z(); };
    const std::vector<double> edges = {0, 0.5, 1, 2};
    for (const double theta : {0.0, 30.0, 80.0, 89.9, 135.0}) {
        const AxisCoordinates c(outgoing(theta));
        // Each hemisphere has area 2 pi and projected area pi, whatever the axis.
        EXPECT_NEAR(integrateSphere(one, c, edges, Hemisphere::Upper, 1e-12), 2 * kPi, 1e-10);
        EXPECT_NEAR(integrateSphere(one, c, edges, Hemisphere::Lower, 1e-12), 2 * kPi, 1e-10);
        EXPECT_NEAR(integrateSphere(z, c, edges, Hemisphere::Upper, 1e-12), kPi, 1e-10);
        EXPECT_NEAR(integrateSphere(z, c, edges, Hemisphere::Lower, 1e-12), -kPi, 1e-10);
        // A cell's area is (h1 - h0)(phi1 - phi0) on both sides of the horizon together.
        const double cell = c.integrate(one, 0.3, 1.4, 1.0, 2.5, Hemisphere::Upper, 1e-12) +
                            c.integrate(one, 0.3, 1.4, 1.0, 2.5, Hemisphere::Lower, 1e-12);
        EXPECT_NEAR(cell, 1.1 * 1.5, 1e-10) << theta;
        // Coordinates round-trip.
        const Vec3d w = c.direction(0.7, 4.0);
        EXPECT_NEAR(w.norm(), 1, 1e-15);
        EXPECT_NEAR(c.h(w), 0.7, 1e-14);
        EXPECT_NEAR(c.phi(w), 4.0, 1e-14);
    }
}

// ---------------------------------------------------------------------------------------------
// Chi-square goodness of fit.
//
// A global (cos theta, phi) grid would put a sharp lobe (n = 1e4 is 0.01 rad wide) into one cell,
// where any distribution of the right total passes. The grid here is in (h, phi) around the mirror
// direction instead, with rows scaled to the lobe (lobeEdges). Any fixed partition of the sphere
// gives a valid chi-square test of the same distribution: the counts are multinomial with cell
// probabilities equal to the density's integrals over the cells, and (h, phi) cells have equal
// solid angle per unit area just as (cos theta, phi) cells do. One more cell counts the samples
// that return no direction (absorbed or below the horizon), whose expected share is 1 minus the
// density's integral over the upper hemisphere, so a wrongly normalised density is caught too.

constexpr int kPhiCells = 24;
// 5e5 rather than 1e6 keeps the 112 runs within the time budget; RejectsWrongPdfs shows the power
// left (a 1% error in the sampled exponent fails too).
constexpr int kChiSquareSamples = 500'000;
constexpr double kSignificance = 0.01;

struct ChiSquareOutcome {
    ChiSquareResult chi;
    long zeroPdfSamples = 0;  // returned directions where the claimed pdf is 0
    Vec3d firstZeroPdf = Vec3d::Zero();
};

// `sample(uLobe, u)` returns an optional direction, `pdf(w)` is the density it claims.
template <typename Sample, typename Pdf>
ChiSquareOutcome directionChiSquare(const Sample& sample, const Pdf& pdf, const Vec3d& axis,
                                    const std::vector<double>& hEdges, std::uint64_t seed) {
    const AxisGrid grid(axis, hEdges, kPhiCells);
    const int cells = grid.cellCount();
    std::vector<double> observed(cells + 1, 0.0);  // the last cell: no direction returned
    ChiSquareOutcome out;
    const CounterRng rng(seed, 0);
    for (int i = 0; i < kChiSquareSamples; ++i) {
        const std::optional<Vec3d> w =
            sample(rng.uniform(i, 0), Vec2d(rng.uniform(i, 1), rng.uniform(i, 2)));
        if (!w) {
            ++observed[cells];
        } else if (!(pdf(*w) > 0)) {
            if (out.zeroPdfSamples++ == 0) out.firstZeroPdf = *w;
        } else {
            ++observed[grid.cellOf(*w)];
        }
    }
    if (out.zeroPdfSamples > 0) {
        out.chi.pValue = 0;
        return out;
    }
    std::vector<double> expected = grid.cellProbabilities(pdf, 1e-11);
    double returned = 0;
    for (double& e : expected) {
        returned += e;
        e *= kChiSquareSamples;
    }
    expected.push_back(std::max(0.0, (1 - returned) * kChiSquareSamples));
    out.chi = chiSquareTest(observed, expected);
    return out;
}

struct ChiSquareRun {
    std::string sampler;
    PhongMaterial m;
    double thetaDeg;
    bool singlePrecision = false;  // sample with PhongSampler<float>

    std::string label() const {
        return fmt::format("{}{} {}", sampler, singlePrecision ? " (float)" : "",
                           describe(m, thetaDeg));
    }
};

const std::vector<ChiSquareRun>& chiSquareRuns() {
    static const std::vector<ChiSquareRun> runs = [] {
        std::vector<ChiSquareRun> r;
        for (const std::string& name : phongSamplerNames())
            for (const double n : {1.0, 10.0, 100.0, 1000.0, 10000.0})
                for (const double theta : {0.0, 45.0, 80.0, 89.9})
                    r.push_back({name, gray(0.3, 0.6, n), theta});
        const Color3 kd(0.5, 0.2, 0.2), ks(0.3, 0.7, 0.1);
        for (const std::string name : {"lafortune", "mixture", "cap"}) {
            r.push_back({name, material(kd, ks, 10), 45});
            r.push_back({name, material(kd, ks, 1000), 80});
            r.push_back({name, gray(0.3, 0.6, 100), 45, true});
            r.push_back({name, gray(0.3, 0.6, 10000), 89.9, true});
        }
        return r;
    }();
    return runs;
}

ChiSquareOutcome runChiSquare(const ChiSquareRun& run, std::uint64_t seed) {
    const auto sampler = makePhongSampler<double>(run.sampler);
    const Vec3d wo = outgoing(run.thetaDeg);
    auto pdf = [&](const Vec3d& wi) { return sampler->pdf(run.m, wo, wi); };
    const std::vector<double> edges = lobeEdges(run.m.n);
    if (!run.singlePrecision) {
        auto sample = [&](double uLobe, const Vec2d& u) -> std::optional<Vec3d> {
            const auto s = sampler->sample(run.m, wo, uLobe, u);
            return s ? std::optional<Vec3d>(s->wi) : std::nullopt;
        };
        return directionChiSquare(sample, pdf, reflectLocal(wo), edges, seed);
    }
    const auto samplerF = makePhongSampler<float>(run.sampler);
    PhongParams<float> mF;
    mF.kd = run.m.kd.cast<float>();
    mF.ks = run.m.ks.cast<float>();
    mF.n = float(run.m.n);
    const Vec3f woF = wo.cast<float>();
    auto sample = [&](double uLobe, const Vec2d& u) -> std::optional<Vec3d> {
        const auto s = samplerF->sample(mF, woF, float(uLobe), u.cast<float>());
        return s ? std::optional<Vec3d>(s->wi.cast<double>().normalized()) : std::nullopt;
    };
    return directionChiSquare(sample, pdf, reflectLocal(wo), edges, seed);
}

// Runs every configuration of one sampler in parallel, then checks each at the Sidak-corrected
// significance over all runs of this file.
void expectSamplerMatchesPdf(const std::string& name) {
    const std::vector<ChiSquareRun>& runs = chiSquareRuns();
    const double alpha = sidakSignificance(kSignificance, int(runs.size()));
    std::vector<std::size_t> mine;
    for (std::size_t i = 0; i < runs.size(); ++i)
        if (runs[i].sampler == name) mine.push_back(i);
    ASSERT_FALSE(mine.empty());
    std::vector<ChiSquareOutcome> outcomes(mine.size());
    tbb::parallel_for(std::size_t(0), mine.size(), [&](std::size_t k) {
        outcomes[k] = runChiSquare(runs[mine[k]], 1000 + mine[k]);
    });
    for (std::size_t k = 0; k < mine.size(); ++k) {
        const ChiSquareOutcome& o = outcomes[k];
        const std::string label = runs[mine[k]].label();
        EXPECT_EQ(o.zeroPdfSamples, 0)
            << label << ": sampled where pdf = 0, e.g. (" << o.firstZeroPdf.transpose() << ")";
        EXPECT_GE(o.chi.pValue, alpha)
            << label << ": chi2 = " << o.chi.statistic << ", dof = " << o.chi.dof;
        EXPECT_GT(o.chi.dof, 20) << label << ": too few cells for a meaningful test";
    }
}

TEST(PhongSamplerChiSquare, Lafortune) { expectSamplerMatchesPdf("lafortune"); }
TEST(PhongSamplerChiSquare, Mixture) { expectSamplerMatchesPdf("mixture"); }
TEST(PhongSamplerChiSquare, Cap) { expectSamplerMatchesPdf("cap"); }
TEST(PhongSamplerChiSquare, Cosine) { expectSamplerMatchesPdf("cosine"); }
TEST(PhongSamplerChiSquare, Uniform) { expectSamplerMatchesPdf("uniform"); }

// The test has power: a density that is wrong in a plausible way is rejected.
struct WrongPdfCase {
    std::string what;
    std::string sampler;
    PhongMaterial m;
    double thetaDeg;
    std::function<double(const PhongSampler<double>&, const Vec3d&, const Vec3d&)> pdf;
};

TEST(PhongSamplerChiSquare, RejectsWrongPdfs) {
    const std::vector<WrongPdfCase> cases = {
        {"lobe normalised with n + 2 instead of n + 1", "lafortune", gray(0.3, 0.6, 10), 45,
         [](const PhongSampler<double>&, const Vec3d& wo, const Vec3d& wi) {
             const double n = 10;
             if (!(wi.z() > 0)) return 0.0;
             return 0.3 * cosineHemispherePdf(wi) +
                    0.6 * phongLobePdf(oneMinusCosAlpha(wi, wo), n) * (n + 2) / (n + 1);
         }},
        {"pdf for n = 1100 while sampling n = 1000", "mixture", gray(0.3, 0.6, 1000), 45,
         [](const PhongSampler<double>& s, const Vec3d& wo, const Vec3d& wi) {
             return s.pdf(gray(0.3, 0.6, 1100), wo, wi);
         }},
        {"pdf for n = 10500 while sampling n = 10000", "lafortune", gray(0.3, 0.6, 10000), 80,
         [](const PhongSampler<double>& s, const Vec3d& wo, const Vec3d& wi) {
             return s.pdf(gray(0.3, 0.6, 10500), wo, wi);
         }},
        {"Phong lobe pdf for cap samples", "cap", gray(0.3, 0.6, 100), 45,
         [](const PhongSampler<double>&, const Vec3d& wo, const Vec3d& wi) {
             if (!(wi.z() > 0)) return 0.0;
             return 0.3 * cosineHemispherePdf(wi) +
                    0.6 * phongLobePdf(oneMinusCosAlpha(wi, wo), 100.0);
         }},
        {"uniform pdf for cosine samples", "cosine", gray(0.3, 0.6, 10), 0,
         [](const PhongSampler<double>&, const Vec3d&, const Vec3d& wi) {
             return uniformHemispherePdf(wi);
         }},
    };
    const double alpha = sidakSignificance(kSignificance, int(chiSquareRuns().size()));
    std::vector<ChiSquareOutcome> outcomes(cases.size());
    tbb::parallel_for(std::size_t(0), cases.size(), [&](std::size_t k) {
        const WrongPdfCase& c = cases[k];
        const auto sampler = makePhongSampler<double>(c.sampler);
        const Vec3d wo = outgoing(c.thetaDeg);
        auto sample = [&](double uLobe, const Vec2d& u) -> std::optional<Vec3d> {
            const auto s = sampler->sample(c.m, wo, uLobe, u);
            return s ? std::optional<Vec3d>(s->wi) : std::nullopt;
        };
        auto pdf = [&](const Vec3d& wi) { return c.pdf(*sampler, wo, wi); };
        outcomes[k] = directionChiSquare(sample, pdf, reflectLocal(wo), lobeEdges(c.m.n), 7 + k);
    });
    for (std::size_t k = 0; k < cases.size(); ++k) {
        EXPECT_EQ(outcomes[k].zeroPdfSamples, 0) << cases[k].what;
        EXPECT_LT(outcomes[k].chi.pValue, alpha)
            << cases[k].what << ": not rejected, chi2 = " << outcomes[k].chi.statistic
            << ", dof = " << outcomes[k].chi.dof;
    }
}

// A density that is zero where the sampler puts directions fails at once, whatever the counts.
TEST(PhongSamplerChiSquare, FailsWhereThePdfIsZero) {
    const PhongMaterial m = gray(0.3, 0.6, 100);
    const auto sampler = makePhongSampler<double>("cap");
    const Vec3d wo = outgoing(30);
    auto sample = [&](double uLobe, const Vec2d& u) -> std::optional<Vec3d> {
        const auto s = sampler->sample(m, wo, uLobe, u);
        return s ? std::optional<Vec3d>(s->wi) : std::nullopt;
    };
    // The cap of an exponent twice as large: half as wide, zero on the outer part of the real cap.
    auto pdf = [&](const Vec3d& wi) {
        if (!(wi.z() > 0)) return 0.0;
        return 0.6 * uniformCapPdf(oneMinusCosAlpha(wi, wo), phongCapHeight(201.0));
    };
    const ChiSquareOutcome o = directionChiSquare(sample, pdf, reflectLocal(wo), lobeEdges(100), 3);
    EXPECT_GT(o.zeroPdfSamples, 0);
    EXPECT_EQ(o.chi.pValue, 0);
}

// ---------------------------------------------------------------------------------------------
// Normalisation: the densities integrate to the sampling mass.

std::vector<PhongMaterial> normalisationMaterials(double n) {
    return {gray(0.3, 0.6, n), gray(0, 0, n), gray(0, 1, n), gray(1, 0, n),
            material(Color3(0.5, 0.2, 0.2), Color3(0.3, 0.7, 0.1), n)};
}

TEST(PhongSamplerPdf, IntegratesToItsMass) {
    struct Case {
        std::string sampler;
        double n, thetaDeg;
    };
    std::vector<Case> cases;
    for (const std::string& name : phongSamplerNames())
        for (const double n : {0.0, 1.0, 10.0, 100.0, 1000.0, 10000.0})
            for (const double theta : {0.0, 45.0, 80.0, 89.9}) cases.push_back({name, n, theta});
    std::vector<std::string> failures(cases.size());
    tbb::parallel_for(std::size_t(0), cases.size(), [&](std::size_t k) {
        const Case& c = cases[k];
        const auto sampler = makePhongSampler<double>(c.sampler);
        const Vec3d wo = outgoing(c.thetaDeg);
        const AxisCoordinates coords(reflectLocal(wo));
        const std::vector<double> edges = lobeEdges(c.n);
        for (const PhongMaterial& m : normalisationMaterials(c.n)) {
            auto unclipped = [&](const Vec3d& wi) { return sampler->unclippedPdf(m, wo, wi); };
            auto pdf = [&](const Vec3d& wi) { return sampler->pdf(m, wo, wi); };
            const double mass = sampler->mass(m);
            const bool absorbing = c.sampler == "lafortune" || c.sampler == "cap";
            const double contract = absorbing ? m.kd.mean() + m.ks.mean() : 1.0;
            if (std::abs(mass - contract) > 1e-15)
                failures[k] += fmt::format("{} {}: mass {}, should be {}\n", c.sampler,
                                           describe(m, c.thetaDeg), mass, contract);
            const double sphere =
                integrateSphere(unclipped, coords, edges, Hemisphere::Upper, 1e-10) +
                integrateSphere(unclipped, coords, edges, Hemisphere::Lower, 1e-10);
            const double upper = integrateSphere(pdf, coords, edges, Hemisphere::Upper, 1e-10);
            const double lower = integrateSphere(pdf, coords, edges, Hemisphere::Lower, 1e-10);
            const bool upperOk =
                c.thetaDeg == 0 ? std::abs(upper - mass) < 1e-7 : upper <= mass + 1e-9;
            if (std::abs(sphere - mass) > 1e-7 || !upperOk || lower != 0)
                failures[k] += fmt::format(
                    "{} {}: mass {}, unclipped over sphere {}, pdf over upper {}, lower {}\n",
                    c.sampler, describe(m, c.thetaDeg), mass, sphere, upper, lower);
        }
    });
    for (const std::string& f : failures) EXPECT_TRUE(f.empty()) << f;
}

// ---------------------------------------------------------------------------------------------
// sample() agrees with pdf() and eval.

template <typename T>
void expectSamplesConsistent(double relTol) {
    for (const std::string& name : phongSamplerNames()) {
        const auto sampler = makePhongSampler<T>(name);
        for (const double n : {0.0, 1.0, 30.0, 1e3, 1e5})
            for (const double theta : {0.0, 30.0, 75.0, 89.999}) {
                PhongParams<T> m;
                m.kd = Color<T>(0.3, 0.1, 0.2);
                m.ks = Color<T>(0.6, 0.5, 0.7);
                m.n = T(n);
                const Vec3<T> wo = outgoing(theta).cast<T>();
                const CounterRng rng(17, std::uint64_t(n * 10 + theta));
                int returned = 0;
                for (int i = 0; i < 2000; ++i) {
                    const auto s =
                        sampler->sample(m, wo, T(rng.uniform(i, 0)),
                                        Vec2<T>(T(rng.uniform(i, 1)), T(rng.uniform(i, 2))));
                    if (!s) continue;
                    ++returned;
                    const std::string where =
                        fmt::format("{} n={} theta_o={} sample {}", name, n, theta, i);
                    ASSERT_GT(s->wi.z(), T(0)) << where;
                    EXPECT_NEAR(double(s->wi.norm()), 1.0, relTol) << where;
                    ASSERT_GT(s->pdf, T(0)) << where;
                    EXPECT_EQ(s->pdf, sampler->pdf(m, wo, s->wi)) << where;
                    const Color<T> expected = phongEval(m, s->wi, wo) * s->wi.z() / s->pdf;
                    for (int c = 0; c < 3; ++c)
                        EXPECT_NEAR(double(s->weight[c]), double(expected[c]),
                                    relTol * std::max(1.0, double(std::abs(expected[c]))))
                            << where;
                }
                EXPECT_GT(returned, 0) << name << " n=" << n << " theta_o=" << theta;
            }
    }
}

TEST(PhongSamplerSample, PdfAndWeightAgreeWithPdfAndEvalDouble) {
    expectSamplesConsistent<double>(1e-12);
}
TEST(PhongSamplerSample, PdfAndWeightAgreeWithPdfAndEvalFloat) {
    expectSamplesConsistent<float>(1e-5);
}

TEST(PhongSamplerSample, LobeTagsFollowTheLobeChoice) {
    const PhongMaterial m = gray(0.3, 0.6, 20);
    const Vec3d wo = outgoing(10);
    const auto lafortune = makePhongSampler<double>("lafortune");
    EXPECT_EQ(lafortune->sample(m, wo, 0.1, Vec2d(0.5, 0.5))->lobe, Lobe::Diffuse);
    EXPECT_EQ(lafortune->sample(m, wo, 0.5, Vec2d(0.5, 0.5))->lobe, Lobe::Specular);
    EXPECT_FALSE(lafortune->sample(m, wo, 0.95, Vec2d(0.5, 0.5)));  // absorbed
    const auto mixture = makePhongSampler<double>("mixture");
    EXPECT_EQ(mixture->sample(m, wo, 0.3, Vec2d(0.5, 0.5))->lobe, Lobe::Diffuse);
    EXPECT_EQ(mixture->sample(m, wo, 0.95, Vec2d(0.5, 0.5))->lobe, Lobe::Specular);
}

// The mean of the weights (0 where nothing is returned) is the directional albedo, computed
// independently by quadrature: an end-to-end check of sample, pdf and eval together.
TEST(PhongSamplerSample, MeanWeightIsTheAlbedo) {
    const PhongMaterial m = gray(0.3, 0.6, 0);
    for (const std::string& name : phongSamplerNames())
        for (const double n : {1.0, 100.0, 10000.0})
            for (const double theta : {0.0, 60.0, 85.0}) {
                // Hemisphere samplers hit a sharp lobe too rarely for a useful mean.
                if ((name == "cosine" || name == "uniform") && n > 10) continue;
                PhongMaterial mn = m;
                mn.n = n;
                const auto sampler = makePhongSampler<double>(name);
                const Vec3d wo = outgoing(theta);
                auto fCos = [&](const Vec3d& wi) { return phongEval(mn, wi, wo)[0] * wi.z(); };
                const double albedo = integrateSphere(fCos, AxisCoordinates(reflectLocal(wo)),
                                                      lobeEdges(n), Hemisphere::Upper, 1e-10);
                constexpr int kSamples = 200'000;
                const CounterRng rng(5, std::uint64_t(n + theta));
                double sum = 0, sumSq = 0;
                for (int i = 0; i < kSamples; ++i) {
                    const auto s = sampler->sample(mn, wo, rng.uniform(i, 0),
                                                   Vec2d(rng.uniform(i, 1), rng.uniform(i, 2)));
                    const double w = s ? s->weight[0] : 0;
                    sum += w;
                    sumSq += w * w;
                }
                const double mean = sum / kSamples;
                const double sigma =
                    std::sqrt(std::max(0.0, sumSq / kSamples - mean * mean) / kSamples);
                EXPECT_NEAR(mean, albedo, 5 * sigma + 1e-6)
                    << name << " n=" << n << " theta_o=" << theta;
            }
}

// ---------------------------------------------------------------------------------------------
// Stiff and extreme cases: never NaN or Inf.

template <typename T>
void expectFiniteEverywhere() {
    // 1 itself too: float(CounterRng::uniform()) rounds to it once in ~3e7 draws.
    std::vector<T> us = {T(0), std::nextafter(T(1), T(0)), T(1), T(0.5), T(1e-7)};
    const CounterRng rng(23, 0);
    for (int i = 0; i < 40; ++i) us.push_back(T(rng.uniform(i, 0)));
    const std::vector<Vec3<T>> wis = {Vec3<T>(0, 0, 1), Vec3<T>(0.6, 0, -0.8), Vec3<T>(1, 0, 0),
                                      Vec3<T>(0, 0, -1), Vec3<T>(-0.6, 0, 0.8)};
    for (const std::string& name : phongSamplerNames()) {
        const auto sampler = makePhongSampler<T>(name);
        for (const double n : {0.0, 1e-6, 1e4, 1e6})
            for (const auto& [kd, ks] : {std::pair{0.3, 0.6},
                                         {0.0, 0.6},
                                         {0.3, 0.0},
                                         {0.0, 0.0},
                                         {0.4, 0.6},
                                         {1.0, 0.0},
                                         {0.0, 1.0}})
                for (const double theta : {0.0, 45.0, 89.999, 90.0, 120.0}) {
                    PhongParams<T> m;
                    m.kd = Color<T>::Constant(T(kd));
                    m.ks = Color<T>::Constant(T(ks));
                    m.n = T(n);
                    const Vec3<T> wo = outgoing(theta).cast<T>();
                    const std::string where =
                        fmt::format("{} n={} kd={} ks={} theta_o={}", name, n, kd, ks, theta);
                    for (const Vec3<T>& wi : wis) {
                        const T p = sampler->pdf(m, wo, wi);
                        ASSERT_TRUE(std::isfinite(p) && p >= 0) << where;
                        if (!(wi.z() > 0) || !(wo.z() > 0)) {
                            EXPECT_EQ(p, T(0)) << where;
                        }
                        ASSERT_TRUE(std::isfinite(sampler->unclippedPdf(m, wo, wi))) << where;
                    }
                    ASSERT_TRUE(std::isfinite(sampler->mass(m))) << where;
                    for (const T uLobe : us)
                        for (std::size_t j = 0; j < us.size(); ++j) {
                            const Vec2<T> u(us[j], us[(j * 7 + 3) % us.size()]);
                            const auto s = sampler->sample(m, wo, uLobe, u);
                            if (!(wo.z() > 0)) {
                                ASSERT_FALSE(s) << where;
                                continue;
                            }
                            if (!s) continue;
                            ASSERT_TRUE(s->wi.allFinite() && s->wi.z() > 0) << where;
                            ASSERT_TRUE(std::isfinite(s->pdf) && s->pdf > 0) << where;
                            ASSERT_TRUE(s->weight.allFinite() && (s->weight >= 0).all())
                                << where << " weight " << s->weight.transpose();
                        }
                }
    }
}

TEST(PhongSamplerExtreme, FiniteDouble) { expectFiniteEverywhere<double>(); }
TEST(PhongSamplerExtreme, FiniteFloat) { expectFiniteEverywhere<float>(); }

TEST(PhongSamplerNames, UnknownNameListsTheAllowedOnes) {
    try {
        makePhongSampler<double>("ggx");
        FAIL() << "no error for an unknown sampler";
    } catch (const Error& e) {
        const std::string message = e.what();
        EXPECT_NE(message.find("ggx"), std::string::npos) << message;
        for (const std::string& name : phongSamplerNames())
            EXPECT_NE(message.find(name), std::string::npos) << message;
    }
    for (const std::string& name : phongSamplerNames())
        EXPECT_EQ(makePhongSampler<float>(name)->name(), name);
}

}  // namespace
}  // namespace phongfit
