// Chi-square goodness of fit for direction samplers, as pbrt-v4 bsdfs_test.cpp, Nori chi2test.cpp
// and Mitsuba 3 chi2.py: directions are histogrammed over cells of a grid, expected counts come
// from integrating the claimed density over each cell, and Pearson's statistic gives a p-value
// through the regularized incomplete gamma function. Also the sphere quadrature this needs, reused
// by the BRDF tests (albedo, normalisation).
//
// Cells are in coordinates (h, phi) around an axis, h = 1 - cos(angle to the axis) in [0, 2]: solid
// angle is dh dphi, so every cell has equal solid angle per unit area (no sin theta factor), and a
// grid around the mirror direction can be scaled to a lobe of any width.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <numeric>
#include <stdexcept>
#include <utility>
#include <vector>

#include "math.h"

namespace phongfit {

// Regularized upper incomplete gamma Q(a, x) = Gamma(a, x) / Gamma(a), for a > 0, x >= 0: the
// series for P below x < a + 1 and Lentz's continued fraction for Q above (Numerical Recipes 6.2).
inline double regularizedGammaQ(double a, double x) {
    if (!(a > 0) || !(x >= 0)) throw std::domain_error("regularizedGammaQ needs a > 0, x >= 0");
    if (x == 0) return 1;
    const double logPrefactor = a * std::log(x) - x - std::lgamma(a);
    constexpr double kEps = 1e-16;
    constexpr int kMaxIterations = 100000;
    if (x < a + 1) {
        double term = 1 / a, sum = term;
        for (int k = 1; k < kMaxIterations && std::abs(term) > std::abs(sum) * kEps; ++k) {
            term *= x / (a + k);
            sum += term;
        }
        return std::max(0.0, 1 - sum * std::exp(logPrefactor));
    }
    constexpr double kTiny = 1e-300;
    double b = x + 1 - a, c = 1 / kTiny, d = 1 / b, frac = d;
    for (int k = 1; k < kMaxIterations; ++k) {
        const double an = -k * (k - a);
        b += 2;
        d = an * d + b;
        if (std::abs(d) < kTiny) d = kTiny;
        c = b + an / c;
        if (std::abs(c) < kTiny) c = kTiny;
        d = 1 / d;
        const double delta = d * c;
        frac *= delta;
        if (std::abs(delta - 1) < kEps) break;
    }
    return std::exp(logPrefactor) * frac;
}

// Probability that a chi-square variable with `dof` degrees of freedom exceeds `statistic`.
inline double chiSquarePValue(double statistic, int dof) {
    return regularizedGammaQ(dof / 2.0, std::max(0.0, statistic) / 2);
}

// Per-run significance so that `runs` independent tests reject a correct sampler with probability
// `alpha` overall.
inline double sidakSignificance(double alpha, int runs) {
    return -std::expm1(std::log1p(-alpha) / runs);
}

struct ChiSquareResult {
    double statistic = 0;
    int dof = 0;
    double pValue = 1;
    double impossible = 0;  // observations in cells whose expected count is 0
};

// Pearson's test. Cells expected to hold fewer than `minExpected` are pooled, smallest first, until
// the pool reaches `minExpected` (as Nori), so the chi-square approximation holds. Observations in
// a cell with expected count 0 make the p-value 0.
inline ChiSquareResult chiSquareTest(const std::vector<double>& observed,
                                     const std::vector<double>& expected, double minExpected = 5) {
    if (observed.size() != expected.size())
        throw std::invalid_argument("chiSquareTest: observed and expected differ in size");
    std::vector<std::size_t> order(observed.size());
    std::iota(order.begin(), order.end(), 0);
    std::sort(order.begin(), order.end(),
              [&](std::size_t i, std::size_t j) { return expected[i] < expected[j]; });
    ChiSquareResult r;
    double pooledObserved = 0, pooledExpected = 0;
    int cells = 0;
    for (const std::size_t i : order) {
        if (expected[i] <= 0) {
            r.impossible += observed[i];
        } else if (expected[i] < minExpected ||
                   (pooledExpected > 0 && pooledExpected < minExpected)) {
            pooledObserved += observed[i];
            pooledExpected += expected[i];
        } else {
            const double d = observed[i] - expected[i];
            r.statistic += d * d / expected[i];
            ++cells;
        }
    }
    if (pooledExpected > 0) {
        const double d = pooledObserved - pooledExpected;
        r.statistic += d * d / pooledExpected;
        ++cells;
    }
    r.dof = cells - 1;
    r.pValue = r.impossible > 0 ? 0 : r.dof > 0 ? chiSquarePValue(r.statistic, r.dof) : 1;
    return r;
}

// Adaptive Gauss-Kronrod (G7-K15) on [a, b]: bisects until |K15 - G7| is within tolerance, the
// absolute tolerance shared between the halves.
template <typename F>
double integrateAdaptive(const F& f, double a, double b, double absTol, double relTol,
                         int depth = 0) {
    static constexpr std::array<double, 8> kNodes = {
        0.991455371120812639206854697526329, 0.949107912342758524526189684047851,
        0.864864423359769072789712788640926, 0.741531185599394439863864773280788,
        0.586087235467691130294144845693013, 0.405845151377397166906606412076961,
        0.207784955007898467600689403773245, 0.0};
    static constexpr std::array<double, 8> kKronrod = {
        0.022935322010529224963732008058970, 0.063092092629978553290700663189204,
        0.104790010322250183839876322541518, 0.140653259715525918745189590510238,
        0.169004726639267902826583426598550, 0.190350578064785409913256402421014,
        0.204432940075298892414161999234649, 0.209482141084727828012999174891714};
    // Gauss weights of the odd-indexed nodes above.
    static constexpr std::array<double, 4> kGauss = {
        0.129484966168869693270611432679082, 0.279705391489276667901467771423780,
        0.381830050505118944950369775488975, 0.417959183673469387755102040816327};
    constexpr int kMaxDepth = 40;
    const double center = (a + b) / 2, half = (b - a) / 2;
    const double fc = f(center);
    double kronrod = kKronrod[7] * fc, gauss = kGauss[3] * fc;
    for (int i = 0; i < 7; ++i) {
        const double sum = f(center - half * kNodes[i]) + f(center + half * kNodes[i]);
        kronrod += kKronrod[i] * sum;
        if (i % 2 == 1) gauss += kGauss[i / 2] * sum;
    }
    kronrod *= half;
    gauss *= half;
    // A non-finite integrand is returned as is (bisecting it would never converge).
    if (!std::isfinite(kronrod) ||
        std::abs(kronrod - gauss) <= std::max(absTol, relTol * std::abs(kronrod)) ||
        depth >= kMaxDepth)
        return kronrod;
    return integrateAdaptive(f, a, center, absTol / 2, relTol, depth + 1) +
           integrateAdaptive(f, center, b, absTol / 2, relTol, depth + 1);
}

enum class Hemisphere { Upper, Lower };  // z > 0 or z <= 0 in the local shading frame

// Coordinates (h, phi) around a unit axis, and integration over their cells split at the horizon
// z = 0, where densities are discontinuous. The horizon is a great circle; in these coordinates it
// is z = sin(alpha) rho cos(phi - phiUp) + cos(alpha) nz, with (rho, phiUp, nz) the normal in the
// axis frame, so each row of the integration knows analytically which azimuths lie above it.
class AxisCoordinates {
public:
    explicit AxisCoordinates(const Vec3d& axis) : frame_(axis) {
        const Vec3d up = frame_.toLocal(Vec3d(0, 0, 1));
        nz_ = up.z();
        rho_ = std::hypot(up.x(), up.y());
        phiUp_ = std::atan2(up.y(), up.x());
    }

    Vec3d direction(double h, double phi) const {
        const double sinAlpha = std::sqrt(std::max(0.0, h * (2 - h)));
        return frame_.toWorld(Vec3d(sinAlpha * std::cos(phi), sinAlpha * std::sin(phi), 1 - h));
    }
    // Precise for directions close to the axis, where 1 - dot(axis, w) cancels.
    double h(const Vec3d& w) const { return (frame_.n - w).squaredNorm() / 2; }
    double phi(const Vec3d& w) const {
        const Vec3d local = frame_.toLocal(w);
        const double p = std::atan2(local.y(), local.x());
        return p < 0 ? std::min(p + 2 * kPi, std::nextafter(2 * kPi, 0.0)) : p;
    }

    // Integral of g(w) dw over the cell h in [h0, h1], phi in [phi0, phi1] within [0, 2pi], on one
    // side of the horizon; g must be smooth there. Breaks the h range where the horizon touches a
    // row tangentially or crosses the cell's phi edges, so every piece is smooth.
    template <typename G>
    double integrate(const G& g, double h0, double h1, double phi0, double phi1, Hemisphere side,
                     double absTol, double relTol = 1e-10) const {
        std::vector<double> cuts = {h0, h1, 1 - rho_, 1 + rho_, crossing(phi0), crossing(phi1)};
        std::sort(cuts.begin(), cuts.end());
        double total = 0;
        double lo = h0;
        for (const double cut : cuts) {
            if (cut <= lo || cut > h1) continue;
            const double innerTol = absTol / (cut - lo) / 4;
            auto row = [&](double h) {
                double sum = 0;
                for (const auto& [a, b] : azimuths(h, phi0, phi1, side))
                    sum += integrateAdaptive([&](double phi) { return g(direction(h, phi)); }, a, b,
                                             innerTol, relTol);
                return sum;
            };
            total += integrateAdaptive(row, lo, cut, absTol / 2, relTol);
            lo = cut;
        }
        return total;
    }

private:
    using Interval = std::pair<double, double>;

    // h where the horizon crosses the azimuth line phi (harmless extra cut when there is none).
    double crossing(double phi) const {
        double alpha = std::atan2(nz_, -rho_ * std::cos(phi - phiUp_));
        if (alpha < 0) alpha += kPi;
        return 1 - std::cos(alpha);
    }

    // The parts of [phi0, phi1] on the requested side of the horizon in the row h.
    std::vector<Interval> azimuths(double h, double phi0, double phi1, Hemisphere side) const {
        const double cosAlpha = 1 - h, sinAlpha = std::sqrt(std::max(0.0, h * (2 - h)));
        const double amplitude = sinAlpha * rho_, offset = cosAlpha * nz_;
        std::vector<Interval> upper;
        if (amplitude <= std::abs(offset)) {
            if (offset > 0) upper.push_back({phi0, phi1});
        } else {
            const double delta = std::acos(-offset / amplitude);
            for (int k = -1; k <= 1; ++k) {
                const double a = std::max(phi0, phiUp_ - delta + 2 * kPi * k);
                const double b = std::min(phi1, phiUp_ + delta + 2 * kPi * k);
                if (a < b) upper.push_back({a, b});
            }
        }
        if (side == Hemisphere::Upper) return upper;
        std::vector<Interval> lower;
        double start = phi0;
        for (const auto& [a, b] : upper) {  // disjoint and ascending
            if (a > start) lower.push_back({start, a});
            start = b;
        }
        if (start < phi1) lower.push_back({start, phi1});
        return lower;
    }

    Frame<double> frame_;
    double nz_, rho_, phiUp_;
};

// Integral of g over one side of the horizon on the whole sphere, row by row between `hEdges`
// (ascending, 0 first and 2 last; put an edge wherever g has a kink or jump in h).
template <typename G>
double integrateSphere(const G& g, const AxisCoordinates& coords, const std::vector<double>& hEdges,
                       Hemisphere side, double absTol) {
    double total = 0;
    const double rowTol = absTol / double(hEdges.size());
    for (std::size_t i = 0; i + 1 < hEdges.size(); ++i)
        total += coords.integrate(g, hEdges[i], hEdges[i + 1], 0, 2 * kPi, side, rowTol);
    return total;
}

// Histogram of directions over an (h, phi) grid around an axis.
class AxisGrid {
public:
    AxisGrid(const Vec3d& axis, std::vector<double> hEdges, int phiCells)
        : coords_(axis), hEdges_(std::move(hEdges)), phiCells_(phiCells) {}

    const AxisCoordinates& coordinates() const { return coords_; }
    int cellCount() const { return rows() * phiCells_; }

    int cellOf(const Vec3d& w) const {
        const int row =
            int(std::upper_bound(hEdges_.begin(), hEdges_.end(), coords_.h(w)) - hEdges_.begin()) -
            1;
        const int col = int(coords_.phi(w) / (2 * kPi) * phiCells_);
        return std::clamp(row, 0, rows() - 1) * phiCells_ + std::clamp(col, 0, phiCells_ - 1);
    }

    // Probability of each cell under `density` (zero below the horizon, smooth above it except at
    // the h edges), each to within absTol.
    template <typename G>
    std::vector<double> cellProbabilities(const G& density, double absTol) const {
        std::vector<double> p(cellCount());
        const double width = 2 * kPi / phiCells_;
        for (int row = 0; row < rows(); ++row)
            for (int col = 0; col < phiCells_; ++col)
                p[row * phiCells_ + col] = coords_.integrate(
                    density, hEdges_[row], hEdges_[row + 1], col * width,
                    col + 1 == phiCells_ ? 2 * kPi : (col + 1) * width, Hemisphere::Upper, absTol);
        return p;
    }

private:
    int rows() const { return int(hEdges_.size()) - 1; }

    AxisCoordinates coords_;
    std::vector<double> hEdges_;
    int phiCells_;
};

}  // namespace phongfit
