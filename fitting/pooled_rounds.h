// Rounds that settled at one estimate, pooled (docs/design/fitter.md, "Rounds pooled"). Each round
// records its paths anew at the last estimate, so two rounds that settled there are two estimates
// of it whose recordings' noise is independent and whose image's noise is common. Their mean,
// weighted per parameter by the inverse of each one's recordings' variance, has the recordings'
// variance of all their paths together: a round needs to record only the paths the pool still
// lacks, not all of them again.
#pragma once

#include <Eigen/Core>
#include <vector>

#include "parameter_state.h"
#include "round_outcome.h"

namespace phongfit {

template <int P>
struct PooledRounds {
    std::vector<Eigen::Matrix<double, P, 1>> estimate;  // natural coordinates, per block
    // Per block and parameter: the recordings' variance of the pooled estimate, and the image's
    // (common to every round), as the round with the most paths measured it: a round with few
    // paths tells the two apart poorly.
    std::vector<std::vector<double>> pathVariance, imageVariance;
    double imagePathFactor = 0;  // the paths of that round
    // Per material, the image noise's standard errors (MaterialFit::kdImageStd, ...), the largest
    // any pooled round's model gave among the rounds within kImageNoisePathRatio of the most
    // paths: the image is common to them, and a round's model can read 0 where another's sees
    // the noise of the one pixel that holds a lobe.
    std::vector<MaterialFit> imageNoise;
    // Per block and parameter: the rounds' chi-square about the pooled mean in units of their
    // recordings' own noise. Over its rounds - 1 degrees of freedom, above 1, it widens the pool's
    // recordings' variance (Birge): rounds that disagree by more than their noise do not pool to
    // the precision their paths would give.
    std::vector<std::vector<double>> chiSquare;
    std::vector<bool> held;  // flat, as ParameterState::heldFlags
    double pathFactor = 0;   // the pooled rounds' paths, summed, relative to the first round's
    int rounds = 0;
};

// Where a round joins a pool and one of the two has this many times the other's paths or more,
// the image noise is that one's alone: at a point-lit sphere's n 300 a round of the first round's
// paths read n +- 2.1 where one of 15 times as many read 0 (its seeds' estimates scatter by 0.04).
// A pool's reading counts as its round's of the most paths.
inline constexpr double kImageNoisePathRatio = 4;

// A round's solution `out`, at `params`' point and recorded at `pathFactor`, as a pool of one. Its
// standard errors are split by the recordings' share of each variance (RoundOutcome::pathShare).
template <int P>
PooledRounds<P> poolOfRound(const RoundOutcome& out, const ParameterState<P>& params,
                            double pathFactor);

// A round's estimate, and a pool's, is pooled only where every free parameter's standard error is
// at most this relative to its value (as FitOptions::precision measures it: n through log n).
// Weighing by the inverse variance assumes one variance at the rounds' point, while an estimate's
// standard errors change with where it is (a broader lobe's n is held more precisely): a climb
// from n 299 +- 4% to 3882 +- 88% pooled back to 303 (docs/design/fitter.md, "Rounds pooled").
inline constexpr double kPoolableStd = 0.1;

// Whether every free parameter of `pool` is as precise as kPoolableStd asks: else no round
// joins it.
template <int P>
bool preciseEnoughToPool(const PooledRounds<P>& pool);

// Whether `round` can join `pool`: the same parameters held, every recordings' variance measured
// (a share of 0 everywhere says there is no split, as without a precision target), and both
// precise enough to pool.
template <int P>
bool poolable(const PooledRounds<P>& pool, const PooledRounds<P>& round);

// Per block and parameter, the noise a move between the pool's estimate and `round`'s may have
// and still be at one point: the round's standard error and the pool's recordings' noise
// together (the image's, common to both, counted once).
template <int P>
std::vector<std::vector<double>> poolingNoise(const PooledRounds<P>& pool,
                                              const PooledRounds<P>& round);

// `pool` with `round` added: per parameter the mean weighted by the inverse recordings'
// variances, whose recordings' variance is their harmonic sum.
template <int P>
PooledRounds<P> pooled(const PooledRounds<P>& pool, const PooledRounds<P>& round);

// The paths, relative to the first round's, that the next round at a pool of `poolFactor` paths
// records where the precision plan asks for `pathGrowth` times the pool's: the paths the pool
// lacks, at least the first round's and a quarter of the pool's (a round that adds less gains
// little, and its scatter, of fewer paths, widens the result; round_scatter.h), at most as many
// as the pool holds or kMostPathGrowth times the first round's, whichever is more.
double pathsThePoolLacks(double poolFactor, double pathGrowth);

// Moves `params` to the pool's estimate and puts it into `out`: its materials (with the pool's
// image noise, and `out`'s unconstrained parameters), exposure, standard errors (the recordings'
// variance widened by Birge's ratio, max(1, chiSquare / (rounds - 1)), plus the image's) and
// their recordings' share.
template <int P>
void adoptPool(const PooledRounds<P>& pool, ParameterState<P>& params, RoundOutcome& out);

}  // namespace phongfit
