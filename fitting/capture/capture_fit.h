// A photometric-stereo capture (capture.h) fitted by the scene fitter, with no path tracer
// (DESIGN.md: a capture needs depth 1 and no indirect bounces). Each (pixel, light) pair is one
// pixel of an exact path set with one term and one vertex:
//
//     I = E * cos(theta_i) * f(wi, wo),   constant = cos(theta_i),   vertex log cos alpha(wi, wo)
//
// in the local frame of the known normal, wo = (0, 0, 1) (orthographic view) and wi the light's
// direction; E = 1 because each image is divided by its light's intensity. The paths are exact (no
// Monte Carlo): least squares on them is unbiased, and the fitter's rounds only confirm that the
// solver converged.
//
// The Lambertian-only comparison (with held-out lights) runs the same fitter on the same pairs with
// every vertex's cos alpha set to 0: the lobe then contributes nothing, the images do not constrain
// ks and n, and the fitter holds them at their start, ks = 0.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "capture.h"
#include "fitter.h"
#include "observation.h"
#include "path_set.h"

namespace phongfit {

// One view per light: the pairs of that light the model can explain.
struct CaptureModel {
    std::vector<int> lights;  // capture light index of each view
    std::vector<Observation> observations;
    std::vector<PathSet> paths;
    std::vector<std::vector<std::uint32_t>> entries;  // per view: the mask pixel of each entry
    std::size_t pairs = 0;                            // mask pixels times lights
    std::size_t used = 0;
    // Pairs left out, by reason: "facing_away" (normal away from the camera), "below_min_cos"
    // (n.l below the threshold: shadowed or grazing light), "clipped", "non_finite".
    std::map<std::string, std::size_t> leftOut;
};

// One view's path set: pair k is pixel k of a one-row image, one term (constant cos theta_i) with
// one vertex (log cos alpha).
PathSet oneTermPerPixel(const std::vector<float>& cosines, const std::vector<float>& logCos);

// Pairs with n.l < minCos are left out, as are clipped and non-finite pixels and normals facing
// away from the camera; a light with no pair left has no view. Throws Error if minCos is not in
// [0, 1).
CaptureModel buildCaptureModel(const Capture& capture, const std::vector<CaptureImage>& images,
                               double minCos);

// buildCaptureModel, or Error if no pair can be used (naming the capture, how many `which` lights,
// "fitted" or "held-out", there were and why their pairs were left out) or if more than
// kMaxNonFiniteFraction of the pairs are not finite.
CaptureModel buildUsableModel(const Capture& capture, const std::vector<CaptureImage>& images,
                              double minCos, const std::string& which);

// The same path sets with the specular lobe removed (cos alpha = 0 at every vertex).
std::vector<PathSet> withoutLobe(const std::vector<PathSet>& paths);

struct PredictionError {
    std::size_t pairs = 0;
    double rmse = 0;     // over pairs and channels, in normalised image units
    double relRmse = 0;  // rmse / RMS of the observed values
};

struct LightPrediction {
    int light = 0;  // capture light index
    PredictionError phong, lambertian;
};

struct HoldoutPrediction {
    PredictionError phong, lambertian;
    std::vector<LightPrediction> perLight;
};

// The best material for a subsample of the pairs, with no bound but kd, ks >= 0. With the lobe:
// kd and ks per channel are non-negative linear least squares at each exponent n; n is the best of
// 1, 2, 4, ..., 2^16, refined by golden-section search. Without the lobe: kd alone, ks = 0. Throws
// Error if the model has no pair.
PhongMaterial scanReflectances(const CaptureModel& model, bool lobe);

// A start for the fit: scanReflectances divided by `scale` (the images' scale the fit runs at),
// then clamped into the energy-conserving range, with ks at least 0.001 so the fitter sees the
// lobe (at ks = 0 the images do not constrain n).
PhongMaterial startScan(const CaptureModel& model, bool lobe, double scale = 1);

// The predicted value of entry `entry` of view `view`, or nothing where the model makes no
// prediction (a pixel it did not fit); such pairs are left out of both errors.
using PairPredictor = std::function<std::optional<Color3>(std::size_t view, std::size_t entry)>;

// The error of predicting every view of `model` with each predictor.
HoldoutPrediction predictCapture(const CaptureModel& model, const PairPredictor& phong,
                                 const PairPredictor& lambertian);

// The error of predicting every view of `model` with each material.
HoldoutPrediction predictCapture(const CaptureModel& model, const PhongMaterial& phong,
                                 const PhongMaterial& lambertian);

struct CaptureFitOptions {
    double minCos = 0.05;
    // The light intensities are known only up to a common factor (and the exposure is unknown):
    // kd and ks are fitted in the images' units, with no energy bound; n is absolute.
    bool relativeIntensities = false;
    FitOptions fit;  // loss, grey, threads, verbose; estimator and rounds are set by fitCapture
};

struct CaptureFit {
    CaptureModel model;  // of the fitted lights
    FitResult phong;
    PhongMaterial start;  // where the Phong fit started: startScan(model, true), in image units
    double scale = 1;     // the images were divided by this for the fit (relative intensities)
    // Calibrated intensities, and the Phong fit ended on kd + ks = 1 in some channel: the images
    // are as bright as an energy-conserving material can be, or brighter (intensities that are
    // in fact relative, a wrong exposure).
    bool energyBoundReached = false;
    // With held-out lights: their model, the Lambertian-only fit and both fits' predictions.
    std::optional<CaptureModel> heldOut;
    std::optional<FitResult> lambertian;
    std::optional<HoldoutPrediction> holdout;
};

// Fits Phong on `images`; if `heldOutImages` is not empty, also fits Lambertian-only on `images`
// and predicts the held-out lights with both. Throws Error if no pair of the fitted (or of the
// held-out) lights can be used.
CaptureFit fitCapture(const Capture& capture, const std::vector<CaptureImage>& images,
                      const std::vector<CaptureImage>& heldOutImages,
                      const CaptureFitOptions& options);

}  // namespace phongfit
