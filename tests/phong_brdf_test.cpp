#include "phong_brdf.h"

#include <gtest/gtest.h>

namespace phongfit {
namespace {

TEST(PhongBrdf, EvaluateTableAtNormalIncidence) {
    const Vec3d w(0, 0, 1);
    PhongMaterial m;
    m.n = 10;
    m.kd = Color3::Constant(0.5);
    m.ks = Color3::Constant(0.5);
    const Color3 f = phongEval(m, w, w);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(f[c], 7 / (2 * kPi), 1e-6);
}

}  // namespace
}  // namespace phongfit
