#include "capture.h"

#include <fmt/format.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <thread>

#include "error.h"

namespace phongfit {
namespace {

namespace fs = std::filesystem;

constexpr const char* kLayout =
    "filenames.txt, light_directions.txt, light_intensities.txt, mask.png and normals.exr";

struct Line {
    int number;  // 1-based, in the file
    std::string text;
};

std::string trim(const std::string& s) {
    const auto begin = s.find_first_not_of(" \t\r\n");
    if (begin == std::string::npos) return "";
    return s.substr(begin, s.find_last_not_of(" \t\r\n") - begin + 1);
}

std::string requireFile(const fs::path& dir, const std::string& name) {
    const fs::path path = dir / name;
    std::error_code ec;
    if (!fs::is_regular_file(path, ec))
        throw Error(fmt::format("capture '{}': missing '{}' (a capture folder holds {})",
                                dir.string(), path.string(), kLayout));
    return path.string();
}

// The non-blank lines of a text file.
std::vector<Line> readLines(const std::string& path) {
    std::error_code ec;
    const std::uintmax_t bytes = fs::file_size(path, ec);
    if (!ec && bytes > kMaxCaptureTextBytes)
        throw Error(fmt::format("'{}' is {} bytes (allowed: up to {} bytes)", path, bytes,
                                kMaxCaptureTextBytes));
    std::ifstream in(path);
    if (!in) throw Error(fmt::format("cannot read '{}'", path));
    std::vector<Line> lines;
    std::string text;
    for (int number = 1; std::getline(in, text); ++number) {
        text = trim(text);
        if (!text.empty()) lines.push_back({number, text});
    }
    if (lines.empty()) throw Error(fmt::format("'{}' is empty", path));
    return lines;
}

// Three numbers separated by spaces, tabs or commas.
Vec3d parseTriple(const std::string& path, const Line& line) {
    Vec3d v;
    const char* p = line.text.c_str();
    int count = 0;
    for (;;) {
        while (*p == ' ' || *p == '\t' || *p == ',') ++p;
        if (*p == '\0') break;
        char* end = nullptr;
        const double value = std::strtod(p, &end);
        if (end == p || count == 3) {
            count = -1;
            break;
        }
        v[count++] = value;
        p = end;
    }
    if (count != 3 || !v.allFinite())
        throw Error(
            fmt::format("{}:{}: '{}' is not three finite numbers", path, line.number, line.text));
    return v;
}

Vec3d unit(const Vec3d& v, const std::string& what) {
    const double length = v.norm();
    if (!(std::abs(length - 1) <= kUnitTolerance))
        throw Error(
            fmt::format("{}: ({:.6g}, {:.6g}, {:.6g}) has length {:.6g} (must be unit "
                        "within {:g})",
                        what, v.x(), v.y(), v.z(), length, kUnitTolerance));
    return v / length;
}

std::string describeCount(const std::string& path, std::size_t count) {
    return fmt::format("'{}' has {} line{}", path, count, count == 1 ? "" : "s");
}

CaptureImage readOne(const Capture& capture, int light, const CaptureReadOptions& options) {
    const CaptureLight& l = capture.lights[light];
    const Image image = readImage(l.imagePath, options.decoding);
    if (image.width != capture.width || image.height != capture.height)
        throw Error(fmt::format("image '{}' is {}x{} but the normals '{}' are {}x{}", l.imagePath,
                                image.width, image.height, capture.normalsPath, capture.width,
                                capture.height));
    CaptureImage out;
    out.light = light;
    out.decoding = image.decoding;
    out.integerCurve = image.integerCurve;
    out.rgb.resize(capture.pixels.size());
    out.state.resize(capture.pixels.size());
    const Color<float> intensity = l.intensity.cast<float>();
    bool black = true;
    for (std::size_t i = 0; i < capture.pixels.size(); ++i) {
        const std::size_t p = capture.pixels[i];
        const Color<float> raw(image.rgb[3 * p], image.rgb[3 * p + 1], image.rgb[3 * p + 2]);
        black = black && (raw == 0.0f).all();
        out.rgb[i] = raw / intensity;
        if (!raw.allFinite())
            out.state[i] = PixelState::NonFinite;
        else if ((!image.clipped.empty() && image.clipped[p]) ||
                 (options.saturation && raw.maxCoeff() >= *options.saturation))
            out.state[i] = PixelState::Clipped;
        else
            out.state[i] = PixelState::Ok;
    }
    if (black)
        throw Error(
            fmt::format("image '{}' is black everywhere inside the mask '{}' (a failed "
                        "exposure or the wrong file? leave the light out with --lights)",
                        l.imagePath, capture.maskPath));
    return out;
}

}  // namespace

Capture readCapture(const std::string& dir, const CaptureReadOptions& options) {
    std::error_code ec;
    if (!fs::is_directory(dir, ec))
        throw Error(
            fmt::format("capture '{}': no such folder (a capture folder holds {})", dir, kLayout));
    Capture c;
    c.dir = dir;
    const std::string namesPath = requireFile(dir, "filenames.txt");
    const std::string directionsPath = requireFile(dir, "light_directions.txt");
    const std::string intensitiesPath = requireFile(dir, "light_intensities.txt");
    c.normalsPath = requireFile(dir, "normals.exr");
    c.maskPath = options.mask.empty() ? requireFile(dir, "mask.png") : options.mask;

    const std::vector<Line> names = readLines(namesPath);
    const std::vector<Line> directions = readLines(directionsPath);
    const std::vector<Line> intensities = readLines(intensitiesPath);
    if (directions.size() != names.size() || intensities.size() != names.size())
        throw Error(
            fmt::format("capture '{}': the light counts disagree: {}, {}, {} (one line per "
                        "light in each, in the same order)",
                        dir, describeCount(namesPath, names.size()),
                        describeCount(directionsPath, directions.size()),
                        describeCount(intensitiesPath, intensities.size())));
    for (std::size_t i = 0; i < names.size(); ++i) {
        CaptureLight l;
        l.number = int(i) + 1;
        l.imagePath = (fs::path(dir) / names[i].text).string();
        l.direction =
            unit(parseTriple(directionsPath, directions[i]),
                 fmt::format("{}:{}: light direction", directionsPath, directions[i].number));
        const Vec3d intensity = parseTriple(intensitiesPath, intensities[i]);
        if (!(intensity.minCoeff() > 0))
            throw Error(fmt::format("{}:{}: intensity '{}' must be > 0 in every channel",
                                    intensitiesPath, intensities[i].number, intensities[i].text));
        l.intensity = intensity.array();
        c.lights.push_back(l);
    }

    const Image normals = readImage(c.normalsPath);
    c.width = normals.width;
    c.height = normals.height;
    const std::vector<std::uint8_t> mask = readMask(c.maskPath, c.width, c.height);
    std::size_t inMask = 0;
    std::string firstBad;
    for (std::size_t p = 0; p < mask.size(); ++p) {
        if (!mask[p]) continue;
        ++inMask;
        const Vec3d n(normals.rgb[3 * p], normals.rgb[3 * p + 1], normals.rgb[3 * p + 2]);
        const double length = n.norm();
        if (!(std::abs(length - 1) <= kUnitTolerance)) {
            if (c.badNormals++ == 0)
                firstBad = fmt::format(
                    "the first at pixel ({}, {}): ({:.6g}, {:.6g}, {:.6g}) has "
                    "length {:.6g}",
                    p % c.width, p / c.width, n.x(), n.y(), n.z(), length);
            continue;
        }
        c.pixels.push_back(std::uint32_t(p));
        c.normals.push_back(n / length);
    }
    if (double(c.badNormals) > kMaxBadNormalFraction * double(inMask))
        throw Error(fmt::format(
            "normals '{}': {} of the {} pixels inside the mask '{}' have no unit normal (within "
            "{:g}); {}. Above {:g}% the normals or the mask do not belong to this capture",
            c.normalsPath, c.badNormals, inMask, c.maskPath, kUnitTolerance, firstBad,
            100 * kMaxBadNormalFraction));
    if (c.pixels.empty())
        throw Error(
            fmt::format("mask '{}' selects no pixel (nonzero pixels are fitted)", c.maskPath));
    return c;
}

std::vector<CaptureImage> readCaptureImages(const Capture& capture, const std::vector<int>& lights,
                                            const CaptureReadOptions& options, int threads) {
    for (int light : lights)
        if (light < 0 || light >= int(capture.lights.size()))
            throw Error(fmt::format("capture '{}': light index {} is outside 0..{}", capture.dir,
                                    light, capture.lights.size() - 1));
    std::vector<CaptureImage> images(lights.size());
    std::atomic<std::size_t> next{0};
    std::mutex errorMutex;
    std::exception_ptr error;
    // The first error in light order, so the message does not depend on thread timing.
    std::size_t errorAt = lights.size();
    const auto work = [&] {
        for (std::size_t i = next++; i < lights.size(); i = next++) {
            try {
                images[i] = readOne(capture, lights[i], options);
            } catch (...) {
                const std::lock_guard lock(errorMutex);
                if (i < errorAt) {
                    errorAt = i;
                    error = std::current_exception();
                }
            }
        }
    };
    const int count =
        std::max(1, std::min(threads > 0 ? threads : int(std::thread::hardware_concurrency()),
                             int(lights.size())));
    std::vector<std::jthread> workers;
    for (int t = 1; t < count; ++t) workers.emplace_back(work);
    work();
    workers.clear();
    if (error) std::rethrow_exception(error);
    return images;
}

std::vector<int> parseLightList(const std::string& text, int count, const std::string& flag) {
    const auto fail = [&](const std::string& why) {
        return Error(
            fmt::format("{} '{}': {} (allowed: light numbers 1 to {}, ranges such as "
                        "1-10, separated by commas)",
                        flag, text, why, count));
    };
    const auto number = [&](const std::string& s) {
        const std::string t = trim(s);
        char* end = nullptr;
        const long v = std::strtol(t.c_str(), &end, 10);
        if (t.empty() || end != t.c_str() + t.size())
            throw fail(fmt::format("'{}' is not a number", t));
        if (v < 1 || v > count) throw fail(fmt::format("light {} does not exist", v));
        return int(v);
    };
    std::vector<int> lights;
    std::vector<bool> seen(count, false);
    std::size_t pos = 0;
    while (pos <= text.size()) {
        const std::size_t comma = std::min(text.find(',', pos), text.size());
        const std::string item = text.substr(pos, comma - pos);
        const std::size_t dash = item.find('-');
        const int first = number(item.substr(0, dash));
        const int last = dash == std::string::npos ? first : number(item.substr(dash + 1));
        if (last < first) throw fail(fmt::format("range '{}' is descending", trim(item)));
        for (int l = first; l <= last; ++l) {
            if (seen[l - 1]) throw fail(fmt::format("light {} is listed twice", l));
            seen[l - 1] = true;
            lights.push_back(l - 1);
        }
        pos = comma + 1;
    }
    return lights;
}

}  // namespace phongfit
