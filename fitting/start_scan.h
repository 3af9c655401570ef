// Where the first round starts: the exposure matched to the images' brightness, and each
// material's exponent chosen by a scan (FitOptions::scanStart), since a start with n off by 10x or
// more can end in a local minimum; later rounds scan the broader side of their lobes again.
#pragma once

#include <algorithm>
#include <vector>

#include "material_params.h"
#include "objective.h"
#include "parameter_state.h"

namespace phongfit {

// Sets the exposure to the s that fits the images best with the materials where they are
// (ExposureBlock::matched; one Gauss-Newton step in log s lands there from anywhere). It is also
// the value the exposure is held at if the images do not constrain it.
template <int P>
void matchExposure(Objective<P>& objective, ParameterState<P>& params);

// One material after the other: for each exponent on a grid (factors of 4 over its range), kd and
// ks take one Gauss-Newton step from where they are, then the least-squares costs are compared.
// The step is exact where every recorded term has one vertex on the material, as under direct
// light: I is then linear in kd and ks. The start competes first, and another exponent must do
// better by more than rounding: where the images show no lobe every exponent fits equally well.
// A candidate whose lobe the two recordings' cross products single out overrules that pick: a
// faint broad lobe adds more of the recordings' variance to least squares than it removes.
template <int P>
void scanExponents(Objective<P>& objective, ParameterState<P>& params);

// In a later round, recorded at the estimate: the scan for the `materials` flagged (per
// material), over the grid's exponents broader than the estimate's by more than 2x, comparing the
// cross products of the two recordings; a material moves only where a grid exponent wins. A start
// on a lobe's sharp side can climb where n only sharpens the edge of a light's reflection and the
// cost is flat (docs/design/fitter.md, "Later rounds scan the broader side").
template <int P>
void scanBroaderExponents(Objective<P>& objective, ParameterState<P>& params,
                          const std::vector<bool>& materials);

// kd, ks >= 0 and kd + ks <= 1 per colour group of natural coordinates y, by clamping; a held kd
// stays and bounds ks instead.
template <int P>
void clampReflectances(double* y, const HeldParams& held) {
    using L = BlockLayout<P>;
    for (int g = 0; g < L::kGroups; ++g) {
        double& kd = y[L::diffuse(g)];
        double& ks = y[L::specular(g)];
        ks = std::clamp(ks, 0.0, held.kd[g] ? 1.0 - kd : 1.0);
        if (!held.kd[g]) kd = std::clamp(kd, 0.0, 1.0 - ks);
    }
}

}  // namespace phongfit
