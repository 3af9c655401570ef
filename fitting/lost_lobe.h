// Where the next round records when a round lost the lobe the round before it showed: its solve
// sent n to where no recorded path sees the lobe, and both ks and n were held there (holding.cpp,
// a lobe no pixel sees; ks then at its start, now at 0). Recordings sparse in a lobe sharper than
// the one they were made at can do that, and the hold then outlives its reason: the Cornell box
// under a point light at 64x64 (kd 0.84, ks 0.077, n 139, from n 1.39) solved ks 0.10 +- 0.016, n
// 51 +- 13 in round 0; round 1, recorded there, sent n to 1e6, and with ks held at 0.3 the rounds
// ended at kd 0.66 +- 0.02. docs/design/fitter.md, "A lobe lost".
#pragma once

#include <vector>

#include "fitter.h"

namespace phongfit {

// The round that records again where the lobe was seen has this many times the lost round's paths.
inline constexpr double kLostLobePaths = 4;

// Whether a round's material `m` shows a lobe: n resolved (not unconstrained) and some channel's
// ks at least kLobeConfirmation of its standard errors.
bool showsLobe(const MaterialFit& m);

// The materials (indices) whose lobe `before` (the round before) showed and `after` lost: ks and n
// both unconstrained.
std::vector<int> lostLobes(const std::vector<MaterialFit>& before,
                           const std::vector<MaterialFit>& after);

}  // namespace phongfit
