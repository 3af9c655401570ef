// How a fitted material is laid out as a Ceres parameter block (internal coordinates x) and how
// that maps to its natural parameters y = (kd, ks, log n).
//
// Per colour group g (3 groups in RGB mode; 1 in grey mode, where kd and ks are shared by the
// channels):
//
//     x[g]      = u_g   in [0, 1]   kd_g = u_g * (1 - ks_g): the diffuse share of what ks leaves
//     x[G + g]  = ks_g  in [0, 1]
//     x[2G]     = log n in [log 1e-3, log 1e6]
//
// Every point of this box satisfies kd, ks >= 0 and kd + ks <= 1, so keeping the solver's steps in
// the box (box_manifold.h) enforces energy conservation exactly, and kd + ks = 1 (u = 1) and
// ks = 0 are bounds a solution can sit on. Holding ks (or n) at a value is holding one coordinate
// constant, which is what the fitter does when the images do not constrain it. The map is singular
// only at ks = 1, where kd = 0 whatever u is. n works in log n because it spans six decades; n = 0
// (cos^0 = 1: a clipped, diffuse-like lobe) is not representable, but the lobe at n = 1e-3 differs
// from it by less than 1% wherever cos alpha > 1e-3, which images cannot tell apart.
//
// When kd is held (a colour group no pixel constrains), x[g] is kd itself, held constant, and ks is
// bounded by 1 - kd.
#pragma once

#include <ceres/jet.h>

#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <span>
#include <vector>

#include "phong_brdf.h"

namespace phongfit {

inline constexpr int kRgbBlock = 7;
inline constexpr int kGreyBlock = 3;
inline constexpr double kMinExponent = 1e-3;
inline constexpr double kMaxExponent = 1e6;

template <int P>
struct BlockLayout {
    static_assert(P == kRgbBlock || P == kGreyBlock, "a block is RGB (7) or grey (3)");
    static constexpr int kGroups = (P - 1) / 2;
    static constexpr int diffuse(int g) { return g; }
    static constexpr int specular(int g) { return kGroups + g; }
    static constexpr int kLogN = 2 * kGroups;
    static constexpr int group(int channel) { return kGroups == 3 ? channel : 0; }
};

// Natural parameters of one material that the fit holds at their start values because the images
// do not constrain them. Indexed by colour group.
struct HeldParams {
    std::array<bool, 3> kd{}, ks{};
    bool n = false;
};

// y = (kd per group, ks per group, log n) from the internal coordinates x.
template <int P, typename T>
void toNatural(const T* x, const HeldParams& held, T* y) {
    using L = BlockLayout<P>;
    for (int g = 0; g < L::kGroups; ++g) {
        const T& ks = x[L::specular(g)];
        y[L::diffuse(g)] = held.kd[g] ? x[L::diffuse(g)] : x[L::diffuse(g)] * (T(1) - ks);
        y[L::specular(g)] = ks;
    }
    y[L::kLogN] = x[L::kLogN];
}

template <int P, typename T>
PhongParams<T> naturalToPhong(const T* y) {
    using L = BlockLayout<P>;
    using std::exp;
    PhongParams<T> m;
    for (int c = 0; c < 3; ++c) {
        m.kd[c] = y[L::diffuse(L::group(c))];
        m.ks[c] = y[L::specular(L::group(c))];
    }
    m.n = exp(y[L::kLogN]);
    return m;
}

template <int P, typename T>
PhongParams<T> toPhong(const T* x, const HeldParams& held) {
    T y[P];
    toNatural<P>(x, held, y);
    return naturalToPhong<P>(y);
}

// Natural coordinates of a material; in grey mode kd and ks are the means over the channels.
template <int P>
Eigen::Matrix<double, P, 1> naturalFromPhong(const PhongMaterial& m) {
    using L = BlockLayout<P>;
    Eigen::Matrix<double, P, 1> y;
    for (int g = 0; g < L::kGroups; ++g) {
        y[L::diffuse(g)] = L::kGroups == 3 ? m.kd[g] : m.kd.mean();
        y[L::specular(g)] = L::kGroups == 3 ? m.ks[g] : m.ks.mean();
    }
    y[L::kLogN] = std::log(std::clamp(m.n, kMinExponent, kMaxExponent));
    return y;
}

// Internal coordinates from natural ones, clamped into the box.
template <int P>
void toInternal(const double* y, const HeldParams& held, double* x) {
    using L = BlockLayout<P>;
    for (int g = 0; g < L::kGroups; ++g) {
        const double kd = std::clamp(y[L::diffuse(g)], 0.0, 1.0);
        if (held.kd[g]) {
            x[L::diffuse(g)] = kd;
            x[L::specular(g)] = std::clamp(y[L::specular(g)], 0.0, 1.0 - kd);
        } else {
            const double ks = std::clamp(y[L::specular(g)], 0.0, 1.0);
            x[L::specular(g)] = ks;
            // At ks = 1 any u gives kd = 0; the middle keeps u off its bounds for when ks drops.
            x[L::diffuse(g)] = ks < 1 ? std::clamp(kd / (1 - ks), 0.0, 1.0) : 0.5;
        }
    }
    x[L::kLogN] = std::clamp(y[L::kLogN], std::log(kMinExponent), std::log(kMaxExponent));
}

template <int P>
void internalBounds(const HeldParams& held, const double* x, double* lower, double* upper) {
    using L = BlockLayout<P>;
    for (int g = 0; g < L::kGroups; ++g) {
        lower[L::diffuse(g)] = 0;
        upper[L::diffuse(g)] = 1;
        lower[L::specular(g)] = 0;
        upper[L::specular(g)] = held.kd[g] ? 1 - x[L::diffuse(g)] : 1;
    }
    lower[L::kLogN] = std::log(kMinExponent);
    upper[L::kLogN] = std::log(kMaxExponent);
}

// Internal coordinates Ceres must keep constant.
template <int P>
std::vector<int> heldCoordinates(const HeldParams& held) {
    using L = BlockLayout<P>;
    std::vector<int> constant;
    for (int g = 0; g < L::kGroups; ++g)
        if (held.kd[g]) constant.push_back(L::diffuse(g));
    for (int g = 0; g < L::kGroups; ++g)
        if (held.ks[g]) constant.push_back(L::specular(g));
    if (held.n) constant.push_back(L::kLogN);
    return constant;
}

// The natural coordinates of Ceres' parameter blocks, P per slot (0 for slots without a block);
// `slots` gives each block's slot, `held` is indexed by slot.
template <int P>
std::vector<double> naturalFromBlocks(double const* const* parameters,
                                      const std::vector<std::uint32_t>& slots,
                                      std::span<const HeldParams> held) {
    std::vector<double> y(held.size() * P, 0.0);
    for (std::size_t b = 0; b < slots.size(); ++b)
        toNatural<P>(parameters[b], held[slots[b]], y.data() + std::size_t(slots[b]) * P);
    return y;
}

// Whether Ceres asks for the Jacobian of any of `blocks` parameter blocks.
inline bool wantsJacobian(double** jacobians, std::size_t blocks) {
    for (std::size_t b = 0; jacobians != nullptr && b < blocks; ++b)
        if (jacobians[b] != nullptr) return true;
    return false;
}

// dy/dx at x, for the delta method (natural covariance = D C_x D^T).
template <int P>
Eigen::Matrix<double, P, P> naturalJacobian(const double* x, const HeldParams& held) {
    using Jet = ceres::Jet<double, P>;
    Jet xj[P], yj[P];
    for (int i = 0; i < P; ++i) xj[i] = Jet(x[i], i);
    toNatural<P>(xj, held, yj);
    Eigen::Matrix<double, P, P> d;
    for (int i = 0; i < P; ++i) d.row(i) = yj[i].v.transpose();
    return d;
}

}  // namespace phongfit
