#include "precision_target.h"

#include <algorithm>
#include <cmath>

#include "holding.h"
#include "identifiability.h"
#include "round_outcome.h"
#include "standard_errors.h"

namespace phongfit {

template <int P>
std::vector<std::vector<double>> recordingShare(Objective<P>& objective, const Linearization<P>& at,
                                                const Instruments<P>* instruments,
                                                const Analysis& analysis,
                                                const std::vector<HeldParams>& held,
                                                const AnchorSandwich* anchor) {
    std::vector<std::vector<double>> share(held.size(), std::vector<double>(P, 0.0));
    if (instruments == nullptr || objective.setCount() < 2) return share;
    const std::vector<bool> flags = ParameterState<P>::heldFlags(held);
    const Eigen::MatrixXd& jacobian = anchor == nullptr ? analysis.jacobian
                                      : anchor->cross   ? analysis.crossGram
                                                        : analysis.gram;
    const std::vector<std::vector<double>> all = naturalStd<P>(
        jacobian,
        anchor == nullptr
            ? analysis.scores
            : anchorScores(anchor->cross ? analysis.crossScores : analysis.leastSquaresScores,
                           anchor->recordings),
        held);
    const std::vector<std::vector<double>> fromPaths =
        naturalStd<P>(jacobian,
                      anchor == nullptr ? scores(objective, at, instruments, jacobian, flags, -1)
                                        : anchor->recordings,
                      held);
    for (std::size_t b = 0; b < all.size(); ++b)
        for (std::size_t i = 0; i < all[b].size(); ++i)
            share[b][i] =
                all[b][i] > 0 ? std::min(1.0, std::pow(fromPaths[b][i] / all[b][i], 2)) : 0.0;
    return share;
}

template <int P>
std::vector<bool> showsNoLobe(const ParameterState<P>& params,
                              const std::vector<std::vector<double>>& naturalStd) {
    std::vector<bool> noLobe;
    for (int s = 0; s < params.materialCount(); ++s) {
        const SpecularGroups groups = freeSpecular(params, s, naturalStd);
        noLobe.push_back(params.held(s).n && !lobeConfirmed(groups.ks, groups.std));
    }
    return noLobe;
}

bool meetsPrecision(const std::vector<MaterialFit>& materials, double target, PrecisionOf which) {
    const bool reported = which == PrecisionOf::Reported;
    for (const MaterialFit& m : materials) {
        const Color3& kd = reported ? m.kdStd : m.kdImageStd;
        const Color3& ks = reported ? m.ksStd : m.ksImageStd;
        const bool noLobe = noLobeSeen(m);
        for (int c = 0; c < 3; ++c)
            if (kd[c] > target * reflectancePrecisionScale(m.kd[c]) ||
                ks[c] > target * reflectancePrecisionScale(noLobe ? m.kd[c] + m.ks[c] : m.ks[c]))
                return false;
        const double logN = reported ? m.logNStd : m.logNImageStd;
        if (logN > target && !m.isUnconstrained("n")) return false;
    }
    return true;
}

template <int P>
PrecisionPlan planPrecision(const ParameterState<P>& params,
                            const std::vector<std::vector<double>>& naturalStd,
                            const std::vector<std::vector<double>>& pathShare, double target,
                            double pathFactor) {
    PrecisionPlan plan;
    const double goal = target * target;
    bool allMet = true, allUnmetAtFloor = true;
    const std::vector<bool> held = params.heldFlags();
    const std::vector<bool> noLobe = showsNoLobe(params, naturalStd);
    for (int s = 0; s < params.materialCount(); ++s) {
        const typename ParameterState<P>::NaturalVector y = params.natural(s);
        for (int i = 0; i < P; ++i) {
            if (held[std::size_t(s * P + i)]) continue;
            const double variance =
                std::pow(naturalStd[s][i] / precisionScale<P>(i, y, noLobe[std::size_t(s)]), 2);
            if (variance <= goal) continue;
            allMet = false;
            const double share = std::clamp(pathShare[s][i], 0.0, 1.0);
            const double fromImage = (1 - share) * variance, fromPaths = share * variance;
            // Out of reach; at the floor once the paths have grown and no longer hold the
            // larger part (else more paths still shrink it: to the image's part, at most).
            const bool outOfReach = fromImage >= goal;
            if (outOfReach && fromImage >= fromPaths && pathFactor >= kMostPathGrowth) continue;
            allUnmetAtFloor = false;
            plan.pathGrowth = std::max(
                plan.pathGrowth, !outOfReach ? fromPaths / (goal - fromImage)
                                 : pathFactor < kMostPathGrowth
                                     ? std::max(kMostPathGrowth / pathFactor, fromPaths / fromImage)
                                     : fromPaths / fromImage);
        }
    }
    plan.met = allMet;
    plan.floor = !allMet && allUnmetAtFloor;
    plan.pathGrowth = std::min(plan.pathGrowth, kMostPathGrowth);
    return plan;
}

template <int P>
bool movedPastTarget(const ParameterState<P>& params,
                     const std::vector<std::vector<double>>& naturalStd,
                     const std::vector<Eigen::Matrix<double, P, 1>>& before,
                     const std::vector<Eigen::Matrix<double, P, 1>>& after, double target) {
    const std::vector<bool> held = params.heldFlags();
    const std::vector<bool> noLobe = showsNoLobe(params, naturalStd);
    for (std::size_t s = 0; s < before.size(); ++s)
        for (int i = 0; i < P; ++i)
            if (!held[s * P + std::size_t(i)] &&
                std::abs(after[s][i] - before[s][i]) >
                    target * precisionScale<P>(i, before[s], s < noLobe.size() && noLobe[s]))
                return true;
    return false;
}

template std::vector<std::vector<double>> recordingShare<kRgbBlock>(
    Objective<kRgbBlock>&, const Linearization<kRgbBlock>&, const Instruments<kRgbBlock>*,
    const Analysis&, const std::vector<HeldParams>&, const AnchorSandwich*);
template std::vector<std::vector<double>> recordingShare<kGreyBlock>(
    Objective<kGreyBlock>&, const Linearization<kGreyBlock>&, const Instruments<kGreyBlock>*,
    const Analysis&, const std::vector<HeldParams>&, const AnchorSandwich*);
template PrecisionPlan planPrecision<kRgbBlock>(const ParameterState<kRgbBlock>&,
                                                const std::vector<std::vector<double>>&,
                                                const std::vector<std::vector<double>>&, double,
                                                double);
template PrecisionPlan planPrecision<kGreyBlock>(const ParameterState<kGreyBlock>&,
                                                 const std::vector<std::vector<double>>&,
                                                 const std::vector<std::vector<double>>&, double,
                                                 double);

template std::vector<bool> showsNoLobe<kRgbBlock>(const ParameterState<kRgbBlock>&,
                                                  const std::vector<std::vector<double>>&);
template std::vector<bool> showsNoLobe<kGreyBlock>(const ParameterState<kGreyBlock>&,
                                                   const std::vector<std::vector<double>>&);
template bool movedPastTarget<kRgbBlock>(const ParameterState<kRgbBlock>&,
                                         const std::vector<std::vector<double>>&,
                                         const std::vector<Eigen::Matrix<double, kRgbBlock, 1>>&,
                                         const std::vector<Eigen::Matrix<double, kRgbBlock, 1>>&,
                                         double);
template bool movedPastTarget<kGreyBlock>(const ParameterState<kGreyBlock>&,
                                          const std::vector<std::vector<double>>&,
                                          const std::vector<Eigen::Matrix<double, kGreyBlock, 1>>&,
                                          const std::vector<Eigen::Matrix<double, kGreyBlock, 1>>&,
                                          double);

}  // namespace phongfit
