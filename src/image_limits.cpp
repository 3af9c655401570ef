#include "image_limits.h"

#include <fmt/format.h>
#include <openexr.h>

#include <algorithm>
#include <array>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <vector>

#include "error.h"

namespace phongfit {
namespace {

std::int64_t fileBytes(const std::string& path) {
    std::error_code ec;
    const std::uintmax_t bytes = std::filesystem::file_size(path, ec);
    if (ec) throw Error(fmt::format("cannot read image '{}': {}", path, ec.message()));
    return std::int64_t(bytes);
}

void requireDeclaredPixels(const std::string& path, std::int64_t width, std::int64_t height,
                           std::int64_t fileSize) {
    if (width < 0 || height < 0)
        throw Error(fmt::format("cannot read image '{}': its header is cut short", path));
    if (width > kMaxImagePixels || height > kMaxImagePixels || width * height > kMaxImagePixels)
        throw Error(fmt::format("image '{}' is {}x{} pixels (allowed: up to {} pixels)", path,
                                width, height, kMaxImagePixels));
    const std::int64_t pixels = width * height;
    if (pixels > kFreeImagePixels && pixels > kMaxPixelsPerFileByte * fileSize)
        throw Error(fmt::format(
            "image '{}' is {}x{} pixels in a file of {} bytes (allowed: up to {} pixels a byte "
            "beyond the first {}); the file is truncated or corrupt",
            path, width, height, fileSize, kMaxPixelsPerFileByte, kFreeImagePixels));
}

void requireBlockBytes(const std::string& path, const char* block, std::int64_t bytes) {
    if (bytes > kMaxBlockBytes)
        throw Error(fmt::format("image '{}': one {} decodes to {} bytes (allowed: up to {} bytes)",
                                path, block, bytes, kMaxBlockBytes));
}

// ---- EXR: OpenEXRCore parses the headers (it checks attribute sizes against the file) with an
// allocator capped at kMaxExrHeaderAllocation; no pixel data or chunk table is read.

thread_local std::string exrMessage;

void recordExrError(exr_const_context_t, exr_result_t code, const char* message) {
    if (exrMessage.empty()) exrMessage = message ? message : exr_get_default_error_message(code);
}

void* cappedExrAlloc(std::size_t bytes) {
    return bytes > std::size_t(kMaxExrHeaderAllocation) ? nullptr : std::malloc(bytes);
}

class ExrHeaders {
public:
    explicit ExrHeaders(const std::string& path) : path_(path) {
        exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
        init.error_handler_fn = recordExrError;
        init.alloc_fn = cappedExrAlloc;
        init.free_fn = std::free;
        exrMessage.clear();
        const exr_result_t result = exr_start_read(&context_, path.c_str(), &init);
        // OpenEXRCore reports some inconsistencies (an attribute of the wrong size) and reads on
        // with its own guess, where OpenEXR's InputFile may guess otherwise: any complaint
        // refuses the file, so both libraries read the header that was checked.
        if (result != EXR_ERR_SUCCESS || !exrMessage.empty()) {
            exr_finish(&context_);
            throw Error(fmt::format(
                "cannot read EXR image '{}': {}", path,
                exrMessage.empty() ? exr_get_default_error_message(result) : exrMessage));
        }
    }
    ~ExrHeaders() { exr_finish(&context_); }
    ExrHeaders(const ExrHeaders&) = delete;
    ExrHeaders& operator=(const ExrHeaders&) = delete;

    // Throws Error with OpenEXR's message unless `result` is success.
    void check(exr_result_t result) const {
        if (result != EXR_ERR_SUCCESS)
            throw Error(fmt::format("cannot read EXR image '{}': {}", path_,
                                    exr_get_default_error_message(result)));
    }
    exr_const_context_t context() const { return context_; }

private:
    std::string path_;
    exr_context_t context_ = nullptr;
};

// ---- PNG, JPEG, TIFF: the few header fields that give the size, read at their offsets.

constexpr std::uint64_t kBeyondAnyFile = std::uint64_t(1) << 62;

class HeaderBytes {
public:
    explicit HeaderBytes(const std::string& path) : in_(path, std::ios::binary) {}
    // The unsigned integer of `bytes` bytes at `offset`, or -1 past the end of the file (or when
    // it is 2^62 or more).
    std::int64_t uint(std::int64_t offset, int bytes, bool bigEndian) {
        std::array<unsigned char, 8> b{};
        in_.clear();
        in_.seekg(offset);
        if (offset < 0 || !in_.read(reinterpret_cast<char*>(b.data()), bytes)) return -1;
        std::uint64_t value = 0;
        for (int i = 0; i < bytes; ++i)
            value |= std::uint64_t(b[bigEndian ? bytes - 1 - i : i]) << (8 * i);
        // No file is 2^62 bytes long: larger values are offsets past its end, and stay far from
        // overflow in the sums made of them.
        return value >= kBeyondAnyFile ? -1 : std::int64_t(value);
    }

private:
    std::ifstream in_;
};

// deflate (PNG's compression) inflates at most 1032 bytes from one.
constexpr std::int64_t kMaxDeflateRatio = 1032;

[[noreturn]] void invalidHeader(const std::string& path, const char* what, const char* why) {
    throw Error(fmt::format("cannot read {} '{}': not a valid image file ({})", what, path, why));
}

void requirePngWithinLimits(const std::string& path, const char* what, std::int64_t size) {
    HeaderBytes file(path);
    if (file.uint(12, 4, true) != 0x49484452)  // "IHDR"
        invalidHeader(path, what, "a PNG starts with its IHDR header");
    const std::int64_t width = file.uint(16, 4, true), height = file.uint(20, 4, true);
    const std::int64_t depth = file.uint(24, 1, true), colour = file.uint(25, 1, true);
    constexpr std::array<int, 7> kChannels = {1, 0, 3, 1, 2, 0, 4};  // by colour type
    if (depth <= 0 || colour < 0 || colour > 6 || kChannels[colour] == 0)
        invalidHeader(path, what, "a PNG's IHDR has a bit depth and a known colour type");
    requireDeclaredPixels(path, width, height, size);
    const std::int64_t inflated = height * ((width * kChannels[colour] * depth + 7) / 8 + 1);
    if (inflated > kMaxDeflateRatio * size)
        throw Error(fmt::format(
            "image '{}' is {}x{} pixels, {} bytes to inflate from a file of {} bytes (deflate "
            "inflates at most {} bytes from one); the file is truncated or corrupt",
            path, width, height, inflated, size, kMaxDeflateRatio));
}

void requireJpegWithinLimits(const std::string& path, const char* what, std::int64_t size) {
    HeaderBytes file(path);
    std::int64_t pos = 2;  // after the start-of-image marker
    while (pos < size) {
        // As libjpeg does, skip what is not a marker, then the 0xFF fill bytes.
        while (pos < size && file.uint(pos, 1, true) != 0xff) ++pos;
        while (pos < size && file.uint(pos, 1, true) == 0xff) ++pos;
        const std::int64_t marker = file.uint(pos++, 1, true);
        if (marker < 0) break;
        if (marker == 0xd8 || marker == 0x01 || (marker >= 0xd0 && marker <= 0xd7)) continue;
        if (marker == 0xd9 || marker == 0xda) break;  // end of image, start of scan
        const std::int64_t length = file.uint(pos, 2, true);
        if (length < 2) break;
        const bool frame =
            marker >= 0xc0 && marker <= 0xcf && marker != 0xc4 && marker != 0xc8 && marker != 0xcc;
        if (frame) {
            requireDeclaredPixels(path, file.uint(pos + 5, 2, true), file.uint(pos + 3, 2, true),
                                  size);
            return;
        }
        pos += length;
    }
    invalidHeader(path, what, "a JPEG has a frame header before its image data");
}

void requireTiffWithinLimits(const std::string& path, const char* what, std::int64_t size) {
    HeaderBytes file(path);
    const bool bigEndian = file.uint(0, 1, true) == 'M';
    const bool big = file.uint(2, 2, bigEndian) == 43;  // BigTIFF: 8-byte offsets and counts
    const int offsetBytes = big ? 8 : 4, entryBytes = big ? 20 : 12;
    const std::int64_t directory = file.uint(big ? 8 : 4, offsetBytes, bigEndian);
    const std::int64_t entries = file.uint(directory, big ? 8 : 2, bigEndian);
    const std::int64_t first = directory + (big ? 8 : 2);
    if (directory < 0 || entries < 0 || entries > (size - first) / entryBytes)
        invalidHeader(path, what, "a TIFF's first directory lies within the file");
    std::int64_t width = -1, height = -1, bits = 1, samples = 1, rowsPerStrip = -1;
    std::int64_t tileWidth = -1, tileHeight = -1;
    for (std::int64_t i = 0; i < entries; ++i) {
        const std::int64_t entry = first + i * entryBytes;
        const std::int64_t tag = file.uint(entry, 2, bigEndian);
        const std::int64_t type = file.uint(entry + 2, 2, bigEndian);
        const std::int64_t count = file.uint(entry + 4, offsetBytes, bigEndian);
        const int valueBytes = type == 3 ? 2 : type == 4 ? 4 : type == 16 ? 8 : 0;  // short, long
        if (valueBytes == 0 || count < 1) continue;
        std::int64_t at = entry + 4 + offsetBytes;
        if (count > offsetBytes / valueBytes) at = file.uint(at, offsetBytes, bigEndian);
        const std::int64_t value = file.uint(at, valueBytes, bigEndian);  // the first value
        switch (tag) {
            case 256:
                width = value;
                break;
            case 257:
                height = value;
                break;
            case 258:
                bits = value;
                break;
            case 277:
                samples = value;
                break;
            case 278:
                rowsPerStrip = value;
                break;
            case 322:
                tileWidth = value;
                break;
            case 323:
                tileHeight = value;
                break;
            default:
                break;
        }
    }
    if (width < 0 || height < 0)
        invalidHeader(path, what, "a TIFF's first directory gives the image width and length");
    requireDeclaredPixels(path, width, height, size);
    const bool tiled = tileWidth > 0 && tileHeight > 0;
    const double blockPixels =
        tiled ? double(tileWidth) * double(tileHeight)
              : double(width) * double(rowsPerStrip < 0 ? height : std::min(rowsPerStrip, height));
    const double bytes = blockPixels * double(std::max<std::int64_t>(samples, 1)) *
                         double((std::max<std::int64_t>(bits, 1) + 7) / 8);
    requireBlockBytes(path, tiled ? "tile" : "strip", std::int64_t(std::min(bytes, 0x1p62)));
}

}  // namespace

void requireLdrWithinLimits(const std::string& path, const char* what, bool pngOnly) {
    HeaderBytes file(path);
    const std::int64_t head = file.uint(0, 4, true);
    const bool png = head == 0x89504e47 && file.uint(4, 4, true) == 0x0d0a1a0a;
    const bool jpeg = head >> 8 == 0xffd8ff;
    const bool tiff =
        head == 0x49492a00 || head == 0x4d4d002a || head == 0x49492b00 || head == 0x4d4d002b;
    if (pngOnly && !png)
        throw Error(fmt::format(
            "cannot read {} '{}': not a valid image file (allowed are 8- or 16-bit PNGs)", what,
            path));
    if (!png && !jpeg && !tiff)
        throw Error(fmt::format(
            "cannot read {} '{}': not a valid image file (allowed: PNG, JPEG or TIFF content)",
            what, path));
    const std::int64_t size = fileBytes(path);
    if (png) requirePngWithinLimits(path, what, size);
    if (jpeg) requireJpegWithinLimits(path, what, size);
    if (tiff) requireTiffWithinLimits(path, what, size);
}

ExrWindow requireExrWithinLimits(const std::string& path) {
    const std::int64_t fileSize = fileBytes(path);
    const ExrHeaders headers(path);
    const exr_const_context_t context = headers.context();
    int parts = 0;
    headers.check(exr_get_count(context, &parts));
    std::int64_t chunks = 0;
    ExrWindow first;
    for (int part = 0; part < parts; ++part) {
        exr_storage_t storage;
        headers.check(exr_get_storage(context, part, &storage));
        if (part == 0 && storage != EXR_STORAGE_SCANLINE && storage != EXR_STORAGE_TILED)
            throw Error(fmt::format(
                "cannot read EXR image '{}': it holds deep data (allowed: scanline or tiled "
                "images)",
                path));
        exr_attr_box2i_t window;
        headers.check(exr_get_data_window(context, part, &window));
        if (part == 0) first = {window.min.x, window.min.y, window.max.x, window.max.y};
        const std::int64_t width = std::int64_t(window.max.x) - window.min.x + 1;
        const std::int64_t height = std::int64_t(window.max.y) - window.min.y + 1;
        requireDeclaredPixels(path, width, height, fileSize);
        std::int32_t partChunks = 0;
        headers.check(exr_get_chunk_count(context, part, &partChunks));
        chunks += partChunks;
        std::uint64_t chunkBytes = 0;
        headers.check(exr_get_chunk_unpacked_size(context, part, &chunkBytes));
        requireBlockBytes(path, "chunk",
                          std::int64_t(std::min<std::uint64_t>(chunkBytes, 1ull << 62)));
        if (storage == EXR_STORAGE_TILED) {
            std::uint32_t tileWidth = 0, tileHeight = 0;
            exr_tile_level_mode_t levels;
            exr_tile_round_mode_t rounding;
            headers.check(exr_get_tile_descriptor(context, part, &tileWidth, &tileHeight, &levels,
                                                  &rounding));
            // OpenEXR reads a tiled file through a buffer of one row of tiles, as float RGB.
            requireBlockBytes(path, "row of tiles", width * std::int64_t(tileHeight) * 12);
        }
    }
    // Each chunk has an 8-byte entry in its part's offset table and at least 8 bytes of header.
    if (chunks * 16 > fileSize)
        throw Error(fmt::format(
            "image '{}' declares {} chunks in a file of {} bytes (each takes at least 16 bytes); "
            "the file is truncated or corrupt",
            path, chunks, fileSize));
    return first;
}

}  // namespace phongfit
