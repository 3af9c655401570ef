#include "image_noise.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <utility>

#include "exposure_block.h"
#include "material_params.h"
#include "standard_errors.h"

namespace phongfit {

namespace {

// The median of a chi-square variable with one degree of freedom, over its mean.
constexpr double kChiSquareMedian = 0.4549;

// A pixel holds a parameter with at least this share of its information (J^T J's diagonal). The
// images are rendered anew at the kRenderedPixels that hold the largest shares, and the kHolders
// largest of each parameter are kept while the pixels are summed. A twentieth, not a quarter: a
// sharp lobe that reflects a probe's sun spreads ks over a few bright pixels, none holding a
// quarter, whose stratified samples are far noisier than the model's median pixel says
// (docs/design/fitter.md, "A sharp lobe under a textured environment").
constexpr double kHeldShare = 0.05;
constexpr std::size_t kRenderedPixels = 4;
constexpr std::size_t kHolders = 8;

// A lobe whose n is known to this factor or worse (3 standard errors of log n) has the image's
// noise taken where it is sharper too: at up to kSharperRungs lobes, each kSharperRung sharper
// than the last (sharperLogNStd).
constexpr double kSharperReach = 2;
constexpr int kSharperRungs = 4;
constexpr double kSharperRung = 4;
// A sharper lobe whose renders fit the pixels holding n worse than the estimate's by this much (a
// likelihood ratio's 3 standard errors) is ruled out by the image (imageReach).
constexpr double kRuledOut = 9;

// A pixel's share of a parameter's information (its term of J^T J's diagonal), and the pixel.
struct Holder {
    double information = 0;
    std::uint32_t pixel = 0;  // into UsedPixels::pixels

    bool operator<(const Holder& other) const {  // more information first; ties by pixel
        return information != other.information ? information > other.information
                                                : pixel < other.pixel;
    }
};

struct NoiseSums {
    Eigen::MatrixXd gram;   // J^T J
    Eigen::MatrixXd noise;  // J^T (path covariance) J
    // Per natural parameter, the kHolders pixels holding most of its information.
    std::vector<std::vector<Holder>> holders;

    NoiseSums& operator+=(const NoiseSums& other) {
        gram += other.gram;
        noise += other.noise;
        for (std::size_t g = 0; g < holders.size(); ++g)
            for (const Holder& h : other.holders[g]) keep(g, h);
        return *this;
    }

    void keep(std::size_t g, const Holder& h) {
        std::vector<Holder>& list = holders[g];
        if (list.size() == kHolders && !(h < list.back())) return;
        list.insert(std::upper_bound(list.begin(), list.end(), h), h);
        if (list.size() > kHolders) list.pop_back();
    }
};

// The pixels that hold each of `sums`' parameters (`only` those flagged, if given): at least
// `leastShare` of its information, at most kRenderedPixels in all (those holding the largest
// shares), by view.
std::map<std::uint32_t, std::vector<std::uint32_t>> heldPixels(const NoiseSums& sums,
                                                               const UsedPixels& prep,
                                                               double leastShare,
                                                               const std::vector<bool>& only) {
    std::vector<std::pair<double, std::uint32_t>> shares;  // (-share, pixel)
    for (std::size_t g = 0; g < sums.holders.size(); ++g)
        for (const Holder& h : sums.holders[g])
            if (const double total = sums.gram(Eigen::Index(g), Eigen::Index(g));
                (only.empty() || only[g]) && total > 0 && h.information >= leastShare * total)
                shares.emplace_back(-h.information / total, h.pixel);
    std::sort(shares.begin(), shares.end());
    std::vector<std::uint32_t> chosen;
    for (const auto& [share, pixel] : shares)
        if (chosen.size() < kRenderedPixels &&
            std::find(chosen.begin(), chosen.end(), pixel) == chosen.end())
            chosen.push_back(pixel);
    std::map<std::uint32_t, std::vector<std::uint32_t>> byView;
    for (std::uint32_t i : chosen) byView[prep.pixels[i].view].push_back(i);
    return byView;
}

// The median of `values` (reordered) and its standard error: half the distribution-free 68%
// interval of the median, between the order statistics sqrt(N) / 2 either side of it.
struct Median {
    double value = 0, error = 0;
};

Median medianOf(std::vector<double>& values) {
    if (values.empty()) return {};
    std::sort(values.begin(), values.end());
    const double count = double(values.size()), reach = std::sqrt(count) / 2;
    const auto at = [&](double rank) {
        return values[std::size_t(std::clamp(rank, 0.0, count - 1))];
    };
    return {at(count / 2), 0.5 * (at(count / 2 + reach) - at(count / 2 - reach))};
}

// A pixel's Jacobian (the mean of the two recordings'), with its residuals `r` and the covariance
// of one of its paths; the Jacobian's columns are scratch.indices' natural coordinates.
template <int P>
Eigen::MatrixXd pixelTerms(Objective<P>& objective, const double* y, const UsedPixel& u,
                           typename Objective<P>::Scratch& scratch,
                           std::array<Eigen::Vector3d, 2>& r, Eigen::Matrix3d& covariance) {
    covariance.setZero();
    for (int k = 0; k < 2; ++k) {
        r[k] = objective.residual(objective.recording(k, u.view), u, y, scratch,
                                  &scratch.jacobians[k]);
        covariance += 0.5 * objective.pathCovariance(k, u, y, scratch);
    }
    const std::span<const std::uint32_t> slots = objective.pixels().slotsOf(u);
    std::vector<Eigen::Index>& indices = scratch.indices;
    indices.clear();
    Eigen::MatrixXd j(3, Eigen::Index(slots.size()) * P);
    for (std::size_t a = 0; a < slots.size(); ++a) {
        for (int k = 0; k < P; ++k) indices.push_back(Eigen::Index(slots[a]) * P + k);
        j.middleCols(Eigen::Index(a) * P, P) =
            0.5 * (scratch.jacobians[0][a] + scratch.jacobians[1][a]);
    }
    return j;
}

// The material blocks: all but the exposure's, if it is fitted (its slot is the last).
template <int P>
int materialBlocks(const Objective<P>& objective) {
    const ExposureBlock& exposure = objective.exposure();
    return exposure.fitted() ? exposure.slot() : objective.blocks();
}

// Log n of material m's lobe kSharperRung^k sharper than the sharp end of 3 of `logNStd` (at
// most kMaxExponent): the rungs sharperReach and imageReach take.
template <int P>
double sharperRung(const std::vector<double>& y, std::size_t m, const std::vector<double>& logNStd,
                   int k) {
    return std::min(y[m * P + BlockLayout<P>::kLogN] + 3 * logNStd[m] + k * std::log(kSharperRung),
                    std::log(kMaxExponent));
}

// The film pixels of used pixels `pixels` (indices into UsedPixels::pixels).
std::vector<std::uint32_t> filmPixels(const UsedPixels& prep,
                                      const std::vector<std::uint32_t>& pixels) {
    std::vector<std::uint32_t> film;
    for (std::uint32_t i : pixels) film.push_back(prep.pixels[i].pixel);
    return film;
}

// The materials at flat natural coordinates `at`.
template <int P>
std::vector<PhongMaterial> materialsAt(const Objective<P>& objective, const double* at) {
    std::vector<PhongMaterial> theta;
    for (int m = 0; m < materialBlocks(objective); ++m)
        theta.push_back(naturalToPhong<P>(at + std::size_t(m) * P));
    return theta;
}

// What the pixels that hold a parameter (heldPixels) add to the modelled noise sum (kappa times
// `sums`'): their noise as rendered with the materials at `at` (flat natural coordinates), where it
// is larger than the model's, which an image of stratified samples can be by far at a highlight
// smaller than a pixel (docs/design/fitter.md, "The pixels that hold a parameter, rendered anew").
template <int P>
Eigen::MatrixXd renderedNoiseSum(Objective<P>& objective, const double* y, const double* at,
                                 const NoiseSums& sums, double kappa, const RenderedNoise& rendered,
                                 double leastShare, const std::vector<bool>& only) {
    const UsedPixels& prep = objective.pixels();
    const std::vector<PhongMaterial> theta = materialsAt(objective, at);
    const double scale = objective.exposure().template value<P>(y);
    const Eigen::MatrixXd zero = Eigen::MatrixXd::Zero(sums.noise.rows(), sums.noise.cols());
    Eigen::MatrixXd added = zero;
    for (const auto& held : heldPixels(sums, prep, leastShare, only)) {
        const std::uint32_t view = held.first;
        const std::vector<std::uint32_t>& pixels = held.second;  // a lambda captures it below
        const std::vector<RenderedPixel> renders =
            rendered(int(view), filmPixels(prep, pixels), theta);
        if (renders.size() != pixels.size()) continue;  // an image without noise
        const auto raise = [&](std::size_t k, Eigen::MatrixXd& sum,
                               typename Objective<P>::Scratch& scratch) {
            const UsedPixel& u = prep.pixels[pixels[k]];
            std::array<Eigen::Vector3d, 2> r;
            Eigen::Matrix3d covariance;
            const Eigen::MatrixXd j = pixelTerms(objective, y, u, scratch, r, covariance);
            const double w = objective.weight(u) * scale;
            // The rendered noise where it exceeds the model's, direction by direction over the
            // channels: a larger trace can hide a smaller variance along some direction, and
            // taking that would narrow the estimate's standard errors on 16 renders' word.
            const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> excess(
                w * w * renders[k].covariance - kappa * covariance);
            const Eigen::Vector3d larger = excess.eigenvalues().cwiseMax(0.0);
            if (!(larger.maxCoeff() > 0)) return;
            const Eigen::MatrixXd jv = excess.eigenvectors().transpose() * j;
            const std::vector<Eigen::Index>& indices = scratch.indices;
            sum(indices, indices) += jv.transpose() * larger.asDiagonal() * jv;
        };
        added += objective.sumPixels(pixels.size(), zero, raise);
    }
    return added;
}

// How far the image itself allows each `climbing` lobe on its sharp side (docs/design/fitter.md,
// "A sharper lobe the image does not rule out"): the pixels that hold most of its n's
// information, rendered as the image was at the estimate and at lobes kSharperRung^k beyond the
// sharp end of 3 of `logNStd`, from the estimate's side, until one fits the image worse than the
// estimate by kRuledOut: `reach` rises to the s whose 3 reach the last not ruled out. Lobes
// `reach` already covers are not rendered. A pixel's misfit is its channels' sum's over the
// larger of the two renders' variances, their means' own added: a narrower highlight is the
// noisier, and the larger keeps a noise the renders underrate from ruling a lobe out.
template <int P>
void imageReach(Objective<P>& objective, const std::vector<double>& y,
                const RenderedNoise& rendered, const NoiseSums& sums,
                const std::vector<bool>& climbing, const std::vector<double>& logNStd,
                std::vector<double>& reach) {
    using L = BlockLayout<P>;
    const UsedPixels& prep = objective.pixels();
    const double scale = objective.exposure().template value<P>(y.data());
    for (std::size_t m = 0; m < climbing.size(); ++m) {
        const std::size_t i = m * P + L::kLogN;
        const auto rung = [&](int k) { return sharperRung<P>(y, m, logNStd, k); };
        if (!climbing[m] || rung(kSharperRungs - 1) - y[i] <= 3 * reach[m]) continue;
        std::vector<bool> only(sums.holders.size(), false);
        only[i] = true;
        const auto held = heldPixels(sums, prep, 0.0, only);
        // Per held pixel, in view order: the scaled renders' channel sums and their variances.
        const auto renderAt = [&](const std::vector<double>& at) {
            std::vector<std::pair<double, double>> sumAndVariance;
            for (const auto& [view, pixels] : held) {
                for (const RenderedPixel& r : rendered(int(view), filmPixels(prep, pixels),
                                                       materialsAt(objective, at.data())))
                    sumAndVariance.emplace_back(
                        scale * r.mean.sum(),
                        scale * scale * r.covariance.sum() * (1 + 1.0 / r.renders));
            }
            return sumAndVariance;
        };
        std::vector<double> observed;
        for (const auto& [view, pixels] : held)
            for (std::uint32_t p : pixels)
                observed.push_back(objective.observed(prep.pixels[p]).sum());
        const auto estimate = renderAt(y);
        if (estimate.size() != observed.size()) continue;  // an image without noise
        std::vector<double> at = y;
        for (int k = 0; k < kSharperRungs; ++k) {
            if (k > 0 && rung(k) <= at[i]) break;
            at[i] = rung(k);
            if (at[i] - y[i] <= 3 * reach[m]) continue;
            const auto sharper = renderAt(at);
            double worse = 0;
            for (std::size_t p = 0; p < observed.size(); ++p)
                worse += (std::pow(observed[p] - sharper[p].first, 2) -
                          std::pow(observed[p] - estimate[p].first, 2)) /
                         std::max({sharper[p].second, estimate[p].second, 1e-300});
            if (!(worse < kRuledOut)) break;
            reach[m] = (at[i] - y[i]) / 3;
        }
    }
}

bool anyOf(const std::vector<bool>& v) {
    return std::any_of(v.begin(), v.end(), [](bool b) { return b; });
}

// The lobes sharperLogNStd takes: n free, known to kSharperReach or worse, below the bound.
template <int P>
std::vector<bool> climbingLobes(const std::vector<double>& y, const std::vector<HeldParams>& held,
                                const std::vector<double>& logNStd) {
    std::vector<bool> climbing(logNStd.size(), false);
    for (std::size_t m = 0; m < logNStd.size(); ++m)
        climbing[m] = !held[m].n && 3 * logNStd[m] > std::log(kSharperReach) &&
                      y[m * P + BlockLayout<P>::kLogN] < std::log(kMaxExponent);
    return climbing;
}

// sharperLogNStd from the sums and kappa at the estimate. Each `climbing` lobe (climbingLobes)
// is taken sharper than the sharp end of its 3 standard errors by kSharperRung^k, k = 0 ..
// kSharperRungs - 1 (at most kMaxExponent): J^T C J with C a path's covariance replayed there,
// and the pixels holding most of n's information rendered there. The sharpest first: where its
// noise does not reach back to the estimate, no rung's is taken as reaching (a narrower highlight
// is the noisier); where it does, the first rung that reaches back from the estimate's side says
// how far. The image itself may allow more (imageReach).
template <int P>
std::vector<double> sharperReach(Objective<P>& objective, const std::vector<double>& y,
                                 const std::vector<HeldParams>& held, const RenderedNoise& rendered,
                                 const NoiseSums& sums, double kappa,
                                 const std::vector<double>& logNStd, std::vector<bool> climbing) {
    using L = BlockLayout<P>;
    const UsedPixels& prep = objective.pixels();
    const std::size_t materials = logNStd.size();
    std::vector<double> reach(materials, 0.0);
    // Whether the climbing lobes' noise at rung `k` reaches back, each: into `reach`.
    const auto reachesBack = [&](int k) {
        std::vector<double> at = y;
        std::vector<bool> sharpened(y.size(), false);
        for (std::size_t m = 0; m < materials; ++m) {
            if (!climbing[m]) continue;
            const std::size_t i = m * P + L::kLogN;
            at[i] = sharperRung<P>(y, m, logNStd, k);
            sharpened[i] = true;
        }
        const Eigen::MatrixXd replayed = objective.sumPixels(
            prep.seeingMaterial,
            Eigen::MatrixXd(Eigen::MatrixXd::Zero(sums.noise.rows(), sums.noise.cols())),
            [&](std::size_t i, Eigen::MatrixXd& sum, typename Objective<P>::Scratch& scratch) {
                const UsedPixel& u = prep.pixels[i];
                std::array<Eigen::Vector3d, 2> r;
                Eigen::Matrix3d covariance;
                const Eigen::MatrixXd j =
                    pixelTerms(objective, y.data(), u, scratch, r, covariance);
                covariance = 0.5 * (objective.pathCovariance(0, u, at.data(), scratch) +
                                    objective.pathCovariance(1, u, at.data(), scratch));
                const std::vector<Eigen::Index>& indices = scratch.indices;
                sum(indices, indices) += j.transpose() * covariance * j;
            });
        const std::vector<std::vector<double>> std =
            naturalStd<P>(sums.gram,
                          kappa * replayed + renderedNoiseSum(objective, y.data(), at.data(), sums,
                                                              kappa, rendered, 0.0, sharpened),
                          held);
        std::vector<bool> back(materials, false);
        for (std::size_t m = 0; m < materials; ++m) {
            const std::size_t i = m * P + L::kLogN;
            const double distance = at[i] - y[i], s = std[m][L::kLogN];
            back[m] = climbing[m] && 3 * s >= distance;
            if (back[m]) reach[m] = std::max(s, distance / 3);
        }
        return back;
    };
    const std::vector<bool> climbed = climbing;
    climbing = reachesBack(kSharperRungs - 1);
    for (int k = 0; k + 1 < kSharperRungs && anyOf(climbing); ++k) {
        const std::vector<bool> back = reachesBack(k);
        for (std::size_t m = 0; m < materials; ++m) climbing[m] = climbing[m] && !back[m];
    }
    imageReach(objective, y, rendered, sums, climbed, logNStd, reach);
    return reach;
}

// The sums over the pixels at `y` and kappa (noiseScale) read from them.
struct NoiseModel {
    NoiseSums sums;
    double kappa = 0;
};

template <int P>
NoiseModel noiseModel(Objective<P>& objective, const std::vector<double>& y) {
    const UsedPixels& prep = objective.pixels();
    const Eigen::Index size = Eigen::Index(objective.blocks()) * P;
    const NoiseSums zero{Eigen::MatrixXd::Zero(size, size), Eigen::MatrixXd::Zero(size, size),
                         std::vector<std::vector<Holder>>(std::size_t(size))};
    std::vector<PixelNoise> noise(prep.seeingMaterial);
    NoiseSums sums = objective.sumPixels(
        prep.seeingMaterial, zero,
        [&](std::size_t i, NoiseSums& sum, typename Objective<P>::Scratch& scratch) {
            std::array<Eigen::Vector3d, 2> r;
            Eigen::Matrix3d covariance;
            const Eigen::MatrixXd j =
                pixelTerms(objective, y.data(), prep.pixels[i], scratch, r, covariance);
            noise[i] = {r[0].dot(r[1]), 0.25 * (r[0] - r[1]).squaredNorm(), covariance.trace()};
            const std::vector<Eigen::Index>& indices = scratch.indices;
            sum.gram(indices, indices) += j.transpose() * j;
            sum.noise(indices, indices) += j.transpose() * covariance * j;
            for (Eigen::Index c = 0; c < j.cols(); ++c)
                sum.keep(std::size_t(indices[std::size_t(c)]),
                         {j.col(c).squaredNorm(), std::uint32_t(i)});
        });
    return {std::move(sums), noiseScale(std::move(noise))};
}

}  // namespace

double noiseScale(std::vector<PixelNoise> pixels) {
    // Pixels reordered, and each ratio's values held one at a time: the fit's state stays within
    // its bytes a pixel (fit_memory_test).
    const auto middle = pixels.begin() + std::ptrdiff_t(pixels.size() / 2);
    std::nth_element(
        pixels.begin(), middle, pixels.end(),
        [](const PixelNoise& a, const PixelNoise& b) { return a.variance < b.variance; });
    const double least = pixels.empty() ? 0.0 : middle->variance;
    const auto counted = [&](const PixelNoise& p) { return p.variance >= least && p.variance > 0; };
    const auto medianOver = [&](auto ratio) {
        std::vector<double> values;
        values.reserve(std::size_t(std::count_if(pixels.begin(), pixels.end(), counted)));
        for (const PixelNoise& p : pixels)
            if (counted(p)) values.push_back(ratio(p) / p.variance);
        return medianOf(values);
    };
    const double product = std::max(
        0.0, medianOver([](const PixelNoise& p) { return p.cross; }).value / kChiSquareMedian);
    const Median d = medianOver([](const PixelNoise& p) { return p.halfDifference; });
    if (!(d.value / kChiSquareMedian <= kModelledRecordingNoise)) return product;
    const Median s = medianOver([](const PixelNoise& p) { return p.cross + p.halfDifference; });
    return std::max(product,
                    (s.value - d.value - 2 * std::hypot(s.error, d.error)) / kChiSquareMedian);
}

template <int P>
std::vector<std::vector<double>> imageNoiseStd(Objective<P>& objective,
                                               const std::vector<double>& y,
                                               const std::vector<HeldParams>& held,
                                               const RenderedNoise& rendered) {
    // Exact recordings have no paths' variance to model the image's noise on.
    if (objective.exact()) return noStd(int(held.size()), P);
    const NoiseModel model = noiseModel(objective, y);
    Eigen::MatrixXd modelled = model.kappa * model.sums.noise;
    if (rendered)
        modelled += renderedNoiseSum(objective, y.data(), y.data(), model.sums, model.kappa,
                                     rendered, kHeldShare, {});
    return naturalStd<P>(model.sums.gram, modelled, held);
}

template <int P>
std::vector<double> sharperLogNStd(Objective<P>& objective, const std::vector<double>& y,
                                   const std::vector<HeldParams>& held,
                                   const RenderedNoise& rendered,
                                   const std::vector<double>& logNStd) {
    if (objective.exact() || !rendered) return {};
    std::vector<bool> climbing = climbingLobes<P>(y, held, logNStd);
    if (!anyOf(climbing)) return {};
    const NoiseModel model = noiseModel(objective, y);
    return sharperReach(objective, y, held, rendered, model.sums, model.kappa, logNStd,
                        std::move(climbing));
}

void applyImageNoise(MaterialFit& fit) {
    // Independent of the recordings' noise: the variances add, less what was counted.
    const auto add = [](double std, double image, double counted) {
        return std::sqrt(std * std + std::max(0.0, image * image - counted * counted));
    };
    for (int c = 0; c < 3; ++c) {
        fit.kdStd[c] = add(fit.kdStd[c], fit.kdImageStd[c], fit.kdCountedImageStd[c]);
        fit.ksStd[c] = add(fit.ksStd[c], fit.ksImageStd[c], fit.ksCountedImageStd[c]);
    }
    if (fit.logNImageStd > fit.logNCountedImageStd) {
        fit.logNStd = add(fit.logNStd, fit.logNImageStd, fit.logNCountedImageStd);
        fit.nStd = std::max(fit.nStd, fit.n * fit.logNStd);
    }
}

template std::vector<std::vector<double>> imageNoiseStd<kRgbBlock>(Objective<kRgbBlock>&,
                                                                   const std::vector<double>&,
                                                                   const std::vector<HeldParams>&,
                                                                   const RenderedNoise&);
template std::vector<std::vector<double>> imageNoiseStd<kGreyBlock>(Objective<kGreyBlock>&,
                                                                    const std::vector<double>&,
                                                                    const std::vector<HeldParams>&,
                                                                    const RenderedNoise&);
template std::vector<double> sharperLogNStd<kRgbBlock>(Objective<kRgbBlock>&,
                                                       const std::vector<double>&,
                                                       const std::vector<HeldParams>&,
                                                       const RenderedNoise&,
                                                       const std::vector<double>&);
template std::vector<double> sharperLogNStd<kGreyBlock>(Objective<kGreyBlock>&,
                                                        const std::vector<double>&,
                                                        const std::vector<HeldParams>&,
                                                        const RenderedNoise&,
                                                        const std::vector<double>&);

}  // namespace phongfit
