// Picks a cell of a grid with probability proportional to its nonnegative weight, by inverse CDF (a
// row from the marginal, then a column within it; pbrt's PiecewiseConstant2D), and hands back
// where the point fell within the cell, so that a caller can reuse it as a fresh uniform point.
#pragma once

#include <utility>
#include <vector>

#include "math.h"

namespace phongfit {

class Distribution2D {
public:
    // weights: width x height, row-major, nonnegative and finite; all zero gives the uniform
    // choice.
    Distribution2D(const std::vector<double>& weights, int width, int height);

    struct Sample {
        int x, y;
        Vec2d within;  // in [0, 1)^2: uniform when u is
    };
    // u.x picks the column, u.y the row: a stratified u stays stratified over the grid.
    Sample sample(const Vec2d& u) const;
    // Probability of cell (x, y); they sum to 1.
    double probability(int x, int y) const;

private:
    static std::pair<int, double> invert(const double* cdf, int n, double u);

    int width_, height_;
    std::vector<double> rowCdfs_;      // per row, width + 1 entries from 0 to 1
    std::vector<double> marginalCdf_;  // height + 1 entries from 0 to 1
};

}  // namespace phongfit
