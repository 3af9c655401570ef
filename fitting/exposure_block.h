// The fitted global exposure s (FitOptions::fitExposure) as the solver carries it.
//
// The sums over pixels, the identifiability test and the standard errors work on flat natural
// coordinates, P per block (material_params.h). The exposure is one more block after the
// materials, laid out like a material's so those sums keep their layout: its kd and ks
// coordinates are held at 0 and its log n coordinate is log(s * kExposureCentre). A block one
// coordinate wide would change the size of every matrix over the flat coordinates, and Eigen's
// products then add their terms in another order (docs/design/fitter.md): the results would no
// longer be bit-identical. What that layout means lives here, and in ParameterState, which holds
// the exposure as a block of its own kind.
#pragma once

#include <cmath>
#include <cstddef>

#include "fitter.h"
#include "material_params.h"
#include "phong_brdf.h"

namespace phongfit {

class ExposureBlock {
public:
    ExposureBlock() = default;  // not fitted
    // Fitted, as block `slot` of the flat coordinates (the one after the materials).
    explicit ExposureBlock(int slot) : slot_(slot) {}

    bool fitted() const { return slot_ >= 0; }
    int slot() const { return slot_; }  // -1 when not fitted

    // s from its coordinate, log(s * kExposureCentre).
    static double fromCoordinate(double coordinate) {
        return std::exp(coordinate) / kExposureCentre;
    }

    // s at flat natural coordinates y (P per block); 1 when it is not fitted.
    template <int P>
    double value(const double* y) const {
        if (slot_ < 0) return 1;
        return fromCoordinate(y[std::size_t(slot_) * P + BlockLayout<P>::kLogN]);
    }

    // The block's start as material_params.h reads it: kd = ks = 0, n = s * kExposureCentre.
    static PhongMaterial asMaterial(double s);
    static double fromMaterial(const PhongMaterial& m) { return m.n / kExposureCentre; }
    // kd and ks held: only the scale is free.
    static HeldParams startHeld();

    // The s that fits the images best with the materials where they are, from the weighted
    // least-squares sums at the current s: `predicted` = <sI, sI>, `product` = <sI, observed>.
    // Least squares in s alone is linear: s <- s <sI, y> / <sI, sI>. Throws Error when the
    // images or the start render black, or s falls outside [kMinExposure, kMaxExposure].
    static double matched(double current, double predicted, double product);

    // Where an exposure the images do not constrain is held: at its start, or higher where the
    // materials, rescaled by current / s to keep s kd and s ks, would otherwise have kd + ks > 1
    // (`highestReflectance`: the largest kd + ks over the materials' colour groups at `current`).
    static double heldValue(double start, double current, double highestReflectance);

private:
    int slot_ = -1;
};

}  // namespace phongfit
