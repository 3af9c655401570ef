// A rectangle of the camera's film that a loop traces (a fit's recordings: the bounding box of the
// pixels it uses, so that nothing it holds per pixel grows with the pixels it leaves out). Its
// films are window-sized, pixels numbered from its corner; each pixel's random numbers stay keyed
// by its index on the whole film, so a window's pixels get the same samples as a whole film's.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace phongfit {

struct FilmWindow {
    int x0 = 0, y0 = 0, width = 0, height = 0;
    std::size_t pixels() const { return std::size_t(width) * std::size_t(height); }
};

// The smallest window holding every pixel where `flags` (width x height, row-major) is non-zero;
// the whole film where none is.
FilmWindow boundingWindow(const std::vector<std::uint8_t>& flags, int width, int height);

// The smallest window holding `pixels` (indices into a film `width` wide, at least one).
FilmWindow boundingWindow(const std::vector<std::uint32_t>& pixels, int width);

// `w` grown by `margin` pixels on every side, within the width x height film.
FilmWindow widened(const FilmWindow& w, int margin, int width, int height);

// The window's part of a film-sized array of `channels` values a pixel.
template <typename T>
std::vector<T> cropped(const std::vector<T>& film, int filmWidth, const FilmWindow& w,
                       int channels = 1) {
    std::vector<T> out;
    out.reserve(w.pixels() * std::size_t(channels));
    for (int y = w.y0; y < w.y0 + w.height; ++y) {
        const auto row = film.begin() + (std::ptrdiff_t(y) * filmWidth + w.x0) * channels;
        out.insert(out.end(), row, row + std::ptrdiff_t(w.width) * channels);
    }
    return out;
}

}  // namespace phongfit
