// When an estimate has stopped moving (FitOptions::tolerance, stdTolerance).
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <vector>

#include "fitter.h"
#include "material_params.h"

namespace phongfit {

// Reflectances below this are compared absolutely.
inline constexpr double kReflectanceFloor = 0.01;

// Whether every parameter moved from `before` to `after` (natural coordinates, per block) by less
// than tolerance * max(|before|, kReflectanceFloor) (log n: tolerance), or by less than
// stdTolerance times its standard error in `naturalStd` (0: that test never passes).
template <int P>
bool withinTolerance(const std::vector<Eigen::Matrix<double, P, 1>>& before,
                     const std::vector<Eigen::Matrix<double, P, 1>>& after,
                     const std::vector<std::vector<double>>& naturalStd,
                     const FitOptions& options) {
    using L = BlockLayout<P>;
    for (std::size_t s = 0; s < before.size(); ++s) {
        for (int i = 0; i < P; ++i) {
            const double change = std::abs(after[s][i] - before[s][i]);
            const double scale =
                i == L::kLogN ? 1.0 : std::max(std::abs(before[s][i]), kReflectanceFloor);
            if (change > options.tolerance * scale &&
                change > options.stdTolerance * naturalStd[s][i])
                return false;
        }
    }
    return true;
}

}  // namespace phongfit
