// A material whose kd and ks are the same in every channel, for tests of the parameters' blocks.
#pragma once

#include "phong_brdf.h"

namespace phongfit::test {

inline PhongMaterial greyMaterial(double kd, double ks, double n) {
    PhongMaterial m;
    m.kd = Color3::Constant(kd);
    m.ks = Color3::Constant(ks);
    m.n = n;
    return m;
}

}  // namespace phongfit::test
