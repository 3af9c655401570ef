#include "rgb_film.h"

#include <algorithm>

namespace phongfit {

RgbFilm::RgbFilm(int width, int height, int spp, std::span<const std::uint8_t> rendered)
    : width_(width),
      height_(height),
      spp_(spp),
      rendered_(rendered),
      sum_(3 * std::size_t(width) * height, 0.0),
      sumSq_(3 * std::size_t(width) * height, 0.0),
      count_(std::size_t(width) * height, 0) {}

void RgbFilm::add(std::uint32_t p, const Color3& radiance) {
    for (int c = 0; c < 3; ++c) {
        sum_[3 * p + c] += radiance[c];
        sumSq_[3 * p + c] += radiance[c] * radiance[c];
    }
    ++count_[p];
}

RenderResult RgbFilm::result(RenderStats stats) const {
    const std::size_t pixels = count_.size();
    RenderResult result;
    result.width = width_;
    result.height = height_;
    result.rgb.resize(3 * pixels);
    result.variance.resize(3 * pixels);
    result.sampleCount = count_;
    for (std::size_t p = 0; p < pixels; ++p) {
        const double n = count_[p];
        for (int c = 0; c < 3; ++c) {
            const double mean = n > 0 ? sum_[3 * p + c] / n : 0;
            const double var =
                n > 1 ? std::max(0.0, sumSq_[3 * p + c] / n - mean * mean) / (n - 1) : 0;
            result.rgb[3 * p + c] = float(mean);
            result.variance[3 * p + c] = float(var);
        }
    }
    result.stats = std::move(stats);
    return result;
}

}  // namespace phongfit
