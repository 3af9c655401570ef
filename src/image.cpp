#include "image.h"

#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>
#include <ImfOutputFile.h>
#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>

#include "atomic_file.h"
#include "error.h"
#include "image_limits.h"
#include "pfm_file.h"

namespace phongfit {
namespace {

std::string lowercaseExtension(const std::string& path) {
    std::string ext = std::filesystem::path(path).extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    return ext;
}

// The extensions readImage reads.
bool readableExtension(const std::string& ext) {
    for (const char* known : {".exr", ".pfm", ".png", ".jpg", ".jpeg", ".tif", ".tiff"})
        if (ext == known) return true;
    return false;
}

void requireReadableFile(const std::string& path, const char* what) {
    std::error_code ec;
    if (!std::filesystem::is_regular_file(path, ec))
        throw Error(fmt::format("cannot read {} '{}': no such file", what, path));
}

// The image's frame: the display window with `displayWindow`, else the data window.
Image readExr(const std::string& path, bool displayWindow) {
    try {
        requireExrWithinLimits(path);
        Imf::InputFile file(path.c_str());
        const Imath::Box2i data = file.header().dataWindow();
        const Imath::Box2i frame = displayWindow ? file.header().displayWindow() : data;
        const std::int64_t width = std::int64_t(frame.max.x) - frame.min.x + 1;
        const std::int64_t height = std::int64_t(frame.max.y) - frame.min.y + 1;
        if (frame != data) requireExrFrameWithinLimits(path, width, height);
        const Imf::ChannelList& channels = file.header().channels();
        const char* names[3] = {"R", "G", "B"};
        int rgbCount = 0;
        for (const char* name : names) rgbCount += channels.findChannel(name) != nullptr;
        const bool grey = rgbCount == 0 && channels.findChannel("Y");
        if (rgbCount != 3 && !grey) {
            std::string present;
            for (auto it = channels.begin(); it != channels.end(); ++it)
                present += fmt::format("{}{}", present.empty() ? "" : ", ", it.name());
            throw Error(
                fmt::format("EXR image '{}' has channels [{}]; phongfit needs R, G and B "
                            "(or a single Y for grey)",
                            path, present));
        }
        Image image(static_cast<int>(width), static_cast<int>(height));
        image.decoding = "EXR, linear";
        // The data the frame holds, read a row at a time (a row's slices have no y stride).
        const int x0 = std::max(data.min.x, frame.min.x), x1 = std::min(data.max.x, frame.max.x);
        const int y0 = std::max(data.min.y, frame.min.y), y1 = std::min(data.max.y, frame.max.y);
        const int channelCount = grey ? 1 : 3;
        std::vector<float> row(std::size_t(channelCount) *
                               std::size_t(data.max.x - data.min.x + 1));
        Imf::FrameBuffer buffer;
        const std::size_t xStride = std::size_t(channelCount) * sizeof(float);
        for (int c = 0; c < channelCount; ++c) {
            // Where pixel (0, y) would be for every y (Slice::Make takes a y stride of 0 as none).
            const std::intptr_t origin = reinterpret_cast<std::intptr_t>(row.data() + c) -
                                         std::intptr_t(data.min.x) * std::intptr_t(xStride);
            buffer.insert(grey ? "Y" : names[c],
                          Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(origin), xStride, 0));
        }
        file.setFrameBuffer(buffer);
        for (int y = y0; y <= y1 && x0 <= x1; ++y) {
            file.readPixels(y, y);
            for (int x = x0; x <= x1; ++x) {
                const float* v = &row[std::size_t(channelCount) * std::size_t(x - data.min.x)];
                float* p = &image.rgb[3 * image.index(x - frame.min.x, y - frame.min.y)];
                for (int c = 0; c < 3; ++c) p[c] = v[grey ? 0 : c];
            }
        }
        if (x0 > frame.min.x || x1 < frame.max.x || y0 > frame.min.y || y1 < frame.max.y) {
            image.noData.assign(image.pixelCount(), 1);
            for (int y = y0; y <= y1 && x0 <= x1; ++y)
                std::fill_n(image.noData.begin() +
                                std::ptrdiff_t(image.index(x0 - frame.min.x, y - frame.min.y)),
                            x1 - x0 + 1, 0);
        }
        return image;
    } catch (const Error&) {
        throw;
    } catch (const std::exception& e) {
        throw Error(fmt::format("cannot read EXR image '{}': {}", path, e.what()));
    }
}

// Lookup table from the integer value to linear, for formats with `levels` values.
Encoding resolvedEncoding(int levels, const ReadOptions& options) {
    if (options.encoding != Encoding::Auto) return options.encoding;
    return levels <= 256 ? Encoding::Srgb : Encoding::Linear;
}

std::string describeDecoding(int levels, const ReadOptions& options) {
    const int bits = levels <= 256 ? 8 : 16;
    const std::string chosen =
        options.encoding == Encoding::Auto ? fmt::format(" (the default for {}-bit)", bits) : "";
    switch (resolvedEncoding(levels, options)) {
        case Encoding::Srgb:
            return fmt::format("{}-bit, decoded with the sRGB curve{}", bits, chosen);
        case Encoding::Gamma:
            return fmt::format("{}-bit, decoded as value^{:g}", bits, options.gamma);
        default:
            return fmt::format("{}-bit, read as linear{}", bits, chosen);
    }
}

std::vector<float> decodingTable(int levels, const ReadOptions& options, const std::string& path) {
    const Encoding encoding = resolvedEncoding(levels, options);
    if (encoding == Encoding::Gamma && !(std::isfinite(options.gamma) && options.gamma > 0))
        throw Error(fmt::format("reading '{}': gamma = {} is invalid (allowed: finite, > 0)", path,
                                options.gamma));
    std::vector<float> table(levels);
    for (int i = 0; i < levels; ++i) {
        const double v = double(i) / (levels - 1);
        switch (encoding) {
            case Encoding::Srgb:
                table[i] = float(srgbToLinear(v));
                break;
            case Encoding::Gamma:
                table[i] = float(std::pow(v, options.gamma));
                break;
            default:
                table[i] = float(v);
                break;
        }
    }
    return table;
}

// BGR(A) or grey OpenCV pixels of integer type P to linear RGB through `table`.
template <typename P>
void decodeIntegerPixels(const cv::Mat& mat, const std::vector<float>& table, Image& image) {
    const int channels = mat.channels();
    const P top = P(table.size() - 1);
    for (int y = 0; y < image.height; ++y) {
        const P* row = mat.ptr<P>(y);
        for (int x = 0; x < image.width; ++x) {
            const P* p = row + std::size_t(x) * channels;
            const P r = channels >= 3 ? p[2] : p[0], g = channels >= 3 ? p[1] : p[0], b = p[0];
            image.set(x, y, Color<float>(table[r], table[g], table[b]));
            image.clipped[image.index(x, y)] = r == top || g == top || b == top;
        }
    }
}

void decodeFloatPixels(const cv::Mat& mat, Image& image) {
    const int channels = mat.channels();
    for (int y = 0; y < image.height; ++y) {
        const float* row = mat.ptr<float>(y);
        for (int x = 0; x < image.width; ++x) {
            const float* p = row + std::size_t(x) * channels;
            image.set(
                x, y,
                channels >= 3 ? Color<float>(p[2], p[1], p[0]) : Color<float>::Constant(p[0]));
        }
    }
}

cv::Mat readWithOpenCv(const std::string& path, int flags, const char* what, bool pngOnly) {
    requireLdrWithinLimits(path, what, pngOnly);
    cv::Mat mat;
    try {
        mat = cv::imread(path, flags);
    } catch (const cv::Exception& e) {
        throw Error(fmt::format("cannot read {} '{}': {}", what, path, e.what()));
    }
    if (mat.empty())
        throw Error(fmt::format("cannot read {} '{}': not a valid image file, or it has no pixels",
                                what, path));
    return mat;
}

Image readLdr(const std::string& path, const ReadOptions& options) {
    // ANYDEPTH keeps 16-bit values, ANYCOLOR keeps grey as grey; EXIF orientation is applied, so
    // the pixels are oriented as viewers show them.
    const cv::Mat mat =
        readWithOpenCv(path, cv::IMREAD_ANYDEPTH | cv::IMREAD_ANYCOLOR, "image", false);
    Image image(mat.cols, mat.rows);
    switch (mat.depth()) {
        case CV_8U:
            decodeIntegerPixels<std::uint8_t>(mat, decodingTable(256, options, path), image);
            image.decoding = describeDecoding(256, options);
            image.integerCurve = resolvedEncoding(256, options);
            break;
        case CV_16U:
            decodeIntegerPixels<std::uint16_t>(mat, decodingTable(65536, options, path), image);
            image.decoding = describeDecoding(65536, options);
            image.integerCurve = resolvedEncoding(65536, options);
            break;
        case CV_32F:
            decodeFloatPixels(mat, image);
            image.decoding = "32-bit float, linear";
            break;
        default:
            throw Error(
                fmt::format("cannot read image '{}': unsupported sample type (allowed: 8- "
                            "or 16-bit integer, 32-bit float)",
                            path));
    }
    return image;
}

void requireFinite(const Image& image, const std::string& path) {
    if (image.width <= 0 || image.height <= 0 || image.rgb.size() != 3 * image.pixelCount())
        throw Error(fmt::format("refusing to write '{}': image is {}x{} with {} values", path,
                                image.width, image.height, image.rgb.size()));
    std::size_t count = 0, first = 0;
    for (std::size_t i = 0; i < image.rgb.size(); ++i) {
        if (std::isfinite(image.rgb[i])) continue;
        if (count++ == 0) first = i;
    }
    if (count == 0) return;
    const std::size_t pixel = first / 3;
    throw Error(
        fmt::format("refusing to write '{}': {} non-finite values (NaN or infinity), the "
                    "first at pixel ({}, {}) channel {}",
                    path, count, pixel % image.width, pixel / image.width, "RGB"[first % 3]));
}

void writeBytes(const std::filesystem::path& path, const std::vector<uchar>& bytes) {
    std::ofstream out(path, std::ios::binary);
    out.write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
    out.close();
    if (!out) throw Error(fmt::format("cannot write '{}': I/O error", path.string()));
}

}  // namespace

Image::Image(int width, int height)
    : width(width), height(height), rgb(3 * pixelCount(), 0.0f), clipped(pixelCount(), 0) {}

double srgbToLinear(double v) {
    return v <= 0.04045 ? v / 12.92 : std::pow((v + 0.055) / 1.055, 2.4);
}

double linearToSrgb(double v) {
    return v <= 0.0031308 ? 12.92 * v : 1.055 * std::pow(v, 1 / 2.4) - 0.055;
}

Image readImage(const std::string& path, const ReadOptions& options) {
    const std::string ext = lowercaseExtension(path);
    const bool exr = ext == ".exr", pfm = ext == ".pfm";
    if (!readableExtension(ext))
        throw Error(
            fmt::format("cannot read image '{}': unknown extension '{}' (allowed: .exr, .pfm, "
                        ".png, .jpg, .jpeg, .tif, .tiff)",
                        path, ext));
    requireReadableFile(path, "image");
    Image image = exr   ? readExr(path, options.exrDisplayWindow)
                  : pfm ? readPfm(path)
                        : readLdr(path, options);
    if (image.pixelCount() == 0) throw Error(fmt::format("image '{}' has no pixels", path));
    return image;
}

void requireExrName(const std::string& path) {
    const std::string ext = lowercaseExtension(path);
    if (ext != ".exr" && readableExtension(ext))
        throw Error(
            fmt::format("cannot write '{}': the image is written as OpenEXR, which a '{}' "
                        "file would not hold; name it .exr",
                        path, ext));
}

std::vector<std::uint8_t> readMask(const std::string& path, int width, int height) {
    if (lowercaseExtension(path) != ".png")
        throw Error(fmt::format("cannot read mask '{}': masks must be PNG files (lossless)", path));
    requireReadableFile(path, "mask");
    const cv::Mat mat = readWithOpenCv(path, cv::IMREAD_UNCHANGED, "mask", true);
    if (mat.depth() != CV_8U && mat.depth() != CV_16U)
        throw Error(fmt::format("cannot read mask '{}': allowed are 8- or 16-bit PNGs", path));
    if (mat.cols != width || mat.rows != height)
        throw Error(fmt::format("mask '{}' is {}x{} but the image is {}x{}", path, mat.cols,
                                mat.rows, width, height));
    // Grey (+ alpha): channel 0; colour (+ alpha): channels 0 to 2. Alpha never counts.
    const int colourChannels = mat.channels() >= 3 ? 3 : 1;
    cv::Mat used(mat.rows, mat.cols, CV_8U, cv::Scalar(0));
    for (int c = 0; c < colourChannels; ++c) {
        cv::Mat channel;
        cv::extractChannel(mat, channel, c);
        cv::bitwise_or(used, channel != 0, used);
    }
    std::vector<std::uint8_t> mask(std::size_t(width) * height);
    for (int y = 0; y < height; ++y)
        for (int x = 0; x < width; ++x)
            mask[std::size_t(y) * width + x] = used.at<uchar>(y, x) != 0;
    return mask;
}

void writeExr(const Image& image, const std::string& path) {
    requireFinite(image, path);
    writeAtomically(path, [&](const std::filesystem::path& temporary) {
        try {
            Imf::Header header(image.width, image.height);
            header.compression() = Imf::ZIP_COMPRESSION;
            Imf::FrameBuffer frame;
            // OpenEXR's Slice takes a mutable pointer even for writing.
            char* base = reinterpret_cast<char*>(const_cast<float*>(image.rgb.data()));
            const char* names[3] = {"R", "G", "B"};
            for (int c = 0; c < 3; ++c) {
                header.channels().insert(names[c], Imf::Channel(Imf::FLOAT));
                frame.insert(names[c],
                             Imf::Slice(Imf::FLOAT, base + c * sizeof(float), 3 * sizeof(float),
                                        3 * sizeof(float) * image.width));
            }
            Imf::OutputFile file(temporary.c_str(), header);
            file.setFrameBuffer(frame);
            file.writePixels(image.height);
        } catch (const std::exception& e) {
            throw Error(fmt::format("cannot write EXR image '{}': {}", path, e.what()));
        }
    });
}

void writePng(const Image& image, const std::string& path, double exposure) {
    if (!(std::isfinite(exposure) && exposure > 0))
        throw Error(fmt::format("writing '{}': exposure = {} is invalid (allowed: finite, > 0)",
                                path, exposure));
    requireFinite(image, path);
    cv::Mat bgr(image.height, image.width, CV_8UC3);
    for (int y = 0; y < image.height; ++y) {
        for (int x = 0; x < image.width; ++x) {
            const Color<float> c = image.at(x, y);
            cv::Vec3b& out = bgr.at<cv::Vec3b>(y, x);
            for (int k = 0; k < 3; ++k) {
                const double v = std::clamp(double(c[k]) * exposure, 0.0, 1.0);
                out[2 - k] = static_cast<uchar>(std::lround(255 * linearToSrgb(v)));
            }
        }
    }
    writePng(bgr, path);
}

void writePng(const cv::Mat& bgr8, const std::string& path) {
    if (lowercaseExtension(path) != ".png")
        throw Error(fmt::format("cannot write '{}': PNG output needs a .png file name", path));
    if (bgr8.empty() || bgr8.depth() != CV_8U)
        throw Error(fmt::format("cannot write '{}': expected a non-empty 8-bit picture", path));
    std::vector<uchar> bytes;
    if (!cv::imencode(".png", bgr8, bytes))
        throw Error(fmt::format("cannot write '{}': PNG encoding failed", path));
    writeAtomically(path,
                    [&](const std::filesystem::path& temporary) { writeBytes(temporary, bytes); });
}

}  // namespace phongfit
