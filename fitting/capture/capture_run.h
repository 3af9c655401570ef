// Fitting Phong to a photometric-stereo capture (capture.h, capture_fit.h): the pipeline behind
// `fit --capture`, in typed steps: read and fit, then write fit.json and compare.png.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "albedo_map_fit.h"
#include "capture.h"
#include "capture_fit.h"
#include "decoding_check.h"
#include "fitter.h"

namespace phongfit {

struct CaptureFitInputs {
    std::string dir;
    // 1-based light lists such as "1-10,20" (parseLightList); empty lights: all not held out.
    std::string lights, holdout;
    CaptureReadOptions read;
    CaptureFitOptions fit;
    bool perPixelAlbedo = false;  // --albedo per-pixel: albedo_map_fit.h instead of one kd
    int materials = 1;            // with perPixelAlbedo: AlbedoMapOptions::materials
    // "calibrated", "relative" (CaptureFitOptions::relativeIntensities), or "auto": relative when
    // every light has the same intensity (a capture whose file says only 1 1 1).
    std::string intensities = "auto";
};

struct CaptureRun {
    Capture capture;
    std::vector<int> lights, holdout;  // indices into capture.lights
    std::vector<CaptureImage> images, heldOutImages;
    // How the light intensities were taken, as fit.json and the console say it.
    std::string intensities;
    std::optional<DecodingCheck> decodingCheck;  // of the fitted lights' photographs
    // One of the two: one material (fitCapture) or an albedo map (fitCaptureAlbedoMap).
    std::optional<CaptureFit> fit;
    std::optional<AlbedoMapCaptureFit> albedoMap;
};

// Reads and checks the capture and its images, then fits (fitCapture or fitCaptureAlbedoMap).
// Throws Error on bad input.
CaptureRun runCaptureFit(const CaptureFitInputs& inputs, bool quiet);

// DIR/fit.json and DIR/compare.png (a typical held-out light, or the middle fitted one), and with
// an albedo map DIR/kd.exr (linear, 0 outside the fitted pixels), DIR/kd.png (a preview) and with
// several materials DIR/materials.png; DIR is created. `loss` is the loss' name as fit.json records
// it.
void writeCaptureFit(const CaptureRun& run, const CaptureFitInputs& inputs, const std::string& loss,
                     const std::string& dir);

}  // namespace phongfit
