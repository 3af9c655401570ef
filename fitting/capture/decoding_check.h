// Does the photographs' decoding look right? A pixel's value under directional light follows the
// model, kd_p n.l / pi plus the lobe, only when decoded with the right curve: a linear capture read
// as sRGB bends every pixel's response to n.l. The check fits the per-pixel albedo model
// (albedo_map_fit.h) to the two readings of the same integer codes, linear and sRGB, on a subset of
// pixels: a capture decoded as sRGB by default whose codes are in fact linear (DiLiGenT's 8-bit
// crops) is caught before its kd is believed.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "capture.h"
#include "capture_fit.h"

namespace phongfit {

struct DecodingCheck {
    Encoding used = Encoding::Linear, other = Encoding::Srgb;
    // The fraction of pixels whose values read the other way the per-pixel albedo model fits
    // better (smaller residual relative to the values).
    double otherBetterFraction = 0;
    // The other reading explains the images markedly better: the decoding is likely wrong.
    bool otherFitsBetter = false;
};

// The check, on the pairs of `model` (built from `images`), or nothing if the photographs are not
// integer-coded with the linear or sRGB curve (float data, a chosen gamma).
std::optional<DecodingCheck> checkDecoding(const Capture& capture, const CaptureModel& model,
                                           const std::vector<CaptureImage>& images, int threads);

// "linear" or "sRGB".
std::string curveName(Encoding curve);

}  // namespace phongfit
