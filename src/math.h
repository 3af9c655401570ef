// Small vector types and the local shading frame. Everything BRDF-related works in the local frame:
// normal on +z, cosTheta(w) = w.z. Frame is the one place that converts to and from world space.
#pragma once

#include <Eigen/Core>
#include <cmath>
#include <numbers>
#include <type_traits>

namespace phongfit {

template <typename T>
using Vec3 = Eigen::Matrix<T, 3, 1>;
template <typename T>
using Vec2 = Eigen::Matrix<T, 2, 1>;
// RGB values (reflectances, radiance). An Array, so products are per channel.
template <typename T>
using Color = Eigen::Array<T, 3, 1>;

using Vec3d = Vec3<double>;
using Vec3f = Vec3<float>;
using Vec2d = Vec2<double>;
using Color3 = Color<double>;

inline constexpr double kPi = std::numbers::pi;
inline constexpr double kInvPi = std::numbers::inv_pi;

// Below this, exp is exactly 0 in S: e^-104 < 2^-150 (float), e^-746 < 2^-1075 (double).
template <typename S>
constexpr S expIsZeroBelow() {
    static_assert(std::is_same_v<S, float> || std::is_same_v<S, double>);
    return std::is_same_v<S, float> ? S(-104) : S(-746);
}

// exp(x), bit for bit, without calling exp where it is exactly 0: glibc's underflow path sets
// errno, and a sharp lobe's fit spent a tenth of its time there. A Jet's derivatives are
// 0 * x.v, as ceres::exp's, signs of zero included.
template <typename T>
T expOrZero(const T& x) {
    using std::exp;
    if constexpr (std::is_floating_point_v<T>) {
        return x < expIsZeroBelow<T>() ? T(0) : exp(x);
    } else {
        using S = decltype(x.a);
        return x.a < expIsZeroBelow<S>() ? T(S(0), S(0) * x.v) : exp(x);
    }
}

template <typename T>
T cosTheta(const Vec3<T>& w) {
    return w.z();
}

// Mirror of w about the normal (+z) in the local frame.
template <typename T>
Vec3<T> reflectLocal(const Vec3<T>& w) {
    return Vec3<T>(-w.x(), -w.y(), w.z());
}

// Orthonormal basis {s, t, n} around a unit normal (Duff et al. 2017, branchless).
template <typename T>
struct Frame {
    Vec3<T> s, t, n;

    Frame() : s(1, 0, 0), t(0, 1, 0), n(0, 0, 1) {}
    explicit Frame(const Vec3<T>& normal) : n(normal) {
        const T sign = std::copysign(T(1), n.z());
        const T a = T(-1) / (sign + n.z());
        const T b = n.x() * n.y() * a;
        s = Vec3<T>(T(1) + sign * n.x() * n.x() * a, sign * b, -sign * n.x());
        t = Vec3<T>(b, sign + n.y() * n.y() * a, -n.y());
    }

    Vec3<T> toLocal(const Vec3<T>& w) const { return Vec3<T>(w.dot(s), w.dot(t), w.dot(n)); }
    Vec3<T> toWorld(const Vec3<T>& w) const { return s * w.x() + t * w.y() + n * w.z(); }
};

}  // namespace phongfit
