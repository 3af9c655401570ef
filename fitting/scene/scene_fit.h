// Fitting phong materials of a scene to images of it: the pipeline that `fit --view`, `demo` and
// `bench fit` share, in three typed steps (read and check everything, fit, write the outputs), so
// a caller times or skips each on its own. Nothing here parses command-line text.
#pragma once

#include <cstddef>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "fitter.h"
#include "image.h"
#include "render_sidecar.h"
#include "renderer.h"

namespace phongfit {

struct SceneFitInputs {
    struct View {
        std::string scenePath, imagePath;
    };
    std::vector<View> views;                     // fitted jointly
    std::vector<std::string> materials;          // ids of phong bsdfs, one slot each, in order
    std::map<std::string, std::string> defines;  // the scenes' `default` overrides
    std::string maskPath;  // empty: none; else a PNG sized as the first view's film
    ReadOptions decoding;
    std::optional<double> saturation;  // pixels with a channel at or above it are left out
    bool ignoreNonFinite = false;      // leave NaN/Inf pixels out instead of failing
    // Keep the pixels that see the fitted materials only through other surfaces (left out by
    // default where every fitted material is seen directly: loadSceneFit). A fit of the images'
    // exposure keeps them: every pixel a light reaches constrains it.
    bool keepIndirect = false;
    // Start values replacing the first view's scene values, for every material.
    std::optional<Color3> kd, ks;
    std::optional<double> n;
    // Per view, or empty: the pixel filter a film that names none takes instead of phongfit's box,
    // where a fit found the image's edges to show it (edgeFilters).
    std::vector<std::optional<PixelFilter>> edgeFilters;
};

// One view, read and checked.
struct SceneView {
    std::string scenePath, imagePath;
    std::unique_ptr<Renderer> renderer;
    std::vector<int> fittedBsdfs;  // per slot
    int maxDepth = -2;             // what is recorded (RecordOptions::maxDepth)
    std::string depthNote;         // what the pipeline left out, in words
    // Delta lights seen directly: no recorded direction depends on the estimate
    // (FitOptions::recordingFollowsEstimate).
    bool deltaLightsOnly = false;
    // Point and directional lights only, whatever else the scene holds
    // (FitOptions::extendedLights).
    bool deltaLights = false;
    Observation observation;
    // Pixels left out: clipped, masked, not finite, and outside the EXR's data window
    // (Image::noData).
    std::size_t clipped = 0, masked = 0, nonFinite = 0, noData = 0;
    // Per pixel: 1 where the ray through its centre first meets a fitted material
    // (Renderer::bsdfSeen); where RecordOptions::directSpp applies.
    std::vector<std::uint8_t> direct;
    // Per slot: seen directly in a pixel the fit keeps (checked before any is left out below).
    std::vector<bool> slotSeen;
    // Left out: pixels whose footprint is off every fitted material, where the materials are seen
    // directly (loadSceneFit): they see them only through other surfaces, if at all.
    std::size_t offMaterials = 0;
    RenderedAs renderedAs;  // how the image was rendered (render_sidecar.h)
    // The pixels a fitted material's silhouette crosses (edge_agreement.h, edgePixels).
    std::vector<std::uint32_t> edges;
    // The film names no filter, and has the one the image's edges showed
    // (SceneFitInputs::edgeFilters).
    bool filterFromEdges = false;
};

// Where the edges fitted filters of two kinds alike (alikeFilters), the fit not kept: per view its
// filter where it took one from the edges; and the rms differences of both estimates, rendered
// anew, from the images (imageResiduals).
struct OtherFilterFit {
    std::vector<std::optional<PixelFilter>> filters;
    double residual = 0, keptResidual = 0;
};

struct SceneFitProblem {
    std::vector<SceneView> views;
    std::vector<std::string> materials;
    std::map<std::string, std::string> defines;
    std::vector<PhongMaterial> start;  // per slot
    std::optional<OtherFilterFit> otherFilterFit;
};

// How each round records its paths.
struct SceneRecording {
    int spp = 4;
    int directSpp = 0;  // RecordOptions::directSpp
    std::uint64_t seed = 0;
    int threads = 0;
    // After the first round: this many extra paths per pixel that sees a fitted material, on
    // average, shared by the paths' importance to the estimate (path_importance.h), at most
    // kMostExtraPaths in a pixel. 0: spp and directSpp only, as in the first round.
    int adaptiveSpp = 0;
    // Spherical and parallelogram lights near a fitted vertex's mirror direction by rings
    // (RecordOptions::lightRings); false: sampled alone.
    bool lightRings = true;
    // The samples per pixel the observed images were rendered with, in their scenes' samplers:
    // where one pixel holds a parameter its noise is measured on renders like it
    // (FitOptions::renderedNoise). -1: each scene's sampleCount; 0: images without noise.
    int imageSpp = -1;
};

// How many pixels from its own a pixel's value takes samples: the Gaussian's 3 standard
// deviations, the tent's radius, none for a box.
int filterReach(const SensorDesc& film);

// Reads and checks every input. Throws Error naming the file and what is allowed.
SceneFitProblem loadSceneFit(const SceneFitInputs& inputs);

// View `v` rendered as its image was (sampler, MIS, the depth recorded) with its fitted materials
// at `theta` (per slot): the options the fit's own renders of pixels start from.
RenderOptions renderOptionsAt(const SceneView& v, const std::vector<PhongMaterial>& theta,
                              int threads);

// The rounds: records each view at the current estimate and fits (fitMaterials).
FitResult fitScene(const SceneFitProblem& problem, const SceneRecording& recording,
                   const FitOptions& options);

// DIR/fit.json, fitted.xml (fitted_view2.xml, ...) and compare.png (compare_view2.png, ...), the
// views re-rendered at the fitted parameters with `compareSpp` paths per pixel. DIR is created.
void writeSceneFit(const SceneFitProblem& problem, const FitResult& result,
                   const SceneRecording& recording, int compareSpp, const std::string& dir);

}  // namespace phongfit
