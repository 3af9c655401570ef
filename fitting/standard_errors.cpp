#include "standard_errors.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>

#include "analysis.h"
#include "convergence.h"
#include "uncertainty.h"

namespace phongfit {

namespace {

// The indices of pixel `u`'s material slots' parameters in the sums' matrices, into `indices`.
template <int P>
const std::vector<Eigen::Index>& slotIndices(const UsedPixels& prep, const UsedPixel& u,
                                             std::vector<Eigen::Index>& indices) {
    indices.clear();
    for (std::uint32_t s : prep.slotsOf(u))
        for (int k = 0; k < P; ++k) indices.push_back(Eigen::Index(s) * P + k);
    return indices;
}

}  // namespace

template <int P>
Eigen::MatrixXd scores(Objective<P>& objective, const Linearization<P>& at,
                       const Instruments<P>* instruments, const Eigen::MatrixXd& jacobian,
                       const std::vector<bool>& held, double secondSign) {
    const UsedPixels& prep = objective.pixels();
    const int sets = objective.setCount();
    const Eigen::MatrixXd inverse = freeInverse(jacobian, held);
    const Eigen::Index size = jacobian.rows();
    return objective.sumPixels(
        prep.pixels.size(), Eigen::MatrixXd(Eigen::MatrixXd::Zero(size, size)),
        [&](std::size_t i, Eigen::MatrixXd& sum, typename Objective<P>::Scratch& scratch) {
            const UsedPixel& u = prep.pixels[i];
            const std::vector<Eigen::Index>& indices = slotIndices<P>(prep, u, scratch.indices);
            // A pixel that sees no material does not pull on the estimate. Its Jacobians at `at`
            // are replayed (Linearization does not keep them).
            const bool replay = u.seesMaterial || instruments == nullptr;
            for (int k = 0; replay && k < sets; ++k)
                objective.residual(k, u, at.y.data(), scratch, true);
            pixelMoment<P>(at, replay ? &scratch.jacobians : nullptr, instruments, sets, i, u,
                           scratch.moment, u.seesMaterial ? &scratch.momentJacobian : nullptr,
                           secondSign);
            const Eigen::VectorXd m =
                u.seesMaterial ? leaveOneOutScore(scratch.momentJacobian, inverse(indices, indices),
                                                  scratch.moment)
                               : scratch.moment;
            sum(indices, indices) += m * m.transpose();
        });
}

template <int P>
Eigen::MatrixXd anchorRecordingScores(Objective<P>& objective, const std::vector<double>& y,
                                      Eigen::Index size, bool cross) {
    const UsedPixels& prep = objective.pixels();
    const int sets = objective.setCount();
    if (sets < 2) return Eigen::MatrixXd::Zero(size, size);
    // Only the pixels that see a material have a term (analyse).
    return objective.sumPixels(
        prep.seeingMaterial, Eigen::MatrixXd(Eigen::MatrixXd::Zero(size, size)),
        [&](std::size_t i, Eigen::MatrixXd& sum, typename Objective<P>::Scratch& scratch) {
            const UsedPixel& u = prep.pixels[i];
            const std::vector<Eigen::Index>& indices = slotIndices<P>(prep, u, scratch.indices);
            Eigen::Vector3d r[2];
            double rho[2] = {1, 1};
            for (int k = 0; k < sets; ++k) {
                r[k] = objective.residual(k, u, y.data(), scratch, true);
                rho[k] = objective.lossWeight(r[k].squaredNorm());
            }
            anchorTerm<P>(scratch.jacobians, r, rho, sets, u.slotCount, cross, scratch.moment,
                          nullptr, -1);
            sum(indices, indices) += scratch.moment * scratch.moment.transpose();
        });
}

Eigen::MatrixXd anchorScores(const Eigen::MatrixXd& fitted, const Eigen::MatrixXd& recordings) {
    if (recordings.isZero(0)) return fitted;
    const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> excess(recordings - fitted);
    return fitted + excess.eigenvectors() * excess.eigenvalues().cwiseMax(0.0).asDiagonal() *
                        excess.eigenvectors().transpose();
}

template <int P>
std::vector<std::vector<double>> naturalStd(const Eigen::MatrixXd& jacobian,
                                            const Eigen::MatrixXd& scores,
                                            const std::vector<HeldParams>& held) {
    const std::vector<double> variance =
        sandwichVariances(jacobian, scores, ParameterState<P>::heldFlags(held));
    const int blocks = int(held.size());
    std::vector<std::vector<double>> result(blocks, std::vector<double>(P, 0.0));
    for (int s = 0; s < blocks; ++s)
        for (int i = 0; i < P; ++i) {
            const double v = variance[std::size_t(s) * P + i];
            result[s][i] = ParameterState<P>::isHeld(held[s], i) || !(v > 0) ? 0 : std::sqrt(v);
        }
    return result;
}

std::vector<std::vector<double>> noStd(int blocks, int p) {
    return std::vector<std::vector<double>>(blocks, std::vector<double>(p, 0.0));
}

template <int P>
double precision(const ParameterState<P>& params,
                 const std::vector<std::vector<double>>& stdNatural) {
    using L = BlockLayout<P>;
    double sum = 0;
    for (int s = 0; s < params.blockCount(); ++s) {
        const Eigen::Matrix<double, P, 1> y = params.natural(s);
        for (int i = 0; i < P; ++i) {
            if (params.isHeld(s, i)) continue;
            const double sd = stdNatural[std::size_t(s)][std::size_t(i)];
            if (!(sd > 0) || !std::isfinite(sd)) return 0;
            const double scale = i == L::kLogN ? 1.0 : std::max(std::abs(y[i]), kReflectanceFloor);
            sum += sd * sd / (scale * scale);
        }
    }
    return sum > 0 ? 1 / sum : 0;
}

template Eigen::MatrixXd scores<kRgbBlock>(Objective<kRgbBlock>&, const Linearization<kRgbBlock>&,
                                           const Instruments<kRgbBlock>*, const Eigen::MatrixXd&,
                                           const std::vector<bool>&, double);
template Eigen::MatrixXd anchorRecordingScores<kRgbBlock>(Objective<kRgbBlock>&,
                                                          const std::vector<double>&, Eigen::Index,
                                                          bool);
template Eigen::MatrixXd anchorRecordingScores<kGreyBlock>(Objective<kGreyBlock>&,
                                                           const std::vector<double>&, Eigen::Index,
                                                           bool);
template std::vector<std::vector<double>> naturalStd<kRgbBlock>(const Eigen::MatrixXd&,
                                                                const Eigen::MatrixXd&,
                                                                const std::vector<HeldParams>&);
template double precision<kRgbBlock>(const ParameterState<kRgbBlock>&,
                                     const std::vector<std::vector<double>>&);
template Eigen::MatrixXd scores<kGreyBlock>(Objective<kGreyBlock>&,
                                            const Linearization<kGreyBlock>&,
                                            const Instruments<kGreyBlock>*, const Eigen::MatrixXd&,
                                            const std::vector<bool>&, double);
template std::vector<std::vector<double>> naturalStd<kGreyBlock>(const Eigen::MatrixXd&,
                                                                 const Eigen::MatrixXd&,
                                                                 const std::vector<HeldParams>&);
template double precision<kGreyBlock>(const ParameterState<kGreyBlock>&,
                                      const std::vector<std::vector<double>>&);

}  // namespace phongfit
