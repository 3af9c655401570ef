// The rounds loop: record two path sets per view at the current estimate, solve the round,
// repeat until the estimate stops moving (fitter.h).
#pragma once

#include <functional>
#include <vector>

#include "fitter.h"
#include "observation.h"
#include "path_set.h"

namespace phongfit {

// The two path-set lists of a round, one set per view each; the same list twice for exact sets.
struct RoundSets {
    const std::vector<PathSet>* first;
    const std::vector<PathSet>* second;
};

// Records (or hands out) round `round`'s sets at the materials' estimate; `importance` per view
// and pixel (path_importance.h), empty in the first round; `pathFactor` as PathRecorder's.
using RecordAll =
    std::function<RoundSets(const std::vector<PhongMaterial>&, int round,
                            const std::vector<std::vector<float>>& importance, double pathFactor)>;

// At most `maxRounds` rounds from `start` on inputs fitMaterials has checked; P is the block size
// (kRgbBlock, or kGreyBlock with FitOptions::grey). `rerecords`: the recorder records at the
// estimate it is given (not fixed sets), so a converged lobe is probed from the sharp side
// (sharper_probe.h). Throws Error when the recorder's sets do not match the observations.
template <int P>
FitResult runRounds(const std::vector<Observation>& observations, const RecordAll& recordAll,
                    const std::vector<PhongMaterial>& start, const FitOptions& options,
                    int maxRounds, bool rerecords);

}  // namespace phongfit
