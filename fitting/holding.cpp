#include "holding.h"

#include <algorithm>
#include <cmath>

#include "identifiability.h"
#include "standard_errors.h"

namespace phongfit {

namespace {
// Below this exponent the lobe has no shape left: (n + 2) / 2 cos^n alpha is 1 within 1% wherever
// cos alpha > 0.37, a second diffuse term rather than a lobe the images show.
constexpr double kShapelessExponent = 0.01;
}  // namespace

template <int P>
bool holdUnconstrained(const Analysis& analysis, const UsedPixels& pixels,
                       ParameterState<P>& params) {
    using L = BlockLayout<P>;
    const std::vector<int> found = findUnconstrained(
        analysis.gram, 3.0 * double(pixels.seeingMaterial), pixels.rmsObserved, params.heldFlags());
    // A lobe no pixel sees (ks and n both found) stays where it is unseen: n at its start, where
    // the held ks (its start) would be seen, was a lobe the images contradict, and kd fitted to
    // make up for it (kd 0.32 for 0.49 where n had gone to its bound, 1e6, from a start of 60).
    std::vector<int> atStart, inPlace;
    for (int index : found) {
        const int s = index / P;
        const bool unseenLobe =
            index % P == L::kLogN && std::any_of(found.begin(), found.end(), [&](int other) {
                return other / P == s && other % P >= L::specular(0) && other % P < L::kLogN;
            });
        (unseenLobe ? inPlace : atStart).push_back(index);
    }
    const bool held = params.hold(atStart);
    return params.hold(inPlace, false) || held || holdUnseenExponents(analysis, params);
}

template <int P>
bool holdUnseenExponents(const Analysis& analysis, ParameterState<P>& params, double significance,
                         const std::vector<std::vector<double>>* ksStdFloor) {
    using L = BlockLayout<P>;
    std::vector<HeldParams> exponentsHeld = params.held();
    for (int s = 0; s < params.materialCount(); ++s) exponentsHeld[s].n = true;
    const std::vector<std::vector<double>> stdNatural =
        naturalStd<P>(analysis.gram, analysis.leastSquaresScores, exponentsHeld);
    std::vector<int> indices, broader;
    for (int s = 0; s < params.materialCount(); ++s) {
        const HeldParams& held = params.held(s);
        if (held.n) continue;
        const Eigen::Matrix<double, P, 1> y = params.natural(s);
        // Near its lower bound n is not measured, whatever ks's significance.
        if (y[L::kLogN] <= std::log(kShapelessExponent)) {
            indices.push_back(s * P + L::kLogN);
            continue;
        }
        std::vector<double> ks, ksStd;
        for (int g = 0; g < L::kGroups; ++g) {
            if (held.ks[g]) continue;
            ks.push_back(y[L::specular(g)]);
            const double floor = ksStdFloor ? (*ksStdFloor)[std::size_t(s)][std::size_t(g)] : 0;
            ksStd.push_back(std::max(stdNatural[s][L::specular(g)], floor));
        }
        if (lobeDetected(ks, ksStd, significance)) continue;
        const bool broad = y[L::kLogN] < std::log(params.start(s).n);
        (broad ? broader : indices).push_back(s * P + L::kLogN);
    }
    const bool atStart = params.hold(indices);
    return params.hold(broader, false) || atStart;
}

template bool holdUnconstrained<kRgbBlock>(const Analysis&, const UsedPixels&,
                                           ParameterState<kRgbBlock>&);
template bool holdUnconstrained<kGreyBlock>(const Analysis&, const UsedPixels&,
                                            ParameterState<kGreyBlock>&);
template bool holdUnseenExponents<kRgbBlock>(const Analysis&, ParameterState<kRgbBlock>&, double,
                                             const std::vector<std::vector<double>>*);
template bool holdUnseenExponents<kGreyBlock>(const Analysis&, ParameterState<kGreyBlock>&, double,
                                              const std::vector<std::vector<double>>*);

}  // namespace phongfit
