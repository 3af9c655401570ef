// The instrumental-variables moment equations g(y) = 0 (fitter.h) as one Ceres residual block.
//
// g and its Jacobian dg/dy come from a callback in natural coordinates y (kd, ks, log n per slot;
// material_params.h), summed over all pixels. The residual is L^-1 g over the natural coordinates
// that are not held, with L L^T = sum Z^T W Z, the instruments' Gram matrix (two-stage least
// squares weighting): there are as many equations as free parameters, so the minimum, 0, is the
// root whatever the weighting, which only shapes the path to it; where no root lies in the box,
// this weighting makes the objective the least-squares one when the instruments are the model's
// own Jacobian. The Jacobian is L^-1 dg/dy dy/dx, per parameter block.
#pragma once

#include <ceres/cost_function.h>

#include <Eigen/Core>
#include <cstdint>
#include <functional>
#include <span>
#include <utility>
#include <vector>

#include "evaluation_cache.h"
#include "material_params.h"

namespace phongfit {

template <int P>
class MomentResidual final : public ceres::CostFunction {
public:
    // Fills g (and, when `jacobian` is not null, dg/dy) at y, P natural coordinates per slot; y is
    // set for the slots of the parameter blocks only.
    using Moments =
        std::function<void(const double* y, Eigen::VectorXd& g, Eigen::MatrixXd* jacobian)>;

    // `slots`: the slot of each parameter block, in order. `held` is indexed by slot and must
    // outlive the residual. `free`: the moment equations kept, as natural indices slot * P + i.
    // `whitening` is L^-1, square of free.size().
    MomentResidual(Moments moments, std::vector<std::uint32_t> slots,
                   std::span<const HeldParams> held, std::vector<int> free,
                   Eigen::MatrixXd whitening)
        : moments_(std::move(moments)),
          slots_(std::move(slots)),
          held_(held),
          free_(std::move(free)),
          whitening_(std::move(whitening)) {
        set_num_residuals(int(free_.size()));
        mutable_parameter_block_sizes()->assign(slots_.size(), P);
    }

    bool Evaluate(double const* const* parameters, double* residuals,
                  double** jacobians) const override {
        const MomentsAt& at = momentsAt(naturalFromBlocks<P>(parameters, slots_, held_));
        const Eigen::Index rows = Eigen::Index(free_.size());
        Eigen::Map<Eigen::VectorXd>(residuals, rows) = whitening_ * at.g(free_);
        if (!wantsJacobian(jacobians, slots_.size())) return true;
        const Eigen::MatrixXd whitened = whitening_ * at.dg(free_, Eigen::all);
        for (std::size_t b = 0; b < slots_.size(); ++b) {
            if (jacobians[b] == nullptr) continue;
            const Eigen::Matrix<double, P, P> d =
                naturalJacobian<P>(parameters[b], held_[slots_[b]]);
            Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, P, Eigen::RowMajor>> jacobian(
                jacobians[b], rows, P);
            jacobian = whitened.middleCols<P>(Eigen::Index(slots_[b]) * P) * d;
        }
        return true;
    }

private:
    struct MomentsAt {
        Eigen::VectorXd g;
        Eigen::MatrixXd dg;
    };

    // g and dg/dy at y, summed once a point (evaluation_cache.h).
    const MomentsAt& momentsAt(const std::vector<double>& y) const {
        if (const MomentsAt* found = evaluated_.find(y)) return *found;
        MomentsAt at;
        moments_(y.data(), at.g, &at.dg);
        return evaluated_.store(y, std::move(at));
    }

    Moments moments_;
    std::vector<std::uint32_t> slots_;
    std::span<const HeldParams> held_;
    std::vector<int> free_;
    Eigen::MatrixXd whitening_;
    mutable EvaluationCache<MomentsAt> evaluated_;
};

}  // namespace phongfit
