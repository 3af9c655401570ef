#include "material_clusters.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <opencv2/core.hpp>

#include "error.h"

namespace phongfit {
namespace {

// The weight of log brightness against chromaticity.
constexpr double kBrightnessWeight = 0.05;

}  // namespace

std::vector<std::uint8_t> clusterMaterials(const AlbedoMapFit& shared, int materials) {
    const std::size_t maskPixels = shared.kd.size();
    std::vector<std::uint32_t> used;
    std::vector<double> brightness;
    for (std::size_t p = 0; p < maskPixels; ++p)
        if (shared.fitted[p]) {
            used.push_back(std::uint32_t(p));
            brightness.push_back(std::log(std::max(shared.kd[p].sum(), 1e-6)));
        }
    if (used.size() < std::size_t(materials))
        throw Error(
            fmt::format("--materials {}: more than the {} fitted pixels", materials, used.size()));
    std::vector<double> sorted = brightness;
    std::sort(sorted.begin(), sorted.end());
    const double low = sorted[sorted.size() / 100], high = sorted[sorted.size() * 99 / 100];
    cv::Mat features(int(used.size()), 3, CV_32F);
    for (std::size_t i = 0; i < used.size(); ++i) {
        const Color3& kd = shared.kd[used[i]];
        const double sum = kd.sum();
        const Color3 chroma = sum > 0 ? Color3(kd / sum) : Color3::Constant(1.0 / 3);
        features.at<float>(int(i), 0) = float(chroma[0]);
        features.at<float>(int(i), 1) = float(chroma[1]);
        features.at<float>(int(i), 2) =
            float(kBrightnessWeight * std::clamp(brightness[i], low, high));
    }
    cv::Mat labels, centres;
    cv::setRNGSeed(1);
    cv::kmeans(features, materials, labels,
               cv::TermCriteria(cv::TermCriteria::EPS + cv::TermCriteria::COUNT, 100, 1e-5), 5,
               cv::KMEANS_PP_CENTERS, centres);
    std::vector<int> order(static_cast<std::size_t>(materials));
    std::iota(order.begin(), order.end(), 0);
    std::sort(order.begin(), order.end(),
              [&](int a, int b) { return centres.at<float>(a, 2) < centres.at<float>(b, 2); });
    std::vector<std::uint8_t> rank(static_cast<std::size_t>(materials));
    for (int i = 0; i < materials; ++i) rank[std::size_t(order[std::size_t(i)])] = std::uint8_t(i);
    std::vector<std::uint8_t> out(maskPixels, 0);
    for (std::size_t i = 0; i < used.size(); ++i)
        out[used[i]] = rank[std::size_t(labels.at<int>(int(i)))];
    return out;
}

}  // namespace phongfit
