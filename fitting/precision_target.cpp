#include "precision_target.h"

#include <algorithm>
#include <cmath>
#include <span>

#include "convergence.h"
#include "replay_jacobian.h"
#include "standard_errors.h"

namespace phongfit {

namespace {
// The sandwiches' meats over the pixels that see a material.
struct ShareSums {
    Eigen::MatrixXd mean, path;
    ShareSums& operator+=(const ShareSums& other) {
        mean += other.mean;
        path += other.path;
        return *this;
    }
};
}  // namespace

template <int P>
std::vector<std::vector<double>> recordingShare(Objective<P>& objective, const Linearization<P>& at,
                                                const Eigen::MatrixXd& gram,
                                                const std::vector<HeldParams>& held) {
    using Jacobian = Eigen::Matrix<double, 3, P>;
    std::vector<std::vector<double>> share(held.size(), std::vector<double>(P, 0.0));
    if (objective.setCount() < 2) return share;
    const UsedPixels& prep = objective.pixels();
    const Eigen::Index size = Eigen::Index(objective.blocks()) * P;
    const ShareSums zero{Eigen::MatrixXd::Zero(size, size), Eigen::MatrixXd::Zero(size, size)};
    const ShareSums sums = objective.sumPixels(
        prep.seeingMaterial, zero,
        [&](std::size_t i, ShareSums& sum, typename Objective<P>::Scratch& scratch) {
            const UsedPixel& u = prep.pixels[i];
            const std::span<const std::uint32_t> slots = prep.slotsOf(u);
            const auto where = [&](std::uint32_t a) { return Eigen::Index(slots[a]) * P; };
            Eigen::VectorXd &m = scratch.meanScore, &q = scratch.pathScore;
            m.setZero(Eigen::Index(u.slotCount) * P);
            q.setZero(Eigen::Index(u.slotCount) * P);
            const Eigen::Vector3d halfSum = 0.5 * (at.residuals[0][i] + at.residuals[1][i]);
            const Eigen::Vector3d halfDifference = 0.5 * (at.residuals[0][i] - at.residuals[1][i]);
            const double rho = 0.5 * (at.weights[0][i] + at.weights[1][i]);
            for (std::uint32_t a = 0; a < u.slotCount; ++a)
                for (const Jacobian* j :
                     {&at.jacobians[0][u.slotBegin + a], &at.jacobians[1][u.slotBegin + a]}) {
                    addPackedGradient<P>(m.segment<P>(Eigen::Index(a) * P), 0.5 * rho, *j, halfSum);
                    addPackedGradient<P>(q.segment<P>(Eigen::Index(a) * P), 0.5 * rho, *j,
                                         halfDifference);
                }
            for (std::uint32_t a = 0; a < u.slotCount; ++a)
                for (std::uint32_t b = 0; b < u.slotCount; ++b) {
                    sum.mean.block<P, P>(where(a), where(b)) +=
                        m.segment<P>(Eigen::Index(a) * P) *
                        m.segment<P>(Eigen::Index(b) * P).transpose();
                    sum.path.block<P, P>(where(a), where(b)) +=
                        q.segment<P>(Eigen::Index(a) * P) *
                        q.segment<P>(Eigen::Index(b) * P).transpose();
                }
        });
    const std::vector<std::vector<double>> all = naturalStd<P>(gram, sums.mean, held),
                                           fromPaths = naturalStd<P>(gram, sums.path, held);
    for (std::size_t b = 0; b < all.size(); ++b)
        for (std::size_t i = 0; i < all[b].size(); ++i)
            share[b][i] =
                all[b][i] > 0 ? std::min(1.0, std::pow(fromPaths[b][i] / all[b][i], 2)) : 0.0;
    return share;
}

template <int P>
PrecisionPlan planPrecision(const ParameterState<P>& params,
                            const std::vector<std::vector<double>>& naturalStd,
                            const std::vector<std::vector<double>>& pathShare, double target,
                            double pathFactor) {
    using L = BlockLayout<P>;
    PrecisionPlan plan;
    const double goal = target * target;
    bool allMet = true, allUnmetAtFloor = true;
    const std::vector<bool> held = params.heldFlags();
    for (int s = 0; s < params.materialCount(); ++s) {
        const typename ParameterState<P>::NaturalVector y = params.natural(s);
        for (int i = 0; i < P; ++i) {
            if (held[std::size_t(s * P + i)]) continue;
            const double scale = i == L::kLogN ? 1.0 : std::max(std::abs(y[i]), kReflectanceFloor);
            const double variance = std::pow(naturalStd[s][i] / scale, 2);
            if (variance <= goal) continue;
            allMet = false;
            const double share = std::clamp(pathShare[s][i], 0.0, 1.0);
            const double fromImage = (1 - share) * variance, fromPaths = share * variance;
            if (fromImage >= goal && pathFactor >= kMostPathGrowth) continue;
            allUnmetAtFloor = false;
            plan.pathGrowth =
                std::max(plan.pathGrowth, fromImage >= goal ? kMostPathGrowth / pathFactor
                                                            : fromPaths / (goal - fromImage));
        }
    }
    plan.met = allMet;
    plan.floor = !allMet && allUnmetAtFloor;
    plan.pathGrowth = std::min(plan.pathGrowth, kMostPathGrowth);
    return plan;
}

template std::vector<std::vector<double>> recordingShare<kRgbBlock>(Objective<kRgbBlock>&,
                                                                    const Linearization<kRgbBlock>&,
                                                                    const Eigen::MatrixXd&,
                                                                    const std::vector<HeldParams>&);
template std::vector<std::vector<double>> recordingShare<kGreyBlock>(
    Objective<kGreyBlock>&, const Linearization<kGreyBlock>&, const Eigen::MatrixXd&,
    const std::vector<HeldParams>&);
template PrecisionPlan planPrecision<kRgbBlock>(const ParameterState<kRgbBlock>&,
                                                const std::vector<std::vector<double>>&,
                                                const std::vector<std::vector<double>>&, double,
                                                double);
template PrecisionPlan planPrecision<kGreyBlock>(const ParameterState<kGreyBlock>&,
                                                 const std::vector<std::vector<double>>&,
                                                 const std::vector<std::vector<double>>&, double,
                                                 double);

}  // namespace phongfit
