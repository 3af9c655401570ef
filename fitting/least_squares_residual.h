// Least squares over all pixels, sum over p of |r_p(y)|^2, as one small Ceres residual block.
//
// A residual block per pixel hands Ceres a Jacobian with a row per pixel and channel (4.2 million
// rows for a 96-light capture) that it stores, scales and factorizes at every step, plus a virtual
// call and the bookkeeping per pixel: on such a capture the solver, not the replay, was the cost.
// Gauss-Newton, dogleg and Levenberg-Marquardt see the residuals only through the cost |r|^2 / 2,
// the gradient J^T r and the Gauss-Newton matrix J^T J, so any residual with the same three at
// the point gives the same steps. With J^T J = V D V^T over the free natural coordinates, the
// block's residual is (D^-1/2 V^T J^T r, sqrt(|r|^2 - |D^-1/2 V^T J^T r|^2)) and its Jacobian
// (D^1/2 V^T; 0): F + 1 entries for F free coordinates, whatever the number of pixels, computed by
// the callback as parallel sums. (That Jacobian is not the derivative of that residual: the basis
// V moves with the point. Ceres never differentiates a residual itself, so only the three sums
// matter; the gradient checker does not apply here, see the tests.) Evaluated without Jacobians,
// at the trial points of a step, the block is (|r|, 0, ..., 0).
#pragma once

#include <ceres/cost_function.h>

#include <Eigen/Core>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>
#include <span>
#include <utility>
#include <vector>

#include "evaluation_cache.h"
#include "material_params.h"

namespace phongfit {

template <int P>
class LeastSquaresResidual final : public ceres::CostFunction {
public:
    // Fills the sum of squared residuals and, when `gradient` is not null, J^T r and J^T J (into
    // `gramian`) over the natural coordinates y (P per slot; y is set for the slots of the
    // parameter blocks only).
    using Sums = std::function<void(const double* y, double& squares, Eigen::VectorXd* gradient,
                                    Eigen::MatrixXd* gramian)>;

    // `slots`: the slot of each parameter block, in order. `held` is indexed by slot and must
    // outlive the residual. `free`: the natural coordinates that are not held, slot * P + i.
    LeastSquaresResidual(Sums sums, std::vector<std::uint32_t> slots,
                         std::span<const HeldParams> held, std::vector<int> free)
        : sums_(std::move(sums)), slots_(std::move(slots)), held_(held), free_(std::move(free)) {
        set_num_residuals(int(free_.size()) + 1);
        mutable_parameter_block_sizes()->assign(slots_.size(), P);
    }

    bool Evaluate(double const* const* parameters, double* residuals,
                  double** jacobians) const override {
        const SumsAt& at = sumsAt(naturalFromBlocks<P>(parameters, slots_, held_));
        const Eigen::Index f = Eigen::Index(free_.size());
        Eigen::Map<Eigen::VectorXd> out(residuals, f + 1);
        const double squares = at.squares;
        if (!wantsJacobian(jacobians, slots_.size())) {
            out.setZero();
            out[f] = std::sqrt(std::max(squares, 0.0));
            return std::isfinite(squares);
        }
        const Eigen::VectorXd& gradient = at.gradient;
        const Eigen::MatrixXd& gramian = at.gramian;
        const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eigen(gramian(free_, free_));
        const Eigen::VectorXd& d = eigen.eigenvalues();
        // Directions the data do not see (D ~ 0) carry no gradient either: leave them out.
        const double floor =
            std::max(d.maxCoeff(), 0.0) * double(f) * std::numeric_limits<double>::epsilon();
        Eigen::MatrixXd natural = Eigen::MatrixXd::Zero(f + 1, Eigen::Index(held_.size()) * P);
        const Eigen::VectorXd projected = eigen.eigenvectors().transpose() * gradient(free_);
        double explained = 0;
        for (Eigen::Index k = 0; k < f; ++k) {
            out[k] = 0;
            if (!(d[k] > floor)) continue;
            const double root = std::sqrt(d[k]);
            out[k] = projected[k] / root;
            explained += out[k] * out[k];
            for (Eigen::Index i = 0; i < f; ++i)
                natural(k, free_[std::size_t(i)]) = root * eigen.eigenvectors()(i, k);
        }
        out[f] = std::sqrt(std::max(squares - explained, 0.0));
        for (std::size_t b = 0; b < slots_.size(); ++b) {
            if (jacobians[b] == nullptr) continue;
            Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, P, Eigen::RowMajor>> jacobian(
                jacobians[b], f + 1, P);
            jacobian = natural.middleCols<P>(Eigen::Index(slots_[b]) * P) *
                       naturalJacobian<P>(parameters[b], held_[slots_[b]]);
        }
        return std::isfinite(squares) && out.allFinite();
    }

private:
    struct SumsAt {
        double squares = 0;
        Eigen::VectorXd gradient;
        Eigen::MatrixXd gramian;
    };

    // The sums at y, gradient and Gauss-Newton matrix included, summed once a point
    // (evaluation_cache.h).
    const SumsAt& sumsAt(const std::vector<double>& y) const {
        if (const SumsAt* found = evaluated_.find(y)) return *found;
        SumsAt at;
        sums_(y.data(), at.squares, &at.gradient, &at.gramian);
        return evaluated_.store(y, std::move(at));
    }

    Sums sums_;
    std::vector<std::uint32_t> slots_;
    std::span<const HeldParams> held_;
    std::vector<int> free_;
    mutable EvaluationCache<SumsAt> evaluated_;
};

}  // namespace phongfit
