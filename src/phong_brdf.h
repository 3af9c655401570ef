// The Modified Phong BRDF (Lafortune & Willems 1994), the one definition shared by the renderer and
// the fitter:
//
//     f(wi, wo) = kd / pi + ks * (n + 2) / (2 pi) * cos^n(alpha)
//
// Conventions (as pbrt-v4 and the Phong importance-sampling note): local shading frame, normal on
// +z; `wo` is given (towards the viewer), `wi` is sampled (towards the light), both point away from
// the surface; f excludes the foreshortening cos(theta_i); alpha is the angle between wi and the
// mirror direction of wo, and cos(alpha) is clamped at 0.
//
// Templated on the parameter type T (float, double, ceres::Jet) and the direction type D (float,
// double), so the fitter differentiates exactly the model the renderer samples.
#pragma once

#include <cmath>
#include <limits>
#include <string>
#include <type_traits>

#include "math.h"

namespace phongfit {

template <typename T>
struct PhongParams {
    Color<T> kd = Color<T>::Zero();
    Color<T> ks = Color<T>::Zero();
    T n = T(0);
};
using PhongMaterial = PhongParams<double>;

// How far kd + ks may exceed 1: the rounding of values written to 6 significant digits (printf's
// %g: 0.942818 + 0.0571824 = 1.0000004), 1e-6 at most, twice that clear of the sum's own.
constexpr double kEnergySumSlack = 2e-6;

// Throws Error naming `what` (e.g. "bsdf 'ball' (scene.xml:12)") when a parameter is outside its
// domain: kd, ks >= 0, kd + ks <= 1 (+ kEnergySumSlack) per channel, n >= 0, all finite.
void validatePhong(const PhongMaterial& m, const std::string& what);

// h = 1 - cos(alpha) = |r - wi|^2 / 2 with r the mirror of wo: precise for tiny alpha, where
// 1 - dot(r, wi) loses every digit.
template <typename D>
D oneMinusCosAlpha(const Vec3<D>& wi, const Vec3<D>& wo) {
    return (reflectLocal(wo) - wi).squaredNorm() / D(2);
}

// log(cos alpha), the only geometric quantity the lobe needs; -infinity where cos(alpha) <= 0.
template <typename D>
D logCosAlpha(const Vec3<D>& wi, const Vec3<D>& wo) {
    const D h = oneMinusCosAlpha(wi, wo);
    return h < D(1) ? std::log1p(-h) : -std::numeric_limits<D>::infinity();
}

// Below this n log(cos alpha) the lobe is taken as 0: cos^n(alpha) < 4.3e-18, below double
// precision next to the lobe's peak (1 at alpha = 0). A sharp lobe's replay spent 40-53% of its
// exp calls on such terms (docs/design/fitter.md, "The lobe's tail").
inline constexpr double kLobeTail = -40;

// cos^n(alpha) = exp(n log cos alpha), 0 below kLobeTail: finite with finite derivatives for n in
// [0, 1e6] and any alpha (ceres::pow has non-finite derivatives at a zero base).
template <typename T, typename D>
T phongPower(const T& n, D logCos) {
    using std::exp;
    if (logCos == -std::numeric_limits<D>::infinity()) return T(0);
    const T x = n * T(logCos);
    return x < T(kLobeTail) ? T(0) : exp(x);
}

// f from log(cos alpha); the form the fitter replays recorded vertices with.
// Where the lobe is exactly 0 (most of a sharp lobe's recorded vertices) its arithmetic is skipped:
// it could only add zeros, so f is the same to the last bit, derivatives included.
template <typename T, typename D>
Color<T> phongEvalLogCos(const PhongParams<T>& p, D logCos) {
    const T power = phongPower(p.n, logCos);
    const Color<T> diffuse = p.kd * T(kInvPi);
    if (power == T(0)) return diffuse;
    const T specular = (p.n + T(2)) * T(0.5 * kInvPi) * power;
    return diffuse + p.ks * specular;
}

// f(wi, wo); 0 when either direction is on or below the horizon.
template <typename T, typename D>
Color<T> phongEval(const PhongParams<T>& p, const Vec3<D>& wi, const Vec3<D>& wo) {
    if (!(cosTheta(wi) > D(0)) || !(cosTheta(wo) > D(0))) return Color<T>::Constant(T(0));
    // A purely diffuse material (most of a scene) needs no lobe. Only for plain numbers: a Jet's
    // derivative with respect to ks is the lobe even where ks = 0.
    if constexpr (std::is_floating_point_v<T>) {
        if ((p.ks == T(0)).all()) return p.kd * T(kInvPi);
    }
    return phongEvalLogCos(p, logCosAlpha(wi, wo));
}

}  // namespace phongfit
