#include "analysis.h"

#include <cmath>
#include <span>

#include "standard_errors.h"

namespace phongfit {

template <int P>
void anchorTerm(const PixelJacobians<P>& j, const Eigen::Vector3d (&r)[2], const double (&rho)[2],
                int sets, std::uint32_t slotCount, bool cross, Eigen::VectorXd& term,
                Eigen::MatrixXd* jacobian, double secondSign) {
    const Eigen::Index n = Eigen::Index(slotCount) * P;
    term.setZero(n);
    if (jacobian != nullptr) jacobian->setZero(n, n);
    for (std::uint32_t a = 0; a < slotCount; ++a) {
        auto t = term.segment<P>(Eigen::Index(a) * P);
        for (int k = 0; k < sets; ++k) {
            // Least squares: set k's own Jacobian and residual; cross products: the other's.
            const int other = cross ? 1 - k : k;
            const double w = cross ? 0.5 : rho[k] / sets;
            addPackedGradient<P>(t, k == 1 ? secondSign * w : w, j[k][a], r[other]);
            for (std::uint32_t b = 0; jacobian != nullptr && b < slotCount; ++b)
                addPackedGram<P>(jacobian->block<P, P>(Eigen::Index(a) * P, Eigen::Index(b) * P), w,
                                 j[k][a], j[other][b]);
        }
    }
}

template <int P>
Analysis analyse(Objective<P>& objective, const ParameterState<P>& params,
                 const Instruments<P>* instruments, Linearization<P>& at) {
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
            Eigen::Vector3d r[2];
            double rho[2] = {1, 1};
            for (int k = 0; k < sets; ++k) {
                r[k] = objective.residual(k, u, y.data(), scratch, true);
                rho[k] = objective.lossWeight(r[k].squaredNorm());
                at.residuals[k][i] = r[k].cast<float>();
                at.weights[k][i] = float(rho[k]);
                mean += r[k] / sets;
            }
            if (!u.seesMaterial) return;
            sum.squares += mean.squaredNorm() / std::pow(objective.weight(u), 2);
            // Each anchor's term and its Jacobian, into its scores and gram.
            const auto add = [&](bool cross, Eigen::MatrixXd& scores, Eigen::MatrixXd& gram) {
                anchorTerm<P>(scratch.jacobians, r, rho, sets, u.slotCount, cross, scratch.moment,
                              &scratch.momentJacobian);
                const Eigen::VectorXd& l = scratch.moment;
                for (std::uint32_t a = 0; a < u.slotCount; ++a)
                    for (std::uint32_t b = 0; b < u.slotCount; ++b) {
                        gram.block<P, P>(where(a), where(b)) +=
                            scratch.momentJacobian.template block<P, P>(Eigen::Index(a) * P,
                                                                        Eigen::Index(b) * P);
                        scores.block<P, P>(where(a), where(b)) +=
                            l.segment<P>(Eigen::Index(a) * P) *
                            l.segment<P>(Eigen::Index(b) * P).transpose();
                    }
            };
            add(false, sum.leastSquaresScores, sum.gram);
            if (sets == 2) add(true, sum.crossScores, sum.crossGram);
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

template void anchorTerm<kRgbBlock>(const PixelJacobians<kRgbBlock>&, const Eigen::Vector3d (&)[2],
                                    const double (&)[2], int, std::uint32_t, bool, Eigen::VectorXd&,
                                    Eigen::MatrixXd*, double);
template void anchorTerm<kGreyBlock>(const PixelJacobians<kGreyBlock>&,
                                     const Eigen::Vector3d (&)[2], const double (&)[2], int,
                                     std::uint32_t, bool, Eigen::VectorXd&, Eigen::MatrixXd*,
                                     double);
template Analysis analyse<kRgbBlock>(Objective<kRgbBlock>&, const ParameterState<kRgbBlock>&,
                                     const Instruments<kRgbBlock>*, Linearization<kRgbBlock>&);
template Analysis analyse<kGreyBlock>(Objective<kGreyBlock>&, const ParameterState<kGreyBlock>&,
                                      const Instruments<kGreyBlock>*, Linearization<kGreyBlock>&);

}  // namespace phongfit
