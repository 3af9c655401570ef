// What `phongfit render` writes beside an image (IMAGE.json) and a fit reads back: how the image
// was rendered. The fit models a pixel's noise on the image's spp and samplers, and refuses an
// image whose pixel filter or depth its scene misstates: fitted as rendered with another filter or
// depth, the image gives a confident wrong lobe (docs/design/fitter.md, "A scene that misstates
// its image").
#pragma once

#include <nlohmann/json.hpp>
#include <string>

#include "pixel_sampler.h"
#include "scene.h"

namespace phongfit {

// How an image was rendered, where no pixel but its own shows a pixel's noise
// (FitOptions::renderedNoise): the scene's sampler and sampleCount, or what `phongfit render`
// wrote beside the image (spp, pixel_sampler, sampler, mis).
struct RenderedAs {
    int spp = 0;  // 0: an image without noise
    PixelSamplerType pixelSampler = PixelSamplerType::Sobol;
    std::string sampler = "mixture";
    bool mis = true;
    std::string source;  // "scene" or the sidecar's path
    // The sidecar names the pixel filter (then the scene's, checked): the image's filter is known.
    bool filterKnown = false;
};

// The film's pixel filter as the sidecar writes it: {"type": "box"}, {"type": "gaussian",
// "stddev": pixels} or {"type": "tent", "radius": pixels}.
nlohmann::json pixelFilterJson(const PixelFilter& filter);

// The settings of the image at `imagePath` from its sidecar IMAGE.json where there is one, else
// the scene's sampler and sampleCount. `scene` is the view's scene, `maxDepth` its depth in
// Mitsuba's count (-1 unbounded) and `directExact` whether direct light alone is exact in it (then
// every depth from 2 renders the same image). Throws Error where the sidecar is malformed, or
// says the image was rendered with another pixel filter or to another depth than the scene's.
RenderedAs readRenderedAs(const std::string& imagePath, const Scene& scene, int maxDepth,
                          bool directExact);

// The image's filter is only phongfit's default: the film names none, and no sidecar says which
// filter made the image (Mitsuba 0.6's default differs).
bool filterAssumed(const SensorDesc& film, const RenderedAs& as);

// What fit.json says of a view's pixel filter: pixelFilterJson's, and "from": "scene", the
// sidecar's path, or "default" where the film names none and no sidecar says which it was.
nlohmann::json pixelFilterReport(const SensorDesc& film, const RenderedAs& as);

}  // namespace phongfit
