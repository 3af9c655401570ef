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
    // A ks found with its n (or with its n held) is held at 0, not at its start: unseen (n at 1e6)
    // or shapeless (n near 0, ks collinear with kd), the images show no lobe, and a shapeless one
    // held at the start's 0.3 took 0.3 from kd (a lobeless point-lit sphere: kd 0, 0.587, 0.106
    // for 0.175, 0.844, 0.362). A ks found alone (a channel no light reaches) stays at its start.
    const auto isSpecular = [](int index) {
        return index % P >= L::specular(0) && index % P < L::kLogN;
    };
    const auto foundWith = [&](int s, const auto& kind) {
        return std::any_of(found.begin(), found.end(),
                           [&](int other) { return other / P == s && kind(other); });
    };
    std::vector<int> atStart, inPlace, absent;
    for (int index : found) {
        const int s = index / P;
        const bool unseenLobe = index % P == L::kLogN && foundWith(s, isSpecular);
        const bool noLobe =
            isSpecular(index) &&
            (params.held(s).n || foundWith(s, [](int other) { return other % P == L::kLogN; }));
        (noLobe ? absent : unseenLobe ? inPlace : atStart).push_back(index);
    }
    const bool held = params.hold(atStart);
    const bool zeroed = params.holdAtZero(absent);
    return params.hold(inPlace, false) || held || zeroed || holdUnseenExponents(analysis, params);
}

template <int P>
SpecularGroups freeSpecular(const ParameterState<P>& params, int s,
                            const std::vector<std::vector<double>>& naturalStd,
                            const std::vector<std::vector<double>>* ksStdFloor) {
    using L = BlockLayout<P>;
    const Eigen::Matrix<double, P, 1> y = params.natural(s);
    SpecularGroups groups;
    for (int g = 0; g < L::kGroups; ++g) {
        if (params.held(s).ks[std::size_t(g)]) continue;
        const double floor = ksStdFloor ? (*ksStdFloor)[std::size_t(s)][std::size_t(g)] : 0;
        groups.ks.push_back(y[L::specular(g)]);
        groups.std.push_back(
            std::max(naturalStd[std::size_t(s)][std::size_t(L::specular(g))], floor));
    }
    return groups;
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
        const SpecularGroups groups = freeSpecular(params, s, stdNatural, ksStdFloor);
        if (lobeDetected(groups.ks, groups.std, significance)) continue;
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
template SpecularGroups freeSpecular<kRgbBlock>(const ParameterState<kRgbBlock>&, int,
                                                const std::vector<std::vector<double>>&,
                                                const std::vector<std::vector<double>>*);
template SpecularGroups freeSpecular<kGreyBlock>(const ParameterState<kGreyBlock>&, int,
                                                 const std::vector<std::vector<double>>&,
                                                 const std::vector<std::vector<double>>*);
template bool holdUnseenExponents<kRgbBlock>(const Analysis&, ParameterState<kRgbBlock>&, double,
                                             const std::vector<std::vector<double>>*);
template bool holdUnseenExponents<kGreyBlock>(const Analysis&, ParameterState<kGreyBlock>&, double,
                                              const std::vector<std::vector<double>>*);

}  // namespace phongfit
