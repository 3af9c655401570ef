// Fitting Phong to a photometric-stereo capture (capture.h, capture_fit.h): the pipeline behind
// `fit --capture`, in typed steps: read and fit, then write fit.json and compare.png.
#pragma once

#include <string>
#include <vector>

#include "capture.h"
#include "capture_fit.h"
#include "fitter.h"

namespace phongfit {

struct CaptureFitInputs {
    std::string dir;
    // 1-based light lists such as "1-10,20" (parseLightList); empty lights: all not held out.
    std::string lights, holdout;
    CaptureReadOptions read;
    CaptureFitOptions fit;
};

struct CaptureRun {
    Capture capture;
    std::vector<int> lights, holdout;  // indices into capture.lights
    std::vector<CaptureImage> images, heldOutImages;
    CaptureFit fit;
};

// Reads and checks the capture and its images, then fits (fitCapture). Throws Error on bad input.
CaptureRun runCaptureFit(const CaptureFitInputs& inputs, bool quiet);

// DIR/fit.json and DIR/compare.png (a typical held-out light, or the middle fitted one); DIR is
// created. `loss` is the loss' name as fit.json records it.
void writeCaptureFit(const CaptureRun& run, const CaptureFitInputs& inputs, const std::string& loss,
                     const std::string& dir);

}  // namespace phongfit
