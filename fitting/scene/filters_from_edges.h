// A film that names no pixel filter is fitted as phongfit's box; where the image's edges show
// another filter, the fit runs again with it, and where they fit two kinds alike, with each,
// keeping the one whose estimate renders closer to the images (docs/design/fitter.md, "Kinds of
// one spread").
#pragma once

#include <optional>
#include <vector>

#include "fitter.h"
#include "scene_fit.h"

namespace phongfit {

// Per view, the filter its image's edges fit far better (FitResult::edgeChecks) where its film
// names none and no sidecar says which made the image (filterAssumed), for
// SceneFitInputs::edgeFilters; empty where no view has one. A fit of a Mitsuba image whose scene
// leaves the filter to the renderer's default (Mitsuba's Gaussian, phongfit's box) is then run
// again with the image's.
std::vector<std::optional<PixelFilter>> edgeFilters(const SceneFitProblem& problem,
                                                    const FitResult& result);

// edgeFilters', with a filter of another kind where the edges fit it as well
// (EdgeCheck::alikeFilter); empty where no view has one. Of one spread, a tent and a Gaussian
// differ at the edges of a small image by less than its noise, but where a highlight varies
// inside by more: the fits with each tell them (imageResiduals).
std::vector<std::optional<PixelFilter>> alikeFilters(const SceneFitProblem& problem,
                                                     const FitResult& result);

// Per view, Mitsuba's default filter (a Gaussian of stddev 0.5) where the film names none, no
// sidecar says which made the image, and the edges fit no filter better than phongfit's box: they
// cannot tell the two apart (a Cornell box's silhouette against its walls), while the fit can be
// swayed by them (a tent image of it at 96x96 fitted as a box: kd 0.354 +- 0.0045 for 0.334).
// Empty where no view is such. The fit runs again with it, and the one that renders closer is
// kept, both held (holdBothFilters).
std::vector<std::optional<PixelFilter>> untoldFilters(const SceneFitProblem& problem,
                                                      const FitResult& result);

// Paths a pixel of each of the two renders of a fit's estimate that imageResiduals compares, and
// the rows of film rendered at a time.
inline constexpr int kResidualSpp = 128;
inline constexpr int kResidualRows = 32;

// The rms difference between the images and each fit's estimate rendered anew, over every view's
// pixels that both fits use inside the silhouettes by the wider filter's reach: the mean product of
// a pixel's differences from two independent renders, whose noise is then out of it (kResidualSpp
// paths a pixel each), and not the fits' own rmse, which holds their recordings' noise, less where
// a fit spent more paths. The second holds the images better where its mean product is below the
// first's by kResidualEvidence standard errors of their difference (over the pixels' channels, as
// independent).
inline constexpr double kResidualEvidence = 3;
struct ImageResiduals {
    double first = 0, second = 0;
    bool firstBetter = false, secondBetter = false;
};
ImageResiduals imageResiduals(const SceneFitProblem& first, const FitResult& firstFit,
                              const SceneFitProblem& second, const FitResult& secondFit,
                              const SceneRecording& recording);

// The images' edges give a filter's spread, not its shape or exact width, and the two filters
// fitted need not include the image's (Tungsten's tent, sampled as one of radius 1.08, lies between
// a tent of radius 1 and a Gaussian of stddev 0.5): the standard errors of `kept` are raised to
// hold `other`'s estimate too, and a fit that had converged is not where the two differ by more
// than its standard errors ("pixel filter unresolved").
void holdBothFilters(FitResult& kept, const FitResult& other);

}  // namespace phongfit
