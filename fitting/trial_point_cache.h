// The residuals of the last evaluation without Jacobians, for the next one at the same point.
//
// Dogleg shrinks its trust region after a rejected step, but while the region is still larger than
// the Gauss-Newton step that step is tried again, unchanged: a moment solve from Ceres' initial
// radius of 1e4 evaluated one trial point up to seven times (a replay of every path each time).
// The residuals at a point are a function of the point, so handing back the stored ones changes
// nothing but the time.
#pragma once

#include <algorithm>
#include <vector>

namespace phongfit {

class TrialPointCache {
public:
    // Copies the residuals stored for `y` into `residuals` and returns true, or returns false.
    bool find(const std::vector<double>& y, double* residuals) const {
        if (!valid_ || y != y_) return false;
        std::copy(residuals_.begin(), residuals_.end(), residuals);
        return true;
    }

    void store(const std::vector<double>& y, const double* residuals, int count) {
        y_ = y;
        residuals_.assign(residuals, residuals + count);
        valid_ = true;
    }

private:
    bool valid_ = false;
    std::vector<double> y_, residuals_;
};

}  // namespace phongfit
