// Before a converged lobe is accepted: one round recorded at a sharper lobe. Paths recorded at an
// exponent n rarely land in a lobe much sharper, so replayed there they cannot tell whether a
// sharper lobe fits the images better; an estimate can settle on the broad side of the truth with
// standard errors that exclude it (a 5-degree light seen in a sphere of n 30000: n 1450 +- 494,
// "converged"). Recorded at the sharper lobe, a round resolves both: it comes back if the
// converged estimate is the minimum, and stays sharp if the images ask for it.
// docs/design/fitter.md, "Sharper lobes than the recordings".
#pragma once

#include <vector>

#include "fitter.h"

namespace phongfit {

// The probe's exponent is this factor (or exp(3 standard errors of log n), if larger) above the
// converged one, at most kMaxExponent.
inline constexpr double kProbeFactor = 4;

// The probe round's least paths relative to the first round's (PathRecorder's pathFactor): it asks
// only where n goes, not for the converged round's precision.
inline constexpr double kProbePaths = 0.5;

// The most paths a second probe round records to tell a roughly resolved lobe's n from its start,
// relative to the first round's; and the margin its standard error of log n is asked to keep below
// probeReturned's.
inline constexpr double kMostProbePaths = 8;
inline constexpr double kProbeMargin = 1.5;

// `at` (where the next round would record: the materials' estimates, a held n as estimateOf
// sends it) with each confirmed lobe's n in `materials` (free, not listed unconstrained, below
// kMaxExponent / kProbeFactor) raised to the probe's; empty when no lobe is to be probed.
std::vector<PhongMaterial> sharperProbe(const std::vector<MaterialFit>& materials,
                                        std::vector<PhongMaterial> at);

// The paths relative to the first round's for a second probe round from the same start, where
// the first, at kProbePaths, could not tell a probed lobe's n from its start (probeTold): as many
// as put its standard error of log n kProbeMargin below what probeReturned asks, predicted from
// the converged round's `converged` at `pathFactor` times the first round's paths (its variance as
// 1 / paths); the most any probed lobe needs. kProbePaths (no second probe) where every lobe needs
// no more, or would need more than kMostProbePaths: the probe cannot vouch for it at a cost below
// the rounds'.
double probePaths(const std::vector<MaterialFit>& converged, double pathFactor);

// The first probe round's paths: kProbePaths, or where it is the fit's `last` round, with no
// second probe after it, probePaths' (a probe at half the paths that could not tell left the
// converged lobe widened to the bound).
double firstProbePaths(const std::vector<MaterialFit>& converged, double pathFactor, bool last);

// Whether each probed lobe came back: the probe round tells the converged n from its own start
// (3 standard errors of log n short of the way between them, and below n) and put its n nearer the
// converged n than the start (in log n), or within 3 of its own standard errors of it; or the
// probe round held n (no lobe seen there).
bool probeReturned(const std::vector<MaterialFit>& converged,
                   const std::vector<MaterialFit>& probe);

// Whether the probe round told each probed lobe's n from its start as probeReturned asks, or held
// it: else it did not come back for want of paths, whatever the images say.
bool probeTold(const std::vector<MaterialFit>& converged, const std::vector<MaterialFit>& probe);

// Whether the probe round came back past a probed lobe's converged n to a broader lobe where no
// probe at kMostProbePaths could tell that lobe from its start (probePaths, from the converged
// round's `pathFactor`): a return of a few paths' pull towards the lobes they reach, as
// widenToProbe takes it, not of the images. Such a probe is recorded again with the converged
// round's paths (docs/design/fitter.md, "A probe pulled broader").
bool pulledBroader(const std::vector<MaterialFit>& converged, const std::vector<MaterialFit>& probe,
                   double pathFactor);

// For a probe that did not come back and no round after it: each probed lobe's n standard error
// in `converged` raised to reach every n the probe did not rule out: its n and 3 of its standard
// errors beyond; at least the start where it cannot tell the converged n from its start (as
// probeReturned) or went past the converged n to a broader lobe; the bound where it told them
// apart and went on sharper than its start.
void widenToProbe(std::vector<MaterialFit>& converged, const std::vector<MaterialFit>& probe);

// Whether some lobe sharperProbe would probe in `materials` was never recorded at
// sqrt(kProbeFactor) times its n or more: `sharpest`, per material, the sharpest n a round recorded
// at. A round recorded that far up whose estimate came down to n is a probe that came back
// (probeReturned: nearer n than its start in log n); a fit that ends without one has not tested its
// lobe's sharper side.
bool sharperSideUntested(const std::vector<MaterialFit>& materials,
                         const std::vector<double>& sharpest);

// Each free lobe in `materials` too near kMaxExponent to be probed (n times kProbeFactor above it):
// no recording went sharper, so its n standard error reaches the bound.
void widenToBound(std::vector<MaterialFit>& materials);

}  // namespace phongfit
