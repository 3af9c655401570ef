// Minimising a function of one variable: golden-section search where it has one minimum; where it
// may have several, the best point of a grid, then golden-section search between its neighbours.
#pragma once

#include <algorithm>
#include <limits>

namespace phongfit {

// The x in [a, b] where f is least, to within `tolerance`, by golden-section search: f falls,
// then rises, over [a, b].
template <typename F>
double goldenSectionMinimum(F&& f, double a, double b, double tolerance) {
    constexpr double kGolden = 0.6180339887498949;
    double c = b - kGolden * (b - a), d = a + kGolden * (b - a);
    double fc = f(c), fd = f(d);
    while (b - a > tolerance) {
        if (fc < fd) {
            b = d, d = c, fd = fc;
            c = b - kGolden * (b - a), fc = f(c);
        } else {
            a = c, c = d, fc = fd;
            d = a + kGolden * (b - a), fd = f(d);
        }
    }
    return 0.5 * (a + b);
}

// The x in [lo, hi] where f is least, to within `tolerance`: f on lo, lo + step, ..., hi, then
// golden-section search in [best - step, best + step]. Finds the global minimum when the grid is
// fine enough that no other basin is deeper between grid points.
template <typename F>
double gridThenGoldenMinimum(F&& f, double lo, double hi, double step, double tolerance) {
    double best = lo, bestValue = std::numeric_limits<double>::infinity();
    for (double x = lo; x <= hi + 1e-9 * step; x += step) {
        const double value = f(x);
        if (value < bestValue) bestValue = value, best = x;
    }
    return goldenSectionMinimum(f, std::max(best - step, lo), std::min(best + step, hi), tolerance);
}

}  // namespace phongfit
