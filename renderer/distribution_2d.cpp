#include "distribution_2d.h"

#include <algorithm>
#include <cmath>

namespace phongfit {
namespace {

// Cumulative sums of f with a leading 0, normalized to end at 1 (uniform steps if f sums to 0).
double fillCdf(const double* f, int n, double* cdf) {
    cdf[0] = 0;
    for (int i = 0; i < n; ++i) cdf[i + 1] = cdf[i] + f[i];
    const double total = cdf[n];
    for (int i = 1; i <= n; ++i) cdf[i] = total > 0 ? cdf[i] / total : double(i) / n;
    cdf[n] = 1;
    return total;
}

}  // namespace

Distribution2D::Distribution2D(const std::vector<double>& weights, int width, int height)
    : width_(width), height_(height) {
    rowCdfs_.resize(std::size_t(width + 1) * height);
    std::vector<double> rowSums(height);
    for (int y = 0; y < height; ++y)
        rowSums[y] = fillCdf(&weights[std::size_t(y) * width], width,
                             &rowCdfs_[std::size_t(y) * (width + 1)]);
    marginalCdf_.resize(height + 1);
    fillCdf(rowSums.data(), height, marginalCdf_.data());
}

std::pair<int, double> Distribution2D::invert(const double* cdf, int n, double u) {
    // The segment holding u; upper_bound skips segments of zero width.
    const int i = std::clamp(int(std::upper_bound(cdf, cdf + n + 1, u) - cdf) - 1, 0, n - 1);
    const double width = cdf[i + 1] - cdf[i];
    const double t = width > 0 ? (u - cdf[i]) / width : 0.5;
    return {i, std::clamp(t, 0.0, std::nextafter(1.0, 0.0))};
}

Distribution2D::Sample Distribution2D::sample(const Vec2d& u) const {
    const auto [y, ty] = invert(marginalCdf_.data(), height_, u.y());
    const auto [x, tx] = invert(&rowCdfs_[std::size_t(y) * (width_ + 1)], width_, u.x());
    return {x, y, Vec2d(tx, ty)};
}

double Distribution2D::probability(int x, int y) const {
    const double* row = &rowCdfs_[std::size_t(y) * (width_ + 1)];
    return (marginalCdf_[y + 1] - marginalCdf_[y]) * (row[x + 1] - row[x]);
}

}  // namespace phongfit
