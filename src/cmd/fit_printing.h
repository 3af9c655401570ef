// What `fit` and `demo` print of a scene fit: the progress line per round and the result lines.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "filters_from_edges.h"
#include "fitter.h"
#include "scene_fit.h"

namespace phongfit {

// Before the fit: a warning per view whose pixel filter is phongfit's default (the film names no
// <rfilter>, and no sidecar says what the image was rendered with), where Mitsuba's differs.
void printSceneWarnings(const SceneFitProblem& problem);

// The views whose film names no filter and whose image's edges showed another (edgeFilters'
// `filters`): the fit runs again with it.
void printEdgeFilters(const SceneFitProblem& problem, const FitResult& result,
                      const std::vector<std::optional<PixelFilter>>& filters);

// The views whose edges, in the fit that named `named` (its `checks`), fit the `alike` filters as
// well: the fit runs with those too.
void printAlikeFilters(const SceneFitProblem& problem, const std::vector<EdgeCheck>& checks,
                       const std::vector<std::optional<PixelFilter>>& named,
                       const std::vector<std::optional<PixelFilter>>& alike);

// The views whose edges could not tell phongfit's box from the `untold` filters (untoldFilters).
void printUntoldFilters(const SceneFitProblem& problem,
                        const std::vector<std::optional<PixelFilter>>& untold);

// Of the fits with edgeFilters' (`named`) and alikeFilters' (`alike`) filters, which was kept,
// and how far each estimate, rendered anew, is from the images.
void printFilterChoice(const SceneFitProblem& problem,
                       const std::vector<std::optional<PixelFilter>>& named,
                       const std::vector<std::optional<PixelFilter>>& alike,
                       const ImageResiduals& residuals);

// One line per round on stderr, naming the materials: rmse, iterations, time, memory, values.
void printRound(const FitRound& round, const SceneFitProblem& problem, bool fitExposure);

// What a material's result line says of the parameters it lists unconstrained: those held, and
// an n no lobe holds (which keeps its standard error); empty when none is.
std::string unconstrainedNote(const MaterialFit& m);

// Per material kd, ks, n with standard errors (and what is unconstrained), the exposure if
// fitted, then the rmse, rounds, convergence, time, what was left out and where fit.json is.
void printSceneFit(const SceneFitProblem& problem, const FitResult& result, bool grey,
                   const std::string& dir);

}  // namespace phongfit
