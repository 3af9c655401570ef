// What an image file may make phongfit allocate. Every reader checks the size a file declares in
// its header against these limits, and against the file's own size, before any pixel buffer is
// allocated (by phongfit, OpenEXR or OpenCV): a few hostile bytes cannot ask for gigabytes.
#pragma once

#include <cstdint>
#include <string>

namespace phongfit {

// Pixels in one image: an 8192 x 8192 image (reading it takes 13 bytes a pixel, 870 MB).
constexpr std::int64_t kMaxImagePixels = std::int64_t(1) << 26;
// Pixels an image may declare per byte of its file, beyond kFreeImagePixels. Generous for every
// compression in use (a constant 8192 x 8192 DWAB EXR has about 13000), and it stops a file of a
// few bytes from asking for the largest image.
constexpr std::int64_t kMaxPixelsPerFileByte = std::int64_t(1) << 16;
constexpr std::int64_t kFreeImagePixels = std::int64_t(1) << 20;
// Bytes one decoded block may take (an EXR chunk, a TIFF strip or tile): the decoders allocate a
// few of these at a time.
constexpr std::int64_t kMaxBlockBytes = std::int64_t(128) << 20;
// EXR header allocations (attributes, channel lists): far above any real header.
constexpr std::int64_t kMaxExrHeaderAllocation = std::int64_t(64) << 20;

// An EXR part's data window, as OpenEXRCore read it.
struct ExrWindow {
    int minX = 0, minY = 0, maxX = -1, maxY = -1;
    bool operator==(const ExrWindow&) const = default;
};

// Throws Error naming the file, the declared size and the limit when the EXR file's header
// (every part of a multi-part file) declares more than the limits allow, or when its chunk offset
// tables could not fit in the file. Throws Error, too, when OpenEXR cannot parse the header, and
// when part 0 holds deep data (not an image phongfit reads). Returns part 0's data window, which
// the reader compares with what OpenEXR's InputFile reads.
ExrWindow requireExrWithinLimits(const std::string& path);

// The same for PNG, JPEG and TIFF: throws Error unless the file's first bytes are those of one of
// these formats (only PNG when `pngOnly`) and its header's declared size is within the limits.
// Call before cv::imread: OpenCV picks its decoder by content, not by name (some decoders it
// links abort the process on a malformed file), and allocates what the header declares.
// `what` names the file's role ("image", "mask").
void requireLdrWithinLimits(const std::string& path, const char* what, bool pngOnly = false);

}  // namespace phongfit
