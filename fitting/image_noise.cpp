#include "image_noise.h"

#include <algorithm>
#include <array>
#include <cmath>

#include "standard_errors.h"

namespace phongfit {

namespace {

// The median of a chi-square variable with one degree of freedom, over its mean.
constexpr double kChiSquareMedian = 0.4549;

struct NoiseSums {
    Eigen::MatrixXd gram;   // J^T J
    Eigen::MatrixXd noise;  // J^T diag(path variance) J

    NoiseSums& operator+=(const NoiseSums& other) {
        gram += other.gram;
        noise += other.noise;
        return *this;
    }
};

// kappa from each pixel's r_A . r_B (`cross`) against its paths' variance (`variance`, over
// channels): the median of their ratios over the pixels whose paths vary at least as much as the
// median pixel's, divided by 0.455, the median of a chi-square with one degree of freedom over
// its mean. A ratio of sums would be the ratio at the few pixels whose paths vary most (a
// sub-pixel highlight's, whose noise kappa is for); a mean of ratios is ruled by pixels whose
// noise no recorded path carries (a silhouette's background, an image's fireflies).
double noiseScale(const std::vector<double>& cross, const std::vector<double>& variance) {
    std::vector<double> sorted = variance;
    const auto middle = sorted.begin() + std::ptrdiff_t(sorted.size() / 2);
    std::nth_element(sorted.begin(), middle, sorted.end());
    const double median = sorted.empty() ? 0.0 : *middle;
    std::vector<double> ratios;
    for (std::size_t i = 0; i < cross.size(); ++i)
        if (variance[i] >= median && variance[i] > 0) ratios.push_back(cross[i] / variance[i]);
    if (ratios.empty()) return 0;
    const auto half = ratios.begin() + std::ptrdiff_t(ratios.size() / 2);
    std::nth_element(ratios.begin(), half, ratios.end());
    return std::max(0.0, *half / kChiSquareMedian);
}

}  // namespace

template <int P>
std::vector<std::vector<double>> imageNoiseStd(Objective<P>& objective,
                                               const std::vector<double>& y,
                                               const std::vector<HeldParams>& held) {
    // Exact recordings have no paths' variance to model the image's noise on.
    if (objective.exact()) return noStd(int(held.size()), P);
    const UsedPixels& prep = objective.pixels();
    const Eigen::Index size = Eigen::Index(objective.blocks()) * P;
    const NoiseSums zero{Eigen::MatrixXd::Zero(size, size), Eigen::MatrixXd::Zero(size, size)};
    std::vector<double> cross(prep.seeingMaterial), variances(prep.seeingMaterial);
    const NoiseSums sums = objective.sumPixels(
        prep.seeingMaterial, zero,
        [&](std::size_t i, NoiseSums& sum, typename Objective<P>::Scratch& scratch) {
            const UsedPixel& u = prep.pixels[i];
            std::array<Eigen::Vector3d, 2> r;
            Eigen::Vector3d variance = Eigen::Vector3d::Zero();
            for (int k = 0; k < 2; ++k) {
                r[k] = objective.residual(objective.recording(k, u.view), u, y.data(), scratch,
                                          &scratch.jacobians[k]);
                variance += 0.5 * objective.pathVariance(k, u, y.data(), scratch);
            }
            cross[i] = r[0].dot(r[1]);
            variances[i] = variance.sum();
            const std::span<const std::uint32_t> slots = prep.slotsOf(u);
            std::vector<Eigen::Index>& indices = scratch.indices;
            indices.clear();
            Eigen::MatrixXd j(3, Eigen::Index(slots.size()) * P);
            for (std::size_t a = 0; a < slots.size(); ++a) {
                for (int k = 0; k < P; ++k) indices.push_back(Eigen::Index(slots[a]) * P + k);
                j.middleCols(Eigen::Index(a) * P, P) =
                    0.5 * (scratch.jacobians[0][a] + scratch.jacobians[1][a]);
            }
            sum.gram(indices, indices) += j.transpose() * j;
            sum.noise(indices, indices) += j.transpose() * variance.asDiagonal() * j;
        });
    return naturalStd<P>(sums.gram, noiseScale(cross, variances) * sums.noise, held);
}

void applyImageNoise(MaterialFit& fit) {
    fit.kdStd = fit.kdStd.max(fit.kdImageStd);
    fit.ksStd = fit.ksStd.max(fit.ksImageStd);
    if (fit.logNImageStd > fit.logNStd) {
        fit.logNStd = fit.logNImageStd;
        fit.nStd = std::max(fit.nStd, fit.n * fit.logNStd);
    }
}

template std::vector<std::vector<double>> imageNoiseStd<kRgbBlock>(Objective<kRgbBlock>&,
                                                                   const std::vector<double>&,
                                                                   const std::vector<HeldParams>&);
template std::vector<std::vector<double>> imageNoiseStd<kGreyBlock>(Objective<kGreyBlock>&,
                                                                    const std::vector<double>&,
                                                                    const std::vector<HeldParams>&);

}  // namespace phongfit
