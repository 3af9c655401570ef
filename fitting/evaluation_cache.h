// What a residual block computed at its last point, for the next evaluation at the same point.
//
// Ceres evaluates a trial point without Jacobians and, once it accepts the step, with them at the
// same point; and dogleg, after a rejected step, tries the same step again while its region is
// still larger than it (a moment solve from Ceres' initial radius of 1e4 evaluated one trial point
// up to seven times). The blocks sum every pixel once a point, Jacobians included (the seeded
// replay costs what the plain one does), and hand back what they summed there: the same numbers,
// one replay of every path fewer an accepted step.
#pragma once

#include <utility>
#include <vector>

namespace phongfit {

template <typename Value>
class EvaluationCache {
public:
    // What was stored for `y`, or null.
    const Value* find(const std::vector<double>& y) const {
        return valid_ && y == y_ ? &value_ : nullptr;
    }

    const Value& store(const std::vector<double>& y, Value value) {
        y_ = y;
        value_ = std::move(value);
        valid_ = true;
        return value_;
    }

private:
    bool valid_ = false;
    std::vector<double> y_;
    Value value_;
};

}  // namespace phongfit
