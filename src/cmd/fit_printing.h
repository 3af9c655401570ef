// What `fit` and `demo` print of a scene fit: the progress line per round and the result lines.
#pragma once

#include <optional>
#include <string>
#include <vector>

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
