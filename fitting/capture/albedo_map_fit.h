// A capture fitted with a diffuse albedo per pixel and one specular lobe shared by the object
// (`fit --capture --albedo per-pixel`): textured objects, where one kd cannot explain the images.
//
//     I(p, l) = cos(theta_i) * (kd_p / pi + ks (n + 2) / (2 pi) cos(alpha)^n)
//
// Given n, the model is linear in kd_p and ks, and each kd_p touches only its own pixel's pairs:
// kd_p is eliminated in closed form (variable projection), ks is solved from the reduced normal
// equations, and the residual is minimised over log n alone (grid, then golden section). kd_p >= 0
// and ks >= 0 are kept by an active set. No energy bound is imposed: kd and ks are in the units of
// the images divided by the light intensities, which are often relative. Standard errors of ks
// and n are the larger of the Gauss-Newton ones with every kd_p eliminated (Schur complement, so
// they include what the unknown albedo map costs) and the sandwich clustered by light (each light
// misfitting in its own way, as on real captures). With K materials each has its own lobe, fitted
// on its own pixels. The per-pixel Lambertian fit (kd_p alone, the photometric-stereo baseline) is
// solved on the same pairs. Design notes: docs/design/captures.md.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "capture.h"
#include "capture_fit.h"

namespace phongfit {

struct AlbedoMapOptions {
    bool grey = false;  // one ks for all channels
    // A pixel with fewer usable pairs is left out: its albedo would absorb its pairs entirely.
    int minPairs = 3;
    // Lobes: 1 shared by the object, or K for K materials found by clustering the albedo map of
    // one shared lobe (material_clusters.h).
    int materials = 1;
    int threads = 0;  // 0 = all hardware threads
};

// One material's specular lobe, shared by its pixels.
struct LobeFit {
    Color3 ks = Color3::Zero(), ksStd = Color3::Zero();
    double n = 0, nStd = 0;
    // Parameters the images do not constrain: "n" when no channel's ks is 3 standard errors above
    // zero (no lobe: the images say nothing about its exponent).
    std::vector<std::string> unconstrained;
    bool nAtBound = false;   // the residual's minimum lies at the end of the searched range of n
    std::size_t pixels = 0;  // fitted pixels of the material
    int evaluations = 0;     // residual evaluations of the search over n
};

struct AlbedoMapFit {
    // Per mask pixel (Capture::pixels); zero where not fitted.
    std::vector<Color3> kd, kdStd, lambertianKd;
    std::vector<std::uint8_t> fitted;    // 1 where the pixel had at least minPairs pairs
    std::vector<std::uint8_t> material;  // index into lobes
    std::vector<LobeFit> lobes;
    std::size_t pixelsFitted = 0, pixelsTooFewPairs = 0;
    std::size_t pairs = 0;                // pairs of the fitted pixels
    double minN = 0, maxN = 0;            // the searched range of n
    double rmse = 0, lambertianRmse = 0;  // on the fitted pairs, per channel value
    // Fitted pixels with kd + ks > 1 in some channel by more than 3 of kd's standard errors; more
    // than 1% of the fitted pixels is beyond chance: the images are brighter than the intensities
    // allow an energy-conserving material to be.
    std::size_t kdAboveOne = 0;
    bool energyBoundExceeded = false;
    double seconds = 0;

    bool converged() const;  // every lobe's exponent constrained
};

// Fits the pairs of `model` (of `capture`). Throws Error if no pixel has minPairs pairs, or a
// material has none, or materials is not in 1..kMaxMaterials.
inline constexpr int kMaxMaterials = 16;
AlbedoMapFit fitAlbedoMap(const Capture& capture, const CaptureModel& model,
                          const AlbedoMapOptions& options);

// The fit's prediction of a pair of pixel `pixel` (a mask pixel index) from its path term.
Color3 predictAlbedoMap(const AlbedoMapFit& fit, std::uint32_t pixel, double cosine, double logCos);

struct AlbedoMapCaptureFit {
    CaptureModel model;  // of the fitted lights
    AlbedoMapFit fit;
    // With held-out lights: their model and the predictions of the fit and of its baseline.
    std::optional<CaptureModel> heldOut;
    std::optional<HoldoutPrediction> holdout;
};

// fitAlbedoMap on the pairs of `images`, predicting `heldOutImages` if there are any. Throws Error
// if no pair of the fitted (or of the held-out) lights can be used.
AlbedoMapCaptureFit fitCaptureAlbedoMap(const Capture& capture,
                                        const std::vector<CaptureImage>& images,
                                        const std::vector<CaptureImage>& heldOutImages,
                                        double minCos, const AlbedoMapOptions& options);

// Held-out lights predicted by the per-pixel Phong fit and the per-pixel Lambertian baseline, on
// the pairs of fitted pixels.
HoldoutPrediction predictCapture(const CaptureModel& model, const AlbedoMapFit& fit);

}  // namespace phongfit
