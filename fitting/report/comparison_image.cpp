#include "comparison_image.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "error.h"
#include "image.h"
#include "percentile.h"

namespace phongfit {
namespace {

const cv::Vec3b kGrey(64, 64, 64);

}  // namespace

cv::Mat comparisonImage(const ComparisonPanels& panels) {
    const int w = panels.width, h = panels.height;
    const std::size_t pixels = std::size_t(w) * std::size_t(h);
    if (w <= 0 || h <= 0 || panels.observed.size() != pixels || panels.state.size() != pixels)
        throw Error(fmt::format("comparison image: {}x{} needs {} pixels ({} and {} given)", w, h,
                                pixels, panels.observed.size(), panels.state.size()));
    std::vector<double> luminance, errors;
    for (std::size_t p = 0; p < pixels; ++p) {
        if (panels.state[p] == ComparePixel::Outside) continue;
        const Color3& o = panels.observed[p];
        if (o.allFinite()) luminance.push_back(o.mean());
        if (panels.state[p] != ComparePixel::Compared) continue;
        for (const std::vector<Color3>& row : panels.predicted)
            errors.push_back(std::abs((row[p] - o).mean()));
    }
    const double white = std::max(1e-12, percentile(luminance, panels.whitePercentile));
    const double errorScale = std::max(1e-12, percentile(errors, 99));
    const auto srgb8 = [&](double v) {
        return cv::saturate_cast<uchar>(255 * linearToSrgb(std::clamp(v / white, 0.0, 1.0)) + 0.5);
    };
    const auto colour = [&](const Color3& c) {
        return c.allFinite() ? cv::Vec3b(srgb8(c[2]), srgb8(c[1]), srgb8(c[0])) : kGrey;
    };
    const int rows = int(panels.predicted.size());
    cv::Mat out(rows * h, 3 * w, CV_8UC3, cv::Scalar(0, 0, 0));
    for (int row = 0; row < rows; ++row) {
        if (panels.predicted[std::size_t(row)].size() != pixels)
            throw Error(fmt::format("comparison image: row {} has {} predicted pixels, not {}", row,
                                    panels.predicted[std::size_t(row)].size(), pixels));
        for (int y = 0; y < h; ++y)
            for (int x = 0; x < w; ++x) {
                const std::size_t p = std::size_t(y) * std::size_t(w) + std::size_t(x);
                const int top = row * h + y;
                if (panels.state[p] == ComparePixel::Outside) continue;
                out.at<cv::Vec3b>(top, x) = colour(panels.observed[p]);
                if (panels.state[p] == ComparePixel::LeftOut) {
                    out.at<cv::Vec3b>(top, w + x) = out.at<cv::Vec3b>(top, 2 * w + x) = kGrey;
                    continue;
                }
                const Color3& c = panels.predicted[std::size_t(row)][p];
                out.at<cv::Vec3b>(top, w + x) = colour(c);
                const double t =
                    std::clamp((c - panels.observed[p]).mean() / errorScale, -1.0, 1.0);
                const uchar fade = cv::saturate_cast<uchar>(255 * (1 - std::abs(t)));
                out.at<cv::Vec3b>(top, 2 * w + x) =
                    t > 0 ? cv::Vec3b(fade, fade, 255) : cv::Vec3b(255, fade, fade);
            }
    }
    return out;
}

std::string formatColor(const Color3& c, const Color3& s, bool grey) {
    if (grey) return fmt::format("{:.4g} ± {:.2g}", c[0], s[0]);
    return fmt::format("({:.4g}, {:.4g}, {:.4g}) ± ({:.2g}, {:.2g}, {:.2g})", c[0], c[1], c[2],
                       s[0], s[1], s[2]);
}

}  // namespace phongfit
