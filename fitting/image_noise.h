// The standard errors the observed image's own noise gives the estimate, from a model of that
// noise: in each pixel, kappa times the variance of one of the fitter's paths there
// (replayPathVariance), kappa from the cross products of the two recordings' residuals (their
// expectation is the image's variance: the recordings' noise is independent of each other and of
// the image's). The sandwich takes a pixel's noise from its own residual, one draw: where one
// pixel holds a parameter (a highlight smaller than a pixel) it cannot see that pixel's noise
// (docs/design/fitter.md, "A parameter held by one noisy pixel"). The model is an image rendered
// with independent samples; stratified ones (Sobol points) shrink some pixels' variance far more
// than others', and there it errs on the wide side.
#pragma once

#include <vector>

#include "fitter.h"
#include "objective.h"
#include "parameter_state.h"

namespace phongfit {

// Per block, the natural parameters' standard errors at the flat natural coordinates `y` from the
// image's modelled noise alone (least squares' sandwich over the pixels that see a material); 0
// for `held` ones, where the image shows no noise beyond the model's, and for exact recordings.
template <int P>
std::vector<std::vector<double>> imageNoiseStd(Objective<P>& objective,
                                               const std::vector<double>& y,
                                               const std::vector<HeldParams>& held);

// Raises `fit`'s standard errors to its image-noise ones (n's through log n).
void applyImageNoise(MaterialFit& fit);

}  // namespace phongfit
