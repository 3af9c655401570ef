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

// `perByte`: the pixels a byte of the file may hold beyond kFreeImagePixels.
void requireDeclaredPixels(const std::string& path, std::int64_t width, std::int64_t height,
                           std::int64_t fileSize, std::int64_t perByte) {
    if (width < 0 || height < 0)
        throw Error(fmt::format("cannot read image '{}': its header is cut short", path));
    if (width > kMaxImagePixels || height > kMaxImagePixels || width * height > kMaxImagePixels)
        throw Error(fmt::format("image '{}' is {}x{} pixels (allowed: up to {} pixels)", path,
                                width, height, kMaxImagePixels));
    const std::int64_t pixels = width * height;
    if (pixels > kFreeImagePixels && pixels > perByte * fileSize)
        throw Error(fmt::format(
            "image '{}' is {}x{} pixels in a file of {} bytes (allowed: up to {} pixels a byte "
            "beyond the first {}); the file is truncated or corrupt",
            path, width, height, fileSize, perByte, kFreeImagePixels));
}

void requireBlockBytes(const std::string& path, const char* block, std::int64_t bytes) {
    if (bytes > kMaxBlockBytes)
        throw Error(fmt::format("image '{}': one {} decodes to {} bytes (allowed: up to {} bytes)",
                                path, block, bytes, kMaxBlockBytes));
}

// ---- EXR: OpenEXRCore parses the headers (it checks attribute sizes against the file) with an
// allocator capped at kMaxExrHeaderAllocation; no pixel data or chunk table is read.

[[noreturn]] void invalidExr(const std::string& path, const char* why) {
    throw Error(fmt::format("cannot read EXR image '{}': {}; the file is corrupt", path, why));
}

// A data window as four numbers, min x, min y, max x, max y.
using ExrWindowValues = std::array<std::int32_t, 4>;

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
    requireDeclaredPixels(path, width, height, size, kMaxPixelsPerByte);
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
            const bool arithmetic = marker >= 0xc9;  // SOF9-11, SOF13-15
            requireDeclaredPixels(path, file.uint(pos + 5, 2, true), file.uint(pos + 3, 2, true),
                                  size, arithmetic ? kMaxPixelsPerByteSparse : kMaxPixelsPerByte);
            return;
        }
        pos += length;
    }
    invalidHeader(path, what, "a JPEG has a frame header before its image data");
}

// Bytes of a TIFF integer type's value (BYTE, SBYTE, SHORT, SSHORT, LONG, SLONG, LONG8, SLONG8);
// 0 for the others.
int tiffIntegerBytes(std::int64_t type) {
    switch (type) {
        case 1:
        case 6:
            return 1;
        case 3:
        case 8:
            return 2;
        case 4:
        case 9:
            return 4;
        case 16:
        case 17:
            return 8;
        default:
            return 0;
    }
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
    // A tag listed twice counts at its largest: libtiff keeps one of them, and which is not ours
    // to guess (png_fuzz found a width of 65532, then 1).
    std::int64_t width = -1, height = -1, bits = 1, samples = 1;
    std::int64_t tileWidth = -1, tileHeight = -1;
    std::vector<std::int64_t> rowsPerStrip;
    for (std::int64_t i = 0; i < entries; ++i) {
        const std::int64_t entry = first + i * entryBytes;
        const std::int64_t tag = file.uint(entry, 2, bigEndian);
        const std::int64_t type = file.uint(entry + 2, 2, bigEndian);
        const std::int64_t count = file.uint(entry + 4, offsetBytes, bigEndian);
        // Every integer type, signed too: libtiff reads an integer tag of any of them (png_fuzz
        // found RowsPerStrip as a signed short), and a signed value counts as unsigned here, at
        // its largest.
        const int valueBytes = tiffIntegerBytes(type);
        if (valueBytes == 0 || count < 1) continue;
        std::int64_t at = entry + 4 + offsetBytes;
        if (count > offsetBytes / valueBytes) at = file.uint(at, offsetBytes, bigEndian);
        const std::int64_t value = file.uint(at, valueBytes, bigEndian);  // the first value
        switch (tag) {
            case 256:
                width = std::max(width, value);
                break;
            case 257:
                height = std::max(height, value);
                break;
            case 258:
                bits = std::max(bits, value);
                break;
            case 277:
                samples = std::max(samples, value);
                break;
            case 278:
                rowsPerStrip.push_back(value);
                break;
            case 322:
                tileWidth = std::max(tileWidth, value);
                break;
            case 323:
                tileHeight = std::max(tileHeight, value);
                break;
            default:
                break;
        }
    }
    if (width < 0 || height < 0)
        invalidHeader(path, what, "a TIFF's first directory gives the image width and length");
    const std::int64_t pixelBytes = std::clamp<std::int64_t>(samples, 1, 1 << 16) *
                                    ((std::clamp<std::int64_t>(bits, 1, 64) + 7) / 8);
    requireDeclaredPixels(path, width, height, size,
                          std::max<std::int64_t>(1, kMaxTiffBytesPerByte / pixelBytes));
    // OpenCV sizes a strip's buffer by RowsPerStrip as declared: only 0 and 2^32 - 1 mean the
    // whole image, not values past the image's length (png_fuzz found a 65532 x 3 image with
    // 14851 rows per strip, for which OpenCV asked for 3.9 GB).
    const bool tiled = tileWidth > 0 && tileHeight > 0;
    std::int64_t stripRows = rowsPerStrip.empty() ? height : 0;
    for (std::int64_t rows : rowsPerStrip)
        stripRows = std::max(stripRows, rows <= 0 || rows == 0xFFFFFFFF ? height : rows);
    const double blockPixels =
        tiled ? double(tileWidth) * double(tileHeight) : double(width) * double(stripRows);
    const double bytes = blockPixels * double(std::max<std::int64_t>(samples, 1)) *
                         double((std::max<std::int64_t>(bits, 1) + 7) / 8);
    requireBlockBytes(path, tiled ? "tile" : "strip", std::int64_t(std::min(bytes, 0x1p62)));
}

std::int64_t exrPixelsPerByte(exr_compression_t compression) {
    switch (compression) {
        case EXR_COMPRESSION_DWAA:
        case EXR_COMPRESSION_DWAB:
            return kMaxPixelsPerByteSparse;
        case EXR_COMPRESSION_PIZ:
            return kMaxPixelsPerBytePiz;
        default:
            return kMaxPixelsPerByte;
    }
}

// The bytes an attribute of a self-delimited type takes as InputFile reads it, from `pos`; -1
// where it runs past the end of the file.
std::int64_t selfDelimitedBytes(HeaderBytes& file, std::int64_t pos, const std::string& type,
                                std::int64_t declared, int maxName) {
    const std::int64_t start = pos;
    if (type == "preview") {
        const std::int64_t width = file.uint(pos, 4, false), height = file.uint(pos + 4, 4, false);
        return width < 0 || height < 0 ? -1 : 8 + 4 * width * height;
    }
    if (type == "stringvector") {  // strings of a 4-byte length each, until the declared size
        while (pos - start < declared) {
            const std::int64_t length = file.uint(pos, 4, false);
            if (length < 0 || length > declared) return -1;
            pos += 4 + length;
        }
        return pos - start;
    }
    for (;;) {  // chlist: name, 16 bytes of type, linearity, reserved and sampling; empty name ends
        int length = 0;
        for (std::int64_t c; (c = file.uint(pos++, 1, false)) != 0; ++length)
            if (c < 0 || length >= maxName) return -1;
        if (length == 0) return pos - start;
        pos += 16;
    }
}

// The headers as OpenEXR's InputFile reads them (name, type, 4-byte size, value; an empty name
// ends a header, and in a multi-part file an empty header ends the list): every attribute must
// fit in the file, as InputFile allocates what the size says before reading, and each part's
// dataWindow must be the one OpenEXRCore read.
void requireRawExrHeaders(const std::string& path, std::int64_t size,
                          const std::vector<ExrWindowValues>& windows) {
    HeaderBytes file(path);
    const std::int64_t version = file.uint(4, 4, false);
    const bool multipart = version >= 0 && (version & 0x1000) != 0;
    const int maxName = version >= 0 && (version & 0x400) != 0 ? 255 : 31;
    std::int64_t pos = 8;
    const auto readName = [&](std::string& name) {
        name.clear();
        for (std::int64_t c; (c = file.uint(pos++, 1, false)) != 0;) {
            if (c < 0 || int(name.size()) >= maxName) return false;
            name += char(c);
        }
        return true;
    };
    std::string name, type;
    for (std::size_t part = 0;; ++part) {
        if (!readName(name))
            invalidExr(path, "an attribute name runs past its limit or the end of the file");
        if (name.empty() && (!multipart || part > 0)) break;  // end of the (last) header
        for (;;) {
            if (name.empty()) break;  // end of this part's header
            if (!readName(type))
                invalidExr(path, "an attribute type runs past its limit or the end of the file");
            const std::int64_t bytes = file.uint(pos, 4, false);
            pos += 4;
            if (bytes < 0 || bytes > size - pos)
                throw Error(fmt::format(
                    "cannot read EXR image '{}': attribute '{}' declares {} bytes, beyond the "
                    "end of the file ({} bytes)",
                    path, name, bytes, size));
            // InputFile reads these three types by their contents, not by the size: a size that
            // disagrees with the contents sends it elsewhere in the file than OpenEXRCore.
            if (type == "chlist" || type == "stringvector" || type == "preview")
                if (selfDelimitedBytes(file, pos, type, bytes, maxName) != bytes)
                    invalidExr(path, "an attribute's size disagrees with its contents");
            if (name == "dataWindow" && type == "box2i" && bytes >= 16) {
                const ExrWindowValues window = {std::int32_t(file.uint(pos, 4, false)),
                                                std::int32_t(file.uint(pos + 4, 4, false)),
                                                std::int32_t(file.uint(pos + 8, 4, false)),
                                                std::int32_t(file.uint(pos + 12, 4, false))};
                if (part >= windows.size() || !(window == windows[part]))
                    invalidExr(path, "its header reads as two different data windows");
            }
            pos += bytes;
            if (!readName(name))
                invalidExr(path, "an attribute name runs past its limit or the end of the file");
        }
        if (!multipart) break;
    }
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

void requireExrFrameWithinLimits(const std::string& path, std::int64_t width, std::int64_t height) {
    requireDeclaredPixels(path, width, height, fileBytes(path), kMaxPixelsPerByte);
}

void requireExrWithinLimits(const std::string& path) {
    const std::int64_t fileSize = fileBytes(path);
    const ExrHeaders headers(path);
    const exr_const_context_t context = headers.context();
    int parts = 0;
    headers.check(exr_get_count(context, &parts));
    std::int64_t chunks = 0;
    std::vector<ExrWindowValues> windows;
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
        windows.push_back({window.min.x, window.min.y, window.max.x, window.max.y});
        const std::int64_t width = std::int64_t(window.max.x) - window.min.x + 1;
        const std::int64_t height = std::int64_t(window.max.y) - window.min.y + 1;
        exr_compression_t compression;
        headers.check(exr_get_compression(context, part, &compression));
        requireDeclaredPixels(path, width, height, fileSize, exrPixelsPerByte(compression));
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
    requireRawExrHeaders(path, fileSize, windows);
}

}  // namespace phongfit
