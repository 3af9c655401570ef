// The standard errors the observed image's own noise gives the estimate, from a model of that
// noise: in each pixel, kappa times the covariance over channels of one of the fitter's paths
// there (replayPathCovariance), kappa from the cross products of the two recordings' residuals
// (their expectation is the image's variance: the recordings' noise is independent of each other
// and of the image's). The sandwich takes a pixel's noise from its own residual, one draw: where
// one pixel holds a parameter (a highlight smaller than a pixel) it cannot see that pixel's noise
// (docs/design/fitter.md, "A parameter held by one noisy pixel"). The model is an image rendered
// with independent samples; stratified ones (Sobol points) shrink some pixels' variance far more
// than others': wide at the Cornell box's highlight, narrow at a point-lit sphere's, whose smooth
// pixels Sobol points render almost without noise. There the pixels that hold a parameter are
// rendered anew as the image was (FitOptions::renderedNoise).
#pragma once

#include <vector>

#include "fitter.h"
#include "objective.h"
#include "parameter_state.h"

namespace phongfit {

// What kappa is read from, in one pixel that sees a material: r_A . r_B, |r_A - r_B|^2 / 4 (the
// two recordings' residuals, over channels) and the variance of one of its paths (the trace of
// their covariance).
struct PixelNoise {
    double cross = 0, halfDifference = 0, variance = 0;
};

// The most the recordings' own noise may be, as the median over the pixels of |r_A - r_B|^2 / 4
// over their paths' variance (divided by 0.455 as below), for the paths' variance to be taken as
// what it is made of: 1 / (2 N) for N paths a pixel, 1/8 at the fewest (4). In the Cornell box the
// recordings vary 4-20x more (light no recorded term carries).
inline constexpr double kModelledRecordingNoise = 0.25;

// kappa, over the pixels whose paths vary at least as much as the median pixel's, as the larger of
// two readings, each a median over 0.455 (the median of a chi-square with one degree of freedom
// over its mean):
// - the median of r_A . r_B / variance. A ratio of sums would be the ratio at the few pixels whose
//   paths vary most (a sub-pixel highlight's, whose noise kappa is for); a mean of ratios is ruled
//   by pixels whose noise no recorded path carries (a silhouette's background, an image's
//   fireflies). Biased low where the recordings' noise is not small against the image's: the
//   product of two residuals whose shared part is small has its median near 0, not at its mean.
// - where the recordings' noise is what the paths' variance says (kModelledRecordingNoise): the
//   median of |r_A + r_B|^2 / 4 / variance (the image's noise and half the recordings') less that
//   of |r_A - r_B|^2 / 4 / variance (half the recordings'; independent of the first for recordings
//   alike), at its lower 2-standard-error end, so that a difference within its noise adds nothing.
// On a point-lit sphere rendered with 256 independent samples a pixel (kappa 1/256 = 0.0039) the
// first reads 0.0020-0.0028 in the last rounds, the second 0.0042-0.0047
// (docs/design/fitter.md, "The residuals split").
double noiseScale(std::vector<PixelNoise> pixels);

// Per block, the natural parameters' standard errors at the flat natural coordinates `y` from the
// image's modelled noise alone (least squares' sandwich over the pixels that see a material); 0
// for `held` ones, where the image shows no noise beyond the model's, and for exact recordings.
// With `rendered`, a pixel that holds a parameter (a share of its information no other pixel can
// check) takes the noise rendered images have there where that is the larger.
template <int P>
std::vector<std::vector<double>> imageNoiseStd(Objective<P>& objective,
                                               const std::vector<double>& y,
                                               const std::vector<HeldParams>& held,
                                               const RenderedNoise& rendered);

// Per material, how far the image's noise reaches on the sharp side of a lobe known to a factor
// 2 or worse (3 of `logNStd`, per material, its standard error of log n): taken 64 times sharper
// than the sharp end of 3 standard errors (the paths replayed there, the pixels holding most of
// n's information rendered there, through the estimate's sensitivities), where a highlight is
// narrower and may be far noisier in the image; if 3 of the standard errors of log n there reach
// back to the estimate, the s whose 3 reach from n to that lobe, or that standard error if larger;
// at least the s whose 3 reach the sharpest such lobe the image does not rule out (its pixels
// holding n rendered there fit it about as well as at the estimate); else 0; empty for exact
// recordings or without `rendered`. docs/design/fitter.md, "A sharper lobe's noisier image", "A
// sharper lobe the image does not rule out".
template <int P>
std::vector<double> sharperLogNStd(Objective<P>& objective, const std::vector<double>& y,
                                   const std::vector<HeldParams>& held,
                                   const RenderedNoise& rendered,
                                   const std::vector<double>& logNStd);

// Adds to `fit`'s variances the image's noise beyond what they counted (n's through log n).
void applyImageNoise(MaterialFit& fit);

}  // namespace phongfit
