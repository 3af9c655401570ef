// What an image file may make phongfit allocate. Every reader checks the size a file declares in
// its header against these limits, and against the file's own size, before any pixel buffer is
// allocated (by phongfit, OpenEXR or OpenCV): a few hostile bytes cannot ask for gigabytes.
#pragma once

#include <cstdint>
#include <string>

namespace phongfit {

// Pixels in one image: an 8192 x 8192 image (reading it takes 13 bytes a pixel, 870 MB).
constexpr std::int64_t kMaxImagePixels = std::int64_t(1) << 26;
// Pixels an image may declare per byte of its file, beyond the first kFreeImagePixels: what its
// compression can reach on a constant image, with a margin. A file of a few bytes cannot ask for
// a large image, and decoding one is bounded by the file's size.
constexpr std::int64_t kFreeImagePixels = std::int64_t(1) << 20;
// DWAA/DWAB EXR (a constant 8192 x 8192 DWAB image has about 13000) and arithmetic-coded JPEG.
constexpr std::int64_t kMaxPixelsPerByteSparse = std::int64_t(1) << 16;
// PIZ EXR (its run-length codes take 9 bits or more per 255 values).
constexpr std::int64_t kMaxPixelsPerBytePiz = 4096;
// Every other EXR compression (deflate inflates at most 1032 bytes from one, and a pixel is at
// least 2 bytes), and Huffman-coded JPEG (one bit at least per 8 x 8 block).
constexpr std::int64_t kMaxPixelsPerByte = 1032;
// Decoded bytes per byte of a TIFF file (LZW inflates at most about 2700 from one, deflate 1032).
constexpr std::int64_t kMaxTiffBytesPerByte = 4096;
// Bytes one decoded block may take (an EXR chunk, a TIFF strip or tile): the decoders allocate a
// few of these at a time.
constexpr std::int64_t kMaxBlockBytes = std::int64_t(128) << 20;
// EXR header allocations (attributes, channel lists): far above any real header.
constexpr std::int64_t kMaxExrHeaderAllocation = std::int64_t(64) << 20;

// Throws Error naming the file, the declared size and the limit when the EXR file's header
// (every part of a multi-part file) declares more than the limits allow, or when its chunk offset
// tables could not fit in the file. The headers are read twice, by OpenEXRCore and as OpenEXR's
// InputFile reads them (every attribute's size must fit in the file; the data windows must
// agree), so what was checked is what InputFile will allocate for. Throws Error, too, when OpenEXR
// cannot parse the header, and when part 0 holds deep data (not an image phongfit reads).
void requireExrWithinLimits(const std::string& path);

// The frame an EXR's image is read in where it is not its data window (its display window,
// ReadOptions::exrDisplayWindow): its pixels are allocated too, against the same limits as
// declared ones. Throws Error naming the file, the size and the limit.
void requireExrFrameWithinLimits(const std::string& path, std::int64_t width, std::int64_t height);

// The same for PNG, JPEG and TIFF: throws Error unless the file's first bytes are those of one of
// these formats (only PNG when `pngOnly`) and its header's declared size is within the limits.
// Call before cv::imread: OpenCV picks its decoder by content, not by name (some decoders it
// links abort the process on a malformed file), and allocates what the header declares.
// `what` names the file's role ("image", "mask").
void requireLdrWithinLimits(const std::string& path, const char* what, bool pngOnly = false);

}  // namespace phongfit
