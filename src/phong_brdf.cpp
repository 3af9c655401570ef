#include "phong_brdf.h"

#include <fmt/format.h>

#include "error.h"

namespace phongfit {

void validatePhong(const PhongMaterial& m, const std::string& what) {
    static constexpr char kChannel[3] = {'R', 'G', 'B'};
    for (int c = 0; c < 3; ++c) {
        const double kd = m.kd[c], ks = m.ks[c];
        if (!std::isfinite(kd) || kd < 0)
            throw Error(
                fmt::format("{}: diffuse reflectance kd = {} in channel {} is invalid "
                            "(allowed: finite, >= 0)",
                            what, kd, kChannel[c]));
        if (!std::isfinite(ks) || ks < 0)
            throw Error(
                fmt::format("{}: specular reflectance ks = {} in channel {} is invalid "
                            "(allowed: finite, >= 0)",
                            what, ks, kChannel[c]));
        if (kd + ks > 1 + kEnergySumSlack)
            throw Error(
                fmt::format("{}: kd + ks = {} + {} = {} in channel {} exceeds 1 "
                            "(energy conservation needs kd + ks <= 1 per channel)",
                            what, kd, ks, kd + ks, kChannel[c]));
    }
    if (!std::isfinite(m.n) || m.n < 0)
        throw Error(
            fmt::format("{}: exponent n = {} is invalid (allowed: finite, >= 0)", what, m.n));
}

}  // namespace phongfit
