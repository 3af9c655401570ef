// The path sets one round replays (the data of the problem, as Ceres' BALProblem is): two
// independent recordings per view.
#pragma once

#include <cstddef>
#include <vector>

#include "path_set.h"

namespace phongfit {

// One path-set list per view for each recording an estimator replays.
using SetLists = std::vector<const std::vector<PathSet>*>;

// What the sets hold, in bytes: terms, vertices, backgrounds, pixel starts and path counts.
std::size_t recordedBytes(const std::vector<PathSet>& sets);

}  // namespace phongfit
