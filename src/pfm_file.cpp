#include "pfm_file.h"

#include <fmt/format.h>

#include <algorithm>
#include <bit>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <vector>

#include "error.h"
#include "image_limits.h"

namespace phongfit {
namespace {

// The header is three tokens after the magic; real ones take a few dozen bytes.
constexpr std::size_t kMostHeaderBytes = 256;

struct PfmHeader {
    int channels = 0;
    std::int64_t width = 0, height = 0;
    bool bigEndian = false;
    std::size_t bytes = 0;  // the header's, up to and including the byte after the scale
};

Error pfmError(const std::string& path, const std::string& what) {
    return Error(fmt::format("cannot read PFM image '{}': {}", path, what));
}

// Netpbm's whitespace: space, tab, newline, vertical tab, form feed, carriage return.
bool isPfmSpace(char c) { return std::isspace(static_cast<unsigned char>(c)) != 0; }

PfmHeader parseHeader(const std::string& path, const std::string& text) {
    const auto bad = [&](const std::string& what) { return pfmError(path, what); };
    if (text.size() < 3 || text[0] != 'P' || (text[1] != 'F' && text[1] != 'f') ||
        !isPfmSpace(text[2]))
        throw bad("it does not start with \"PF\" (RGB) or \"Pf\" (grey)");
    PfmHeader h;
    h.channels = text[1] == 'F' ? 3 : 1;
    std::size_t at = 2;
    // The next whitespace-separated token, empty where the header ends first.
    const auto token = [&] {
        while (at < text.size() && isPfmSpace(text[at])) ++at;
        const std::size_t begin = at;
        while (at < text.size() && !isPfmSpace(text[at])) ++at;
        return text.substr(begin, at - begin);
    };
    for (std::int64_t* size : {&h.width, &h.height}) {
        const std::string t = token();
        // At most 9 digits: no overflow before the limit is checked.
        if (t.empty() || t.size() > 9 || !std::all_of(t.begin(), t.end(), [](char c) {
                return std::isdigit(static_cast<unsigned char>(c)) != 0;
            }))
            throw bad(fmt::format("its {} is '{}', not a whole number of pixels",
                                  size == &h.width ? "width" : "height", t));
        *size = std::stoll(t);
    }
    const std::string scale = token();
    char* end = nullptr;
    const double s = scale.empty() ? 0.0 : std::strtod(scale.c_str(), &end);
    if (scale.empty() || end != scale.c_str() + scale.size() || !std::isfinite(s) || s == 0)
        throw bad(
            fmt::format("its scale is '{}': a finite non-zero number is needed (its sign "
                        "gives the byte order)",
                        scale));
    // Exactly one whitespace byte ends the header.
    if (at >= text.size() || !isPfmSpace(text[at]))
        throw bad("its header does not end in one whitespace byte after the scale");
    h.bigEndian = s > 0;
    h.bytes = at + 1;
    if (h.width < 1 || h.height < 1)
        throw bad(fmt::format("it is {} x {} pixels: it has none", h.width, h.height));
    if (h.width * h.height > kMaxImagePixels)
        throw bad(fmt::format("it declares {} x {} pixels, more than the {} allowed", h.width,
                              h.height, kMaxImagePixels));
    return h;
}

}  // namespace

Image readPfm(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    std::error_code ec;
    const std::uintmax_t fileBytes = std::filesystem::file_size(path, ec);
    if (!in || ec) throw pfmError(path, "cannot open it");
    std::string text(std::min<std::uintmax_t>(fileBytes, kMostHeaderBytes), '\0');
    in.read(text.data(), std::streamsize(text.size()));
    const PfmHeader h = parseHeader(path, text);
    const std::uintmax_t values = std::uintmax_t(h.width * h.height) * std::uintmax_t(h.channels);
    if (fileBytes - h.bytes != values * sizeof(float))
        throw pfmError(path, fmt::format("its header says {} x {} pixels of {} float{}, {} bytes, "
                                         "but {} bytes follow it",
                                         h.width, h.height, h.channels, h.channels > 1 ? "s" : "",
                                         values * sizeof(float), fileBytes - h.bytes));
    Image image(int(h.width), int(h.height));
    image.decoding = "PFM, linear";
    // Row by row into the image, so that reading takes no more than the image itself.
    const bool swap = h.bigEndian != (std::endian::native == std::endian::big);
    std::vector<std::uint32_t> row(std::size_t(h.width) * std::size_t(h.channels));
    in.seekg(std::streamoff(h.bytes));
    for (int r = 0; r < image.height; ++r) {
        in.read(reinterpret_cast<char*>(row.data()), std::streamsize(row.size() * sizeof(float)));
        if (!in) throw pfmError(path, "I/O error");
        if (swap)
            for (std::uint32_t& w : row) w = __builtin_bswap32(w);
        // Rows are stored from the bottom up.
        const int y = image.height - 1 - r;
        for (int x = 0; x < image.width; ++x) {
            Color<float> c;
            for (int k = 0; k < 3; ++k)
                c[k] = std::bit_cast<float>(row[std::size_t(x) * std::size_t(h.channels) +
                                                std::size_t(h.channels == 3 ? k : 0)]);
            image.set(x, y, c);
        }
    }
    return image;
}

}  // namespace phongfit
