#include "film_window.h"

#include <algorithm>
#include <limits>
#include <opencv2/imgproc.hpp>

namespace phongfit {

FilmWindow boundingWindow(const std::vector<std::uint8_t>& flags, int width, int height) {
    const cv::Rect box =
        cv::boundingRect(cv::Mat(height, width, CV_8U, const_cast<std::uint8_t*>(flags.data())));
    if (box.empty()) return {0, 0, width, height};
    return {box.x, box.y, box.width, box.height};
}

FilmWindow boundingWindow(const std::vector<std::uint32_t>& pixels, int width) {
    const auto w = std::uint32_t(width);
    std::uint32_t x0 = w, y0 = std::numeric_limits<std::uint32_t>::max(), x1 = 0, y1 = 0;
    for (std::uint32_t p : pixels) {
        x0 = std::min(x0, p % w), x1 = std::max(x1, p % w);
        y0 = std::min(y0, p / w), y1 = std::max(y1, p / w);
    }
    return {int(x0), int(y0), int(x1 - x0 + 1), int(y1 - y0 + 1)};
}

FilmWindow widened(const FilmWindow& w, int margin, int width, int height) {
    const int x0 = std::max(w.x0 - margin, 0), y0 = std::max(w.y0 - margin, 0);
    return {x0, y0, std::min(w.x0 + w.width + margin, width) - x0,
            std::min(w.y0 + w.height + margin, height) - y0};
}

}  // namespace phongfit
