// Images in linear RGB float. EXR (radiance, as rendered) through OpenEXR, and PFM (pfm_file.h);
// PNG, JPEG and TIFF (photographs, plots) through OpenCV, decoded to linear on reading and encoded
// to sRGB on writing.
// Every write is atomic (atomic_file.h) and refuses non-finite values: a NaN in an output is a bug
// upstream, which the caller must sanitize and report, never pass on silently.
#pragma once

#include <cstddef>
#include <cstdint>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "math.h"

namespace phongfit {

// How 8- and 16-bit values v in [0, 1] become linear. EXR and float TIFF are linear already.
enum class Encoding {
    Auto,    // sRGB for 8-bit (what cameras and editors write), linear for 16-bit (raw converters)
    Srgb,    // the sRGB transfer function
    Linear,  // v itself
    Gamma,   // v^gamma
};

struct Image {
    int width = 0, height = 0;
    std::vector<float> rgb;  // 3 floats per pixel, row-major, row 0 = top
    // Per pixel: 1 if any channel was at the LDR format's maximum (the true value may be higher).
    std::vector<std::uint8_t> clipped;
    // How the file's values became linear, in words, e.g. "8-bit, decoded with the sRGB curve (the
    // default for 8-bit)": what a user must know to tell a linear capture decoded as sRGB.
    std::string decoding = "linear";
    // The curve integer values were decoded with (never Auto); none for float data.
    std::optional<Encoding> integerCurve;
    // Per pixel: 1 where the file holds no value (an EXR framed in its display window, outside its
    // data window: ReadOptions::exrDisplayWindow); such pixels read 0. Empty where every pixel
    // has a value.
    std::vector<std::uint8_t> noData;

    Image() = default;
    // Black, nothing clipped.
    Image(int width, int height);

    std::size_t pixelCount() const { return std::size_t(width) * std::size_t(height); }
    std::size_t index(int x, int y) const { return std::size_t(y) * std::size_t(width) + x; }
    Color<float> at(int x, int y) const {
        const float* p = &rgb[3 * index(x, y)];
        return Color<float>(p[0], p[1], p[2]);
    }
    void set(int x, int y, const Color<float>& c) {
        float* p = &rgb[3 * index(x, y)];
        p[0] = c[0], p[1] = c[1], p[2] = c[2];
    }
};

struct ReadOptions {
    Encoding encoding = Encoding::Auto;
    double gamma = 2.2;  // for Encoding::Gamma
    // EXR: the image is the file's display window, the frame the renderer rendered, with the data
    // window's pixels in their place (a crop window's render, an overscan): pixels it does not
    // cover are flagged in Image::noData, and data outside the frame is dropped. Otherwise the
    // image is the data window alone, as Mitsuba and pbrt read an environment map.
    bool exrDisplayWindow = false;
};

// By extension (case-insensitive): .exr via OpenEXR (R, G, B, or a single Y read as grey; its data
// window, or its display window with ReadOptions::exrDisplayWindow);
// .png, .jpg, .jpeg, .tif, .tiff via OpenCV (8- or 16-bit, grey or colour; alpha ignored; 32-bit
// float TIFF as linear). Throws Error naming the file if it is missing or unreadable, has an
// unknown extension, no pixels, or lacks a colour channel.
Image readImage(const std::string& path, const ReadOptions& options = {});

// A lossless 8- or 16-bit PNG of size width x height; a pixel is used where any colour channel is
// nonzero. Throws Error naming the file (and both sizes on a size mismatch).
std::vector<std::uint8_t> readMask(const std::string& path, int width, int height);

// Float32 RGB, ZIP-compressed, atomic. Throws Error if the image holds NaN or infinity.
void writeExr(const Image& image, const std::string& path);
// Throws where `path` names another format readImage reads (a render's -o a.pfm): an OpenEXR file
// under that name is refused by its format's readers. Other names (none, .out) are left as given.
void requireExrName(const std::string& path);
// Linear RGB times `exposure`, clamped to [0, 1], sRGB-encoded to 8 bits; atomic. Throws Error if
// the image holds NaN or infinity, or exposure is not finite and > 0.
void writePng(const Image& image, const std::string& path, double exposure = 1.0);
// An 8-bit BGR (or grey) picture, e.g. a plot; atomic.
void writePng(const cv::Mat& bgr8, const std::string& path);

// The sRGB transfer function and its inverse, on [0, 1].
double srgbToLinear(double v);
double linearToSrgb(double v);

}  // namespace phongfit
