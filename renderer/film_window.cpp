#include "film_window.h"

#include <algorithm>
#include <opencv2/imgproc.hpp>

namespace phongfit {

FilmWindow boundingWindow(const std::vector<std::uint8_t>& flags, int width, int height) {
    const cv::Rect box =
        cv::boundingRect(cv::Mat(height, width, CV_8U, const_cast<std::uint8_t*>(flags.data())));
    if (box.empty()) return {0, 0, width, height};
    return {box.x, box.y, box.width, box.height};
}

FilmWindow widened(const FilmWindow& w, int margin, int width, int height) {
    const int x0 = std::max(w.x0 - margin, 0), y0 = std::max(w.y0 - margin, 0);
    return {x0, y0, std::min(w.x0 + w.width + margin, width) - x0,
            std::min(w.y0 + w.height + margin, height) - y0};
}

}  // namespace phongfit
