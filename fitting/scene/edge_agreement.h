// Whether an image agrees with its scene where the scene's geometry edges cross pixels, rendered
// anew at the fitted estimate. There a pixel's value is the share of its footprint each side
// covers, weighed by the pixel filter: an image made with another filter, camera or shapes than
// the scene says differs there by tens of percent, whatever the materials, while the fit itself
// may end "converged" on a confidently wrong lobe (docs/design/fitter.md, "A scene that misstates
// its image").
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "fitter.h"
#include "scene_fit.h"

namespace phongfit {

// At most this many edge pixels are rendered anew, evenly spread over the higher-contrast half of
// a view's edges (a filter moves a pixel by its contrast with its neighbours: the sphere against
// the Cornell box's walls is mostly of low contrast).
inline constexpr std::size_t kMostEdgePixels = 64;
// A verdict needs this many edge pixels with light in the image or the render.
inline constexpr std::size_t kLeastEdgePixels = 8;
// The median deviation (image against the render, over their noise, at the edge pixels whose
// centre sees a fitted material, at least kLeastEdgePixels / 2 of them) above which a view's
// image disagrees with its scene: 0.67 where they agree, and the noise modelled is independent
// samples', at least a stratified image's.
inline constexpr double kEdgeDisagreement = 4;
// Differences the noise does not explain but a faithful image may hold (another renderer's
// rounding and light sampling), relative to the pixel's value.
inline constexpr double kEdgeTolerance = 0.02;
// Another pixel filter fits the edges better when its misfit (the sum of squared deviations) is
// below this share of the scene filter's, and below it by kFilterEvidence: as a likelihood ratio,
// 5 standard deviations. A filter's width other than its default is named only when it fits
// better than the default by kFilterEvidence too.
inline constexpr double kFilterPreference = 0.5;
inline constexpr double kFilterEvidence = 25;
// The widths searched, from the default's quotient by this to its product with it; searched
// where another default filter fits better, or the median deviation passes kWidthSearch (0.67
// where image and render agree; at most 0.73 on the recovery matrix and the drawn set). A filter
// is named only where its own median deviation is within kWidthSearch.
inline constexpr double kWidthRange = 4;
inline constexpr double kWidthSearch = 1.5;

// A filter as EdgeCheck::betterFilter is printed: "box", "gaussian stddev 0.5", "tent radius 1.08".
std::string pixelFilterLabel(const PixelFilter& f);

// The pixels of a `width` x `height` film (row-major, Renderer::bsdfSeen's `seen` per pixel)
// whose centre sees another bsdf, or nothing, than a 4-neighbour's, one of the two a `fitted` one.
std::vector<std::uint32_t> edgePixels(const std::vector<int>& seen, int width, int height,
                                      const std::vector<int>& fitted);

// View `v`'s used edge pixels (SceneView::edges), up to kMostEdgePixels, rendered anew at
// `fitted` (per slot) times `exposure` with independent samples, against its image, whose noise is
// modelled as `imageSpp` independent samples (0: none); and rendered so with each other pixel
// filter at its default width, and where one of them fits better (or the median deviation passes
// kWidthSearch), with the widths of each (kWidthRange) to the one that fits best. The image
// disagrees with the scene where its median deviation passes kEdgeDisagreement, or another filter
// fits the edges better (kFilterPreference).
EdgeCheck edgeAgreement(const SceneView& v, const std::vector<PhongMaterial>& fitted,
                        double exposure, int imageSpp, std::uint64_t seed, int threads);

}  // namespace phongfit
