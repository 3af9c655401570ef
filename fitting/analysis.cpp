#include "analysis.h"

#include <cmath>
#include <span>

#include "standard_errors.h"

namespace phongfit {

template <int P>
Analysis analyse(Objective<P>& objective, const ParameterState<P>& params,
                 const Instruments<P>* instruments, Linearization<P>& at) {
    using Jacobian = Eigen::Matrix<double, 3, P>;
    const UsedPixels& prep = objective.pixels();
    const std::vector<double> y = params.naturalCoordinates();
    const int sets = objective.setCount();
    const bool moments = instruments == nullptr || !instruments->empty();
    at.y = y;
    for (int k = 0; k < sets; ++k) {
        at.residuals[k].resize(prep.pixels.size());
        at.weights[k].resize(prep.pixels.size());
    }
    const Eigen::Index size = Eigen::Index(objective.blocks()) * P;
    const Eigen::MatrixXd zeros = Eigen::MatrixXd::Zero(size, size);
    const Analysis zero{zeros, zeros, Eigen::MatrixXd(), zeros, zeros, zeros, 0.0};
    Analysis result = objective.sumPixels(
        prep.pixels.size(), zero,
        [&](std::size_t i, Analysis& sum, typename Objective<P>::Scratch& scratch) {
            const UsedPixel& u = prep.pixels[i];
            const std::span<const std::uint32_t> slots = prep.slotsOf(u);
            const auto where = [&](std::uint32_t a) { return Eigen::Index(slots[a]) * P; };
            Eigen::Vector3d mean = Eigen::Vector3d::Zero();
            Eigen::VectorXd& l = scratch.moment;
            l.setZero(Eigen::Index(u.slotCount) * P);
            Eigen::Vector3d r[2];
            for (int k = 0; k < sets; ++k) {
                r[k] = objective.residual(k, u, y.data(), scratch, true);
                const std::vector<Jacobian>& j = scratch.jacobians[k];
                const double rho = objective.lossWeight(r[k].squaredNorm());
                at.residuals[k][i] = r[k].cast<float>();
                at.weights[k][i] = float(rho);
                mean += r[k] / sets;
                for (std::uint32_t a = 0; a < u.slotCount; ++a) {
                    addPackedGradient<P>(l.segment<P>(Eigen::Index(a) * P), rho / sets, j[a], r[k]);
                    for (std::uint32_t b = 0; u.seesMaterial && b < u.slotCount; ++b)
                        addPackedGram<P>(sum.gram.block<P, P>(where(a), where(b)), rho / sets, j[a],
                                         j[b]);
                }
            }
            if (!u.seesMaterial) return;
            sum.squares += mean.squaredNorm() / std::pow(objective.weight(u), 2);
            for (std::uint32_t a = 0; a < u.slotCount; ++a)
                for (std::uint32_t b = 0; b < u.slotCount; ++b)
                    sum.leastSquaresScores.block<P, P>(where(a), where(b)) +=
                        l.segment<P>(Eigen::Index(a) * P) *
                        l.segment<P>(Eigen::Index(b) * P).transpose();
            if (sets == 2) {
                Eigen::VectorXd& c = scratch.cross;
                c.setZero(Eigen::Index(u.slotCount) * P);
                const std::vector<Jacobian>& ja = scratch.jacobians[0];
                const std::vector<Jacobian>& jb = scratch.jacobians[1];
                for (std::uint32_t a = 0; a < u.slotCount; ++a) {
                    addPackedGradient<P>(c.segment<P>(Eigen::Index(a) * P), 0.5, ja[a], r[1]);
                    addPackedGradient<P>(c.segment<P>(Eigen::Index(a) * P), 0.5, jb[a], r[0]);
                    for (std::uint32_t b = 0; b < u.slotCount; ++b) {
                        addPackedGram<P>(sum.crossGram.block<P, P>(where(a), where(b)), 0.5, ja[a],
                                         jb[b]);
                        addPackedGram<P>(sum.crossGram.block<P, P>(where(a), where(b)), 0.5, jb[a],
                                         ja[b]);
                    }
                }
                for (std::uint32_t a = 0; a < u.slotCount; ++a)
                    for (std::uint32_t b = 0; b < u.slotCount; ++b)
                        sum.crossScores.block<P, P>(where(a), where(b)) +=
                            c.segment<P>(Eigen::Index(a) * P) *
                            c.segment<P>(Eigen::Index(b) * P).transpose();
            }
            if (!moments) return;
            pixelMoment<P>(at, &scratch.jacobians, instruments, sets, i, u, scratch.moment,
                           &scratch.momentJacobian);
            for (std::uint32_t a = 0; a < u.slotCount; ++a)
                for (std::uint32_t b = 0; b < u.slotCount; ++b)
                    sum.jacobian.block<P, P>(where(a), where(b)) +=
                        scratch.momentJacobian.template block<P, P>(Eigen::Index(a) * P,
                                                                    Eigen::Index(b) * P);
        });
    if (moments)
        result.scores = scores(objective, at, instruments, result.jacobian, params.heldFlags());
    return result;
}

template Analysis analyse<kRgbBlock>(Objective<kRgbBlock>&, const ParameterState<kRgbBlock>&,
                                     const Instruments<kRgbBlock>*, Linearization<kRgbBlock>&);
template Analysis analyse<kGreyBlock>(Objective<kGreyBlock>&, const ParameterState<kGreyBlock>&,
                                      const Instruments<kGreyBlock>*, Linearization<kGreyBlock>&);

}  // namespace phongfit
