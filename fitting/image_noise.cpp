#include "image_noise.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <utility>

#include "standard_errors.h"

namespace phongfit {

namespace {

// The median of a chi-square variable with one degree of freedom, over its mean.
constexpr double kChiSquareMedian = 0.4549;

struct NoiseSums {
    Eigen::MatrixXd gram;   // J^T J
    Eigen::MatrixXd noise;  // J^T (path covariance) J

    NoiseSums& operator+=(const NoiseSums& other) {
        gram += other.gram;
        noise += other.noise;
        return *this;
    }
};

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

}  // namespace

double noiseScale(std::vector<PixelNoise> pixels) {
    // Pixels reordered, and each ratio's values held one at a time: the fit's state stays within
    // its bytes a pixel (fit_memory_test).
    const auto middle = pixels.begin() + std::ptrdiff_t(pixels.size() / 2);
    std::nth_element(
        pixels.begin(), middle, pixels.end(),
        [](const PixelNoise& a, const PixelNoise& b) { return a.variance < b.variance; });
    const double least = pixels.empty() ? 0.0 : middle->variance;
    const auto medianOver = [&](auto ratio) {
        std::vector<double> values;
        for (const PixelNoise& p : pixels)
            if (p.variance >= least && p.variance > 0) values.push_back(ratio(p) / p.variance);
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
                                               const std::vector<HeldParams>& held) {
    // Exact recordings have no paths' variance to model the image's noise on.
    if (objective.exact()) return noStd(int(held.size()), P);
    const UsedPixels& prep = objective.pixels();
    const Eigen::Index size = Eigen::Index(objective.blocks()) * P;
    const NoiseSums zero{Eigen::MatrixXd::Zero(size, size), Eigen::MatrixXd::Zero(size, size)};
    std::vector<PixelNoise> noise(prep.seeingMaterial);
    const NoiseSums sums = objective.sumPixels(
        prep.seeingMaterial, zero,
        [&](std::size_t i, NoiseSums& sum, typename Objective<P>::Scratch& scratch) {
            const UsedPixel& u = prep.pixels[i];
            std::array<Eigen::Vector3d, 2> r;
            Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
            for (int k = 0; k < 2; ++k) {
                r[k] = objective.residual(objective.recording(k, u.view), u, y.data(), scratch,
                                          &scratch.jacobians[k]);
                covariance += 0.5 * objective.pathCovariance(k, u, y.data(), scratch);
            }
            noise[i] = {r[0].dot(r[1]), 0.25 * (r[0] - r[1]).squaredNorm(), covariance.trace()};
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
            sum.noise(indices, indices) += j.transpose() * covariance * j;
        });
    return naturalStd<P>(sums.gram, noiseScale(std::move(noise)) * sums.noise, held);
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
