// Checks of what the fitter is given, so a bad input fails with a message, not a crash.
#pragma once

#include "observation.h"
#include "path_set.h"

namespace phongfit {

// Throws Error unless `obs` has 3 values per pixel, a mask and weights with one entry per pixel or
// none, and finite weights >= 0.
void checkObservation(const Observation& obs, int view);

// Throws Error unless `paths` matches `obs` in size, has `slots` material slots and consistent
// pixel, term and vertex indices, and log cos alpha <= 0 (or -inf) at every vertex.
void checkPathSet(const PathSet& paths, const Observation& obs, int view, int slots);

}  // namespace phongfit
