// Warps from the unit square to directions, each with its density (per unit solid angle). Lobes
// around an axis are written in terms of h = 1 - cos(alpha), which keeps full precision for the
// very narrow lobes of n up to 1e6, where cos(alpha) itself rounds to 1.
#pragma once

#include <cmath>

#include "math.h"

namespace phongfit {

template <typename T>
Vec3<T> sphericalDirection(T sinTheta, T cosTheta, T phi) {
    return Vec3<T>(sinTheta * std::cos(phi), sinTheta * std::sin(phi), cosTheta);
}

// sin(alpha) from h = 1 - cos(alpha), without cancellation.
template <typename T>
T sinFromOneMinusCos(T h) {
    return std::sqrt(std::max(T(0), h * (T(2) - h)));
}

template <typename T>
Vec3<T> squareToCosineHemisphere(const Vec2<T>& u) {
    const T r = std::sqrt(u.x());
    return sphericalDirection(r, std::sqrt(std::max(T(0), T(1) - u.x())), T(2 * kPi) * u.y());
}

template <typename T>
T cosineHemispherePdf(const Vec3<T>& w) {
    return w.z() > T(0) ? w.z() * T(kInvPi) : T(0);
}

template <typename T>
Vec3<T> squareToUniformHemisphere(const Vec2<T>& u) {
    const T z = T(1) - u.x();  // in (0, 1]: never exactly on the horizon
    return sphericalDirection(std::sqrt(std::max(T(0), T(1) - z * z)), z, T(2 * kPi) * u.y());
}

template <typename T>
T uniformHemispherePdf(const Vec3<T>& w) {
    return w.z() > T(0) ? T(0.5 * kInvPi) : T(0);
}

// The normalized Phong lobe (n + 1) / (2 pi) cos^n(alpha) around +z: cos(alpha) = u^(1 / (n + 1))
// (Lawrence), i.e. h = -expm1(log(u) / (n + 1)). Uses 1 - u.x in (0, 1] so log is finite.
template <typename T>
Vec3<T> squareToPhongLobe(const Vec2<T>& u, T n) {
    const T h = -std::expm1(std::log(T(1) - u.x()) / (n + T(1)));
    return sphericalDirection(sinFromOneMinusCos(h), T(1) - h, T(2 * kPi) * u.y());
}

// Density of squareToPhongLobe at a direction with 1 - cos(alpha) = h (0 beyond 90 degrees).
template <typename T>
T phongLobePdf(T h, T n) {
    if (!(h < T(1))) return T(0);
    return (n + T(1)) * T(0.5 * kInvPi) * expOrZero(n * std::log1p(-h));
}

// 1 - cos(theta_max) of the cap that holds the Phong lobe down to eps of its peak:
// cos(theta_max) = eps^(1 / (n + 1)).
template <typename T>
T phongCapHeight(T n, T eps = T(1e-10)) {
    return -std::expm1(std::log(eps) / (n + T(1)));
}

// Uniform over the spherical cap around +z with 1 - cos(alpha) <= hMax.
template <typename T>
Vec3<T> squareToUniformCap(const Vec2<T>& u, T hMax) {
    const T h = u.x() * hMax;
    return sphericalDirection(sinFromOneMinusCos(h), T(1) - h, T(2 * kPi) * u.y());
}

template <typename T>
T uniformCapPdf(T h, T hMax) {
    return h <= hMax ? T(1) / (T(2 * kPi) * hMax) : T(0);
}

}  // namespace phongfit
