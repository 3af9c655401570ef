#include "exposure_block.h"

#include <fmt/format.h>

#include <algorithm>

#include "error.h"

namespace phongfit {

PhongMaterial ExposureBlock::asMaterial(double s) {
    PhongMaterial m;
    m.n = s * kExposureCentre;
    return m;
}

HeldParams ExposureBlock::startHeld() {
    HeldParams held;
    held.kd.fill(true);
    held.ks.fill(true);
    return held;
}

double ExposureBlock::matched(double current, double predicted, double product) {
    if (!(predicted > 0) || !(product > 0))
        throw Error(
            fmt::format("--fit-exposure: the {} where a fitted material is seen (nothing to scale)",
                        predicted > 0 ? "images are black" : "start materials render black"));
    const double s = current * product / predicted;
    if (!(s >= kMinExposure && s <= kMaxExposure))
        throw Error(fmt::format(
            "--fit-exposure: the images are {:.3g} times as bright as the scene renders them "
            "at the start (allowed: {:.3g} to {:.3g}; scale the emitters)",
            s, kMinExposure, kMaxExposure));
    return s;
}

double ExposureBlock::heldValue(double start, double current, double highestReflectance) {
    return std::max(start, current * highestReflectance);
}

}  // namespace phongfit
