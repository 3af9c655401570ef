// The path sets one round replays (the data of the problem, as Ceres' BALProblem is): two
// independent recordings per view, and for least squares their pool.
#pragma once

#include <cstddef>
#include <vector>

#include "path_set.h"

namespace phongfit {

// One path-set list per view for each set an estimator replays.
using SetLists = std::vector<const std::vector<PathSet>*>;

// One set whose estimate is the mean of the two sets' estimates: both sets' terms at half weight.
PathSet pool(const PathSet& a, const PathSet& b);

// What the sets hold, in bytes: terms, vertices, backgrounds and pixel starts.
std::size_t recordedBytes(const std::vector<PathSet>& sets);

class RoundPaths {
public:
    // `first` and `second` (one set per view each) must outlive this; exact, noise-free sets are
    // passed as the same list twice.
    RoundPaths(const std::vector<PathSet>& first, const std::vector<PathSet>& second)
        : first_(&first), second_(&second) {}

    const std::vector<PathSet>& first() const { return *first_; }
    const std::vector<PathSet>& second() const { return *second_; }
    bool exact() const { return first_ == second_; }

    // The sets least squares replays: exact sets as they are, else the two recordings pooled,
    // built on first use (the instrumental-variables rounds need them only for the exponent
    // scan, the exposure match and the fallback anchor).
    const std::vector<PathSet>& leastSquaresSets();

    // Both recordings (instrumental variables) or the least-squares sets.
    SetLists sets(bool instrumental) {
        return instrumental ? SetLists{first_, second_} : SetLists{&leastSquaresSets()};
    }

private:
    const std::vector<PathSet>* first_;
    const std::vector<PathSet>* second_;
    std::vector<PathSet> pooled_;  // leastSquaresSets(), once built
};

}  // namespace phongfit
