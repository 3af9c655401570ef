// A pixel's replayed prediction I_p and its derivatives with respect to the natural coordinates of
// a material slot.
//
// Derivatives are forward-mode Jets through the same replay and BRDF code as the prediction, packed
// by channel: every term of I_p is a per-channel product, so channel c of the prediction depends on
// kd_c, ks_c and n only. Seeding kd_c in Jet component 0 and ks_c in component 1 for every channel,
// and log n in component 2, gives in channel c of the result d/d(kd_c, ks_c, log n) with 3-wide
// Jets instead of 7-wide ones (the replay is where the time goes). A pixel that touches k slots is
// replayed once per slot with only that slot seeded; the seeded slot's one-vertex terms (most of
// them) are summed apart and their derivatives taken once a pixel (SeededOneVertexSums).
#pragma once

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

// The seeded slot's one-vertex terms summed apart: per channel the sums of their constants k, of
// k cos^n and of k cos^n log cos, which give the terms' values and derivatives at once (d/dkd_c
// = sum k / pi, d/dks_c = the lobe's scale times sum k cos^n, d/dlog n = ks_c n (sum k cos^n /
// 2 pi + scale sum k cos^n log cos)). Three sums a channel where the Jets took four products
// (`BM_ReplayJet*`); the same values as the term-by-term replay to rounding.
struct SeededOneVertexSums {
    Color3 constant = Color3::Zero(), power = Color3::Zero(), powerLogCos = Color3::Zero();

    void add(double n, float logCos, const Color<float>& k) {
        const double p = phongPower(n, logCos);
        for (int c = 0; c < 3; ++c) constant[c] += double(k[c]);
        if (p == 0) return;
        const double pl = p * double(logCos);
        for (int c = 0; c < 3; ++c) {
            power[c] += p * double(k[c]);
            powerLogCos[c] += pl * double(k[c]);
        }
    }

    // sum += the terms' f times k at the seeded Jets `p`.
    void addTo(Color<PackedJet>& sum, const PhongParams<PackedJet>& p) const {
        const double n = p.n.a, scale = (n + 2.0) * (0.5 * kInvPi);
        for (int c = 0; c < 3; ++c) {
            const double lobe = scale * power[c];
            sum[c].a += p.kd[c].a * kInvPi * constant[c] + p.ks[c].a * lobe;
            sum[c].v[0] += kInvPi * constant[c];
            sum[c].v[1] += lobe;
            sum[c].v[2] += p.ks[c].a * n * (0.5 * kInvPi * power[c] + scale * powerLogCos[c]);
        }
    }
};

// replayPixel with the Jets of packedParams at slot `seeded` and constants elsewhere.
inline Color<PackedJet> replaySeededPixel(const PathSet& paths, std::size_t pixel,
                                          const PhongParams<PackedJet>* theta,
                                          std::uint32_t seeded) {
    SeededOneVertexSums seededSums;
    const double n = theta[seeded].n.a;
    Color<PackedJet> sum =
        replayTerms(paths, pixel, theta,
                    [theta, seeded, n, &seededSums](Color<PackedJet>& sum, const PathVertex& v,
                                                    const Color<float>& k) {
                        if (v.slot == seeded)
                            seededSums.add(n, v.logCos, k);
                        else
                            addOneVertexTerm(sum, theta[v.slot], v.logCos, k);
                    });
    seededSums.addTo(sum, theta[seeded]);
    return sum;
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
    const Color<PackedJet> predicted = replaySeededPixel(paths, pixel, theta.data(), seeded);
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

// A Jacobian shaped as replayNaturalJacobian leaves it, kept in the 9 entries that can be non-zero,
// as floats: row c holds d/d(kd and ks of c's colour group, log n). The fitter keeps one per pixel
// slot and set twice (at the last analysis, and as instruments): 36 bytes instead of 24 P.
using StoredJacobian = Eigen::Matrix<float, 3, 3>;

template <int P>
StoredJacobian storeJacobian(const Eigen::Matrix<double, 3, P>& j) {
    using L = BlockLayout<P>;
    StoredJacobian s;
    for (int c = 0; c < 3; ++c) {
        s(c, 0) = float(j(c, L::diffuse(L::group(c))));
        s(c, 1) = float(j(c, L::specular(L::group(c))));
        s(c, 2) = float(j(c, L::kLogN));
    }
    return s;
}

template <int P>
Eigen::Matrix<double, 3, P> loadJacobian(const StoredJacobian& s) {
    using L = BlockLayout<P>;
    Eigen::Matrix<double, 3, P> j = Eigen::Matrix<double, 3, P>::Zero();
    for (int c = 0; c < 3; ++c) {
        j(c, L::diffuse(L::group(c))) = s(c, 0);
        j(c, L::specular(L::group(c))) = s(c, 1);
        j(c, L::kLogN) = s(c, 2);
    }
    return j;
}

// out += w a^T b for two Jacobians shaped as replayNaturalJacobian leaves them: row c is 0 but for
// kd and ks of c's colour group and log n. 27 products instead of 3 P^2; the fitter's sums over
// millions of pixels are made of these.
template <int P, typename Out>
void addPackedGram(Out&& out, double w, const Eigen::Matrix<double, 3, P>& a,
                   const Eigen::Matrix<double, 3, P>& b) {
    using L = BlockLayout<P>;
    for (int c = 0; c < 3; ++c) {
        const int columns[3] = {L::diffuse(L::group(c)), L::specular(L::group(c)), L::kLogN};
        for (int i : columns) {
            const double wa = w * a(c, i);
            for (int k : columns) out(i, k) += wa * b(c, k);
        }
    }
}

// out += w a^T r, with a shaped as in addPackedGram.
template <int P, typename Out>
void addPackedGradient(Out&& out, double w, const Eigen::Matrix<double, 3, P>& a,
                       const Eigen::Vector3d& r) {
    using L = BlockLayout<P>;
    for (int c = 0; c < 3; ++c) {
        const double wr = w * r[c];
        out[L::diffuse(L::group(c))] += wr * a(c, L::diffuse(L::group(c)));
        out[L::specular(L::group(c))] += wr * a(c, L::specular(L::group(c)));
        out[L::kLogN] += wr * a(c, L::kLogN);
    }
}

}  // namespace phongfit
