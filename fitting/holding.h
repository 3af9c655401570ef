// Holding what the images leave unconstrained at a round's solution (identifiability.h decides
// from the information matrix; this applies it to the parameter state).
#pragma once

#include "analysis.h"
#include "identifiability.h"
#include "parameter_state.h"
#include "used_pixels.h"

namespace phongfit {

// Holds the parameters findUnconstrained finds in `analysis`' Gram matrix (at their start; an n
// found with its ks, a lobe no pixel sees, where it is), then, if none, the exponents of materials
// that show no lobe (holdUnseenExponents). True if anything new is held:
// the problem changed and is solved again.
template <int P>
bool holdUnconstrained(const Analysis& analysis, const UsedPixels& pixels,
                       ParameterState<P>& params);

// Material s's free ks groups, with their standard errors from `naturalStd` (per block, natural
// coordinates), each at least `ksStdFloor`'s for its group when given.
template <int P>
SpecularGroups freeSpecular(const ParameterState<P>& params, int s,
                            const std::vector<std::vector<double>>& naturalStd,
                            const std::vector<std::vector<double>>* ksStdFloor = nullptr);

// n only shapes the lobe: where no free ks of a material is `significance` standard errors above
// 0 (lobeDetected), its n is held: at its start value, or where it is if that is broader than
// the start (a broad lobe sent back to a sharp start gave its share of the shading to kd). The
// standard errors are least squares' with every material's n held: n has no effect at ks = 0, the
// hypothesis tested, and with n free they would count the trade-off between ks and n that only a
// lobe has. `ksStdFloor` (per material, per ks group), if given, is a least standard error for ks:
// the scatter of the rounds' estimates (round_scatter.h).
template <int P>
bool holdUnseenExponents(const Analysis& analysis, ParameterState<P>& params,
                         double significance = kLobeSignificance,
                         const std::vector<std::vector<double>>* ksStdFloor = nullptr);

}  // namespace phongfit
