#include "pooled_rounds.h"

#include <algorithm>
#include <cmath>

#include "precision_target.h"

namespace phongfit {

template <int P>
PooledRounds<P> poolOfRound(const RoundOutcome& out, const ParameterState<P>& params,
                            double pathFactor) {
    PooledRounds<P> pool;
    pool.estimate = params.naturalBlocks();
    pool.held = params.heldFlags();
    pool.imageNoise = out.materials;
    pool.pathFactor = pool.imagePathFactor = pathFactor;
    pool.rounds = 1;
    for (std::size_t b = 0; b < out.naturalStd.size(); ++b) {
        std::vector<double>& path = pool.pathVariance.emplace_back(P, 0.0);
        std::vector<double>& image = pool.imageVariance.emplace_back(P, 0.0);
        pool.chiSquare.emplace_back(P, 0.0);
        for (int i = 0; i < P; ++i) {
            const double variance =
                out.naturalStd[b][std::size_t(i)] * out.naturalStd[b][std::size_t(i)];
            const double share = b < out.pathShare.size()
                                     ? std::clamp(out.pathShare[b][std::size_t(i)], 0.0, 1.0)
                                     : 0.0;
            path[std::size_t(i)] = share * variance;
            image[std::size_t(i)] = (1 - share) * variance;
        }
    }
    return pool;
}

template <int P>
bool preciseEnoughToPool(const PooledRounds<P>& pool) {
    for (std::size_t b = 0; b < pool.pathVariance.size(); ++b)
        for (int i = 0; i < P; ++i) {
            const std::size_t j = std::size_t(i);
            if (pool.held[b * P + j]) continue;
            const double std = std::sqrt(pool.pathVariance[b][j] + pool.imageVariance[b][j]);
            if (!(std <= kPoolableStd * precisionScale<P>(i, pool.estimate[b]))) return false;
        }
    return true;
}

template <int P>
bool poolable(const PooledRounds<P>& pool, const PooledRounds<P>& round) {
    if (pool.rounds == 0 || pool.held != round.held ||
        pool.estimate.size() != round.estimate.size())
        return false;
    for (std::size_t b = 0; b < round.pathVariance.size(); ++b)
        for (int i = 0; i < P; ++i)
            if (!round.held[b * P + std::size_t(i)] && !(pool.pathVariance[b][std::size_t(i)] > 0 &&
                                                         round.pathVariance[b][std::size_t(i)] > 0))
                return false;
    return preciseEnoughToPool(pool) && preciseEnoughToPool(round);
}

template <int P>
std::vector<std::vector<double>> poolingNoise(const PooledRounds<P>& pool,
                                              const PooledRounds<P>& round) {
    std::vector<std::vector<double>> noise = round.pathVariance;
    for (std::size_t b = 0; b < noise.size() && b < pool.pathVariance.size(); ++b)
        for (std::size_t i = 0; i < noise[b].size(); ++i)
            noise[b][i] =
                std::sqrt(noise[b][i] + round.imageVariance[b][i] + pool.pathVariance[b][i]);
    return noise;
}

template <int P>
PooledRounds<P> pooled(const PooledRounds<P>& pool, const PooledRounds<P>& round) {
    PooledRounds<P> sum = round;
    sum.pathFactor = pool.pathFactor + round.pathFactor;
    sum.rounds = pool.rounds + 1;
    // A round of far fewer paths than another read its image noise where its recordings barely
    // resolved the estimate, and reads far more: the other's reading stands alone.
    if (pool.imagePathFactor >= kImageNoisePathRatio * round.pathFactor) {
        sum.imageNoise = pool.imageNoise;
    } else if (round.pathFactor < kImageNoisePathRatio * pool.imagePathFactor) {
        for (std::size_t m = 0; m < sum.imageNoise.size() && m < pool.imageNoise.size(); ++m) {
            MaterialFit& most = sum.imageNoise[m];
            const MaterialFit& other = pool.imageNoise[m];
            most.kdImageStd = most.kdImageStd.cwiseMax(other.kdImageStd);
            most.ksImageStd = most.ksImageStd.cwiseMax(other.ksImageStd);
            most.logNImageStd = std::max(most.logNImageStd, other.logNImageStd);
            most.logNSharperImageStd =
                std::max(most.logNSharperImageStd, other.logNSharperImageStd);
        }
    }
    if (pool.imagePathFactor > round.pathFactor) {
        sum.imageVariance = pool.imageVariance;
        sum.imagePathFactor = pool.imagePathFactor;
    }
    for (std::size_t b = 0; b < round.estimate.size(); ++b)
        for (int i = 0; i < P; ++i) {
            if (round.held[b * P + std::size_t(i)]) continue;
            const double a = pool.pathVariance[b][std::size_t(i)],
                         c = round.pathVariance[b][std::size_t(i)];
            sum.estimate[b][i] = (c * pool.estimate[b][i] + a * round.estimate[b][i]) / (a + c);
            sum.pathVariance[b][std::size_t(i)] = a * c / (a + c);
            // The chi-square about the mean grows by the new estimate's squared distance from
            // the old mean over the variance of that difference.
            sum.chiSquare[b][std::size_t(i)] =
                pool.chiSquare[b][std::size_t(i)] +
                std::pow(round.estimate[b][i] - pool.estimate[b][i], 2) / (a + c);
        }
    return sum;
}

double pathsThePoolLacks(double poolFactor, double pathGrowth) {
    // A round added to a pool records at least the pool's paths over this.
    constexpr double kLeastPoolGrowth = 4;
    return std::max({1.0,
                     std::min(poolFactor * (pathGrowth - 1), std::max(poolFactor, kMostPathGrowth)),
                     poolFactor / kLeastPoolGrowth});
}

template <int P>
void adoptPool(const PooledRounds<P>& pool, ParameterState<P>& params, RoundOutcome& out) {
    for (std::size_t b = 0; b < pool.estimate.size(); ++b) {
        params.setNatural(int(b), pool.estimate[b].data());
        for (int i = 0; i < P; ++i) {
            const double birge =
                pool.rounds > 1
                    ? std::max(1.0, pool.chiSquare[b][std::size_t(i)] / double(pool.rounds - 1))
                    : 1.0;
            const double path = birge * pool.pathVariance[b][std::size_t(i)],
                         all = path + pool.imageVariance[b][std::size_t(i)];
            out.naturalStd[b][std::size_t(i)] = std::sqrt(all);
            if (b < out.pathShare.size())
                out.pathShare[b][std::size_t(i)] = all > 0 ? path / all : 0;
        }
    }
    for (int m = 0; m < params.materialCount(); ++m) {
        MaterialFit fit = materialFit(params, m, out.naturalStd[std::size_t(m)]);
        const MaterialFit& image = pool.imageNoise[std::size_t(m)];
        fit.kdImageStd = image.kdImageStd;
        fit.ksImageStd = image.ksImageStd;
        fit.logNImageStd = image.logNImageStd;
        fit.logNSharperImageStd = image.logNSharperImageStd;
        countImageNoise(params, m, out, fit);
        fit.unconstrained = out.materials[std::size_t(m)].unconstrained;
        out.materials[std::size_t(m)] = fit;
    }
    const ExposureBlock& exposure = params.exposure();
    if (exposure.fitted())
        out.exposure = exposureFit(params, out.naturalStd[std::size_t(exposure.slot())]);
}

template PooledRounds<kRgbBlock> poolOfRound<kRgbBlock>(const RoundOutcome&,
                                                        const ParameterState<kRgbBlock>&, double);
template PooledRounds<kGreyBlock> poolOfRound<kGreyBlock>(const RoundOutcome&,
                                                          const ParameterState<kGreyBlock>&,
                                                          double);
template bool preciseEnoughToPool<kRgbBlock>(const PooledRounds<kRgbBlock>&);
template bool preciseEnoughToPool<kGreyBlock>(const PooledRounds<kGreyBlock>&);
template bool poolable<kRgbBlock>(const PooledRounds<kRgbBlock>&, const PooledRounds<kRgbBlock>&);
template bool poolable<kGreyBlock>(const PooledRounds<kGreyBlock>&,
                                   const PooledRounds<kGreyBlock>&);
template std::vector<std::vector<double>> poolingNoise<kRgbBlock>(const PooledRounds<kRgbBlock>&,
                                                                  const PooledRounds<kRgbBlock>&);
template std::vector<std::vector<double>> poolingNoise<kGreyBlock>(const PooledRounds<kGreyBlock>&,
                                                                   const PooledRounds<kGreyBlock>&);
template PooledRounds<kRgbBlock> pooled<kRgbBlock>(const PooledRounds<kRgbBlock>&,
                                                   const PooledRounds<kRgbBlock>&);
template PooledRounds<kGreyBlock> pooled<kGreyBlock>(const PooledRounds<kGreyBlock>&,
                                                     const PooledRounds<kGreyBlock>&);
template void adoptPool<kRgbBlock>(const PooledRounds<kRgbBlock>&, ParameterState<kRgbBlock>&,
                                   RoundOutcome&);
template void adoptPool<kGreyBlock>(const PooledRounds<kGreyBlock>&, ParameterState<kGreyBlock>&,
                                    RoundOutcome&);

}  // namespace phongfit
