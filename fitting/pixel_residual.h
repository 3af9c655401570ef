// The residual of one pixel: weight * (I_p(theta) - observed), RGB, over the parameter blocks of
// the material slots the pixel's recorded vertices touch (usually one).
//
// Derivatives are forward-mode Jets through the same replay and BRDF code as the prediction, packed
// by channel: every term of I_p is a per-channel product, so channel c of the prediction depends on
// kd_c, ks_c and n only. Seeding kd_c in Jet component 0 and ks_c in component 1 for every channel,
// and log n in component 2, gives in channel c of the result d/d(kd_c, ks_c, log n) with 3-wide
// Jets instead of 7-wide ones (the replay is where the time goes). A pixel that touches k slots is
// replayed once per slot with only that slot seeded. The chain rule to Ceres' coordinates is then a
// 3 x P by P x P product per pixel.
#pragma once

#include <ceres/cost_function.h>
#include <ceres/jet.h>

#include <cstdint>
#include <span>
#include <vector>

#include "material_params.h"
#include "replay.h"

namespace phongfit {

using PackedJet = ceres::Jet<double, 3>;

// Channel-packed Jets of a material given by its natural coordinates y (see above).
template <int P>
PhongParams<PackedJet> packedParams(const double* y) {
    using L = BlockLayout<P>;
    PhongParams<PackedJet> m;
    for (int c = 0; c < 3; ++c) {
        m.kd[c] = PackedJet(y[L::diffuse(L::group(c))], 0);
        m.ks[c] = PackedJet(y[L::specular(L::group(c))], 1);
    }
    m.n = exp(PackedJet(y[L::kLogN], 2));
    return m;
}

template <typename T>
PhongParams<T> constantParams(const PhongMaterial& m) {
    PhongParams<T> p;
    for (int c = 0; c < 3; ++c) {
        p.kd[c] = T(m.kd[c]);
        p.ks[c] = T(m.ks[c]);
    }
    p.n = T(m.n);
    return p;
}

// The pixel's prediction and its derivatives with respect to the natural coordinates (kd, ks,
// log n; see material_params.h) of slot `seeded`. `y` holds P natural coordinates per slot and is
// read for the slots in `slots`; `theta` is scratch with one entry per slot.
template <int P>
Color3 replayNaturalJacobian(const PathSet& paths, std::uint32_t pixel,
                             std::span<const std::uint32_t> slots, const double* y,
                             std::uint32_t seeded, std::vector<PhongParams<PackedJet>>& theta,
                             Eigen::Matrix<double, 3, P>& jacobian) {
    using L = BlockLayout<P>;
    for (std::uint32_t s : slots) {
        const double* ys = y + std::size_t(s) * P;
        theta[s] =
            s == seeded ? packedParams<P>(ys) : constantParams<PackedJet>(naturalToPhong<P>(ys));
    }
    const Color<PackedJet> predicted = replayPixel(paths, pixel, theta.data());
    jacobian.setZero();
    Color3 value;
    for (int c = 0; c < 3; ++c) {
        value[c] = predicted[c].a;
        jacobian(c, L::diffuse(L::group(c))) = predicted[c].v[0];
        jacobian(c, L::specular(L::group(c))) = predicted[c].v[1];
        jacobian(c, L::kLogN) = predicted[c].v[2];
    }
    return value;
}

template <int P>
class PixelResidual final : public ceres::CostFunction {
public:
    // `paths` and `held` must outlive the residual; `slots` lists the slots the pixel's vertices
    // use, one parameter block each, in that order; `held` is indexed by slot.
    PixelResidual(const PathSet& paths, std::uint32_t pixel, const Color3& observed, double weight,
                  std::span<const std::uint32_t> slots, std::span<const HeldParams> held)
        : paths_(paths),
          pixel_(pixel),
          observed_(observed),
          weight_(weight),
          slots_(slots),
          held_(held) {
        set_num_residuals(3);
        mutable_parameter_block_sizes()->assign(slots.size(), P);
    }

    bool Evaluate(double const* const* parameters, double* residuals,
                  double** jacobians) const override {
        // Natural coordinates, P per slot (only the pixel's slots are filled).
        std::vector<double> y(held_.size() * P);
        for (std::size_t k = 0; k < slots_.size(); ++k)
            toNatural<P>(parameters[k], held_[slots_[k]], y.data() + std::size_t(slots_[k]) * P);
        bool written = false;
        if (jacobians != nullptr) {
            std::vector<PhongParams<PackedJet>> theta(held_.size());
            Eigen::Matrix<double, 3, P> natural;
            for (std::size_t b = 0; b < slots_.size(); ++b) {
                if (jacobians[b] == nullptr) continue;
                const Color3 predicted = replayNaturalJacobian<P>(paths_, pixel_, slots_, y.data(),
                                                                  slots_[b], theta, natural);
                writeResiduals(predicted, residuals);
                const Eigen::Matrix<double, P, P> d =
                    naturalJacobian<P>(parameters[b], held_[slots_[b]]);
                Eigen::Map<Eigen::Matrix<double, 3, P, Eigen::RowMajor>> jacobian(jacobians[b]);
                jacobian = weight_ * natural * d;
                written = true;
            }
        }
        if (!written) {
            std::vector<PhongMaterial> theta(held_.size());
            for (std::uint32_t s : slots_)
                theta[s] = naturalToPhong<P>(y.data() + std::size_t(s) * P);
            writeResiduals(replayPixel(paths_, pixel_, theta.data()), residuals);
        }
        return true;
    }

private:
    void writeResiduals(const Color3& predicted, double* residuals) const {
        for (int c = 0; c < 3; ++c) residuals[c] = weight_ * (predicted[c] - observed_[c]);
    }

    const PathSet& paths_;
    std::uint32_t pixel_;
    Color3 observed_;
    double weight_;
    std::span<const std::uint32_t> slots_;
    std::span<const HeldParams> held_;
};

}  // namespace phongfit
