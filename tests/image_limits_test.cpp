// What image headers may declare (image_limits.h): hostile headers are refused with one line naming
// the file, the declared size and the limit, before anything is allocated; real files still read.
#include "image_limits.h"

#include <ImfChannelList.h>
#include <ImfDeepScanLineOutputFile.h>
#include <ImfHeader.h>
#include <ImfPartType.h>
#include <gtest/gtest.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <string>
#include <utility>
#include <vector>

#include "capture.h"
#include "error_of.h"
#include "image.h"
#include "temp_dir.h"

namespace phongfit {
namespace {

using test::errorOf;

std::string le32(std::uint32_t v) {
    return {char(v & 0xff), char(v >> 8 & 0xff), char(v >> 16 & 0xff), char(v >> 24)};
}
std::string be32(std::uint32_t v) {
    return {char(v >> 24), char(v >> 16 & 0xff), char(v >> 8 & 0xff), char(v & 0xff)};
}
std::string be16(std::uint32_t v) { return {char(v >> 8 & 0xff), char(v & 0xff)}; }
std::string le16(std::uint32_t v) { return {char(v & 0xff), char(v >> 8 & 0xff)}; }

std::string attribute(const std::string& name, const std::string& type, const std::string& value) {
    return name + '\0' + type + '\0' + le32(std::uint32_t(value.size())) + value;
}

// A scanline (or tiled) EXR header written by hand, followed by `tail` bytes: what a hostile file
// can declare without holding the data.
struct ExrHeaderSpec {
    int width = 4, height = 4;
    int floatChannels = 3;
    int compression = 0;  // none: one scanline a chunk
    int tileWidth = 0, tileHeight = 0;
    std::size_t tail = 64;
};

std::string exrBytes(const ExrHeaderSpec& spec) {
    std::string channels;
    for (int c = 0; c < spec.floatChannels; ++c) {  // B, G, R, then X3, X4, ...: sorted
        channels.append(c < 3 ? std::string(1, "BGR"[c]) : std::to_string(c).insert(0, 1, 'X'));
        channels.append(1, '\0');
        channels.append(le32(2) + std::string(4, '\0') + le32(1) + le32(1));
    }
    channels += '\0';
    const std::string box = le32(0) + le32(0) + le32(std::uint32_t(spec.width - 1)) +
                            le32(std::uint32_t(spec.height - 1));
    const std::string one = le32(0x3f800000);  // 1.0f
    std::string header = le32(20000630) + le32(spec.tileWidth > 0 ? 0x202 : 2);
    header += attribute("channels", "chlist", channels);
    header += attribute("compression", "compression", std::string(1, char(spec.compression)));
    header += attribute("dataWindow", "box2i", box);
    header += attribute("displayWindow", "box2i", box);
    header += attribute("lineOrder", "lineOrder", std::string(1, '\0'));
    header += attribute("pixelAspectRatio", "float", one);
    header += attribute("screenWindowCenter", "v2f", le32(0) + le32(0));
    header += attribute("screenWindowWidth", "float", one);
    if (spec.tileWidth > 0)
        header += attribute("tiles", "tiledesc",
                            le32(std::uint32_t(spec.tileWidth)) +
                                le32(std::uint32_t(spec.tileHeight)) + std::string(1, '\0'));
    return header + '\0' + std::string(spec.tail, '\0');
}

class ImageLimitsTest : public ::testing::Test {
protected:
    test::TempDir dir{"image_limits"};
    std::string write(const std::string& name, const std::string& bytes) {
        return dir.write(name, bytes).string();
    }
    // The error of the limits check, which readImage must give too.
    std::string exrError(const ExrHeaderSpec& spec) {
        const std::string path = write("h.exr", exrBytes(spec));
        const std::string checked = errorOf([&] { requireExrWithinLimits(path); });
        EXPECT_EQ(errorOf([&] { readImage(path); }), checked);
        EXPECT_NE(checked.find(path), std::string::npos) << checked;
        return checked;
    }
};

TEST_F(ImageLimitsTest, HandWrittenExrHeaderIsAcceptedWhenItsDataFits) {
    // 4x4, 4 chunks of 16 bytes at least: within every limit. The pixels themselves are missing,
    // which OpenEXR finds when reading them.
    const std::string path = write("h.exr", exrBytes({}));
    EXPECT_EQ(errorOf([&] { requireExrWithinLimits(path); }), "(no phongfit::Error)");
    EXPECT_NE(errorOf([&] { readImage(path); }).find("cannot read EXR image '" + path + "'"),
              std::string::npos);
}

TEST_F(ImageLimitsTest, ExrDeclaringTooManyPixelsIsRefused) {
    const std::string e = exrError({.width = 100000, .height = 100000});
    EXPECT_NE(e.find("is 100000x100000 pixels (allowed: up to 67108864 pixels)"), std::string::npos)
        << e;
}

TEST_F(ImageLimitsTest, ExrDeclaringMorePixelsThanItsFileCanHoldIsRefused) {
    // 8192 x 8192 in 256-line chunks (DWAB): 67 M pixels from under 1 kB.
    const std::string e = exrError({.width = 8192, .height = 8192, .compression = 9, .tail = 200});
    EXPECT_NE(e.find("is 8192x8192 pixels in a file of"), std::string::npos) << e;
    EXPECT_NE(e.find("(allowed: up to 65536 pixels a byte beyond the first 1048576)"),
              std::string::npos)
        << e;
}

TEST_F(ImageLimitsTest, ExrWhoseChunkTableCannotFitInTheFileIsRefused) {
    // 1000 uncompressed scanlines are 1000 chunks: at least 16 kB of offsets and chunk headers.
    const std::string e = exrError({.width = 8, .height = 1000});
    EXPECT_NE(e.find("declares 1000 chunks in a file of"), std::string::npos) << e;
    EXPECT_NE(e.find("(each takes at least 16 bytes)"), std::string::npos) << e;
}

TEST_F(ImageLimitsTest, ExrWhoseChunkDecodesToTooManyBytesIsRefused) {
    // One scanline of 4 M pixels in 12 float channels: 192 MiB to decode in one chunk (the file is
    // large enough for 4 M pixels to pass the density check).
    const std::string e =
        exrError({.width = 1 << 22, .height = 1, .floatChannels = 12, .tail = 4096});
    EXPECT_NE(e.find("one chunk decodes to 201326592 bytes (allowed: up to 134217728 bytes)"),
              std::string::npos)
        << e;
}

TEST_F(ImageLimitsTest, TiledExrWhoseRowOfTilesIsTooLargeIsRefused) {
    // Tiles of 1 x 2^22 on a 64-pixel-wide image: OpenEXR would buffer 64 x 2^22 float RGB.
    const std::string e =
        exrError({.width = 64, .height = 64, .tileWidth = 1, .tileHeight = 1 << 22, .tail = 8192});
    EXPECT_NE(e.find("one row of tiles decodes to 3221225472 bytes"), std::string::npos) << e;
}

TEST_F(ImageLimitsTest, ExrAttributeLargerThanTheFileIsRefused) {
    std::string bytes = exrBytes({});
    const std::string name("pixelAspectRatio\0float\0", 23);
    bytes.replace(bytes.find(name) + name.size(), 4, le32(0x7ffffff0));
    const std::string path = write("attr.exr", bytes);
    const std::string e = errorOf([&] { readImage(path); });
    EXPECT_NE(e.find("cannot read EXR image '" + path + "'"), std::string::npos) << e;
}

TEST_F(ImageLimitsTest, DeepExrIsRefusedByName) {
    const std::string path = dir.at("deep.exr");
    Imf::Header header(2, 2);
    header.setType(Imf::DEEPSCANLINE);
    header.compression() = Imf::ZIPS_COMPRESSION;
    header.channels().insert("R", Imf::Channel(Imf::FLOAT));
    { Imf::DeepScanLineOutputFile file(path.c_str(), header); }
    const std::string e = errorOf([&] { readImage(path); });
    EXPECT_NE(e.find("it holds deep data (allowed: scanline or tiled images)"), std::string::npos)
        << e;
}

// The real light probe in shared/data: tiled, mip-mapped, half float, 2.3 MB.
TEST_F(ImageLimitsTest, RealTiledMipmappedHalfFloatProbeIsRead) {
    const std::string path = std::string(PHONGFIT_DATA_DIR) + "/envmaps/KernerEnvLatLong.exr";
    requireExrWithinLimits(path);
    const Image image = readImage(path);
    EXPECT_GT(image.width, 0);
    EXPECT_EQ(image.width, 2 * image.height);
}

std::string pngWithHeader(std::uint32_t width, std::uint32_t height, std::size_t tail) {
    const std::string ihdr = be32(width) + be32(height) + std::string{8, 2, 0, 0, 0};
    return std::string("\x89PNG\r\n\x1a\n", 8) + be32(13) + "IHDR" + ihdr + be32(0) +
           std::string(tail, '\0');
}

TEST_F(ImageLimitsTest, PngHeadersAreCheckedBeforeDecoding) {
    const std::string huge = write("huge.png", pngWithHeader(100000, 100000, 64));
    EXPECT_NE(errorOf([&] { readImage(huge); }).find("is 100000x100000 pixels (allowed: up to"),
              std::string::npos);
    // 2000 x 2000 RGB is 12 MB to inflate; deflate cannot hold it in 5 kB.
    const std::string dense = write("dense.png", pngWithHeader(2000, 2000, 5000));
    const std::string e = errorOf([&] { readImage(dense); });
    EXPECT_NE(e.find("is 2000x2000 pixels, 12002000 bytes to inflate from a file of"),
              std::string::npos)
        << e;
    EXPECT_NE(errorOf([&] { readMask(dense, 2000, 2000); }).find("12002000 bytes to inflate"),
              std::string::npos);
    const std::string noHeader = write("nohdr.png", std::string("\x89PNG\r\n\x1a\n", 8) + "junk");
    EXPECT_NE(errorOf([&] {
                  readImage(noHeader);
              }).find("not a valid image file (a PNG starts with its IHDR header)"),
              std::string::npos);
}

TEST_F(ImageLimitsTest, JpegFrameHeaderIsCheckedBeforeDecoding) {
    // A comment segment, then a baseline frame header of 60000 x 60000 (3.6 G pixels).
    const auto jpeg = [](std::uint32_t width, std::uint32_t height) {
        return std::string("\xff\xd8\xff\xfe", 4) + be16(6) + "hiya" + std::string("\xff\xc0", 2) +
               be16(11) + std::string(1, 8) + be16(height) + be16(width) +
               std::string{1, 1, 0x11, 0} + std::string(64, '\0');
    };
    const std::string huge = write("huge.jpg", jpeg(60000, 60000));
    EXPECT_NE(errorOf([&] { readImage(huge); }).find("is 60000x60000 pixels (allowed: up to"),
              std::string::npos);
    const std::string dense = write("dense.jpg", jpeg(4000, 3000));
    EXPECT_NE(errorOf([&] { readImage(dense); }).find("is 4000x3000 pixels in a file of 87 bytes"),
              std::string::npos)
        << errorOf([&] { readImage(dense); });
    const std::string noFrame = write("noframe.jpg", std::string("\xff\xd8\xff\xda", 4) + "xx");
    EXPECT_NE(errorOf([&] {
                  readImage(noFrame);
              }).find("a JPEG has a frame header before its image data"),
              std::string::npos);
}

// A little-endian TIFF whose first directory holds these (tag, short value) entries.
std::string tiff(const std::vector<std::pair<int, std::uint32_t>>& entries, std::size_t tail) {
    std::string bytes = std::string("II\x2a\0", 4) + le32(8) + le16(std::uint32_t(entries.size()));
    for (const auto& [tag, value] : entries)
        bytes += le16(std::uint32_t(tag)) + le16(4) + le32(1) + le32(value);
    return bytes + le32(0) + std::string(tail, '\0');
}

TEST_F(ImageLimitsTest, TiffDirectoryIsCheckedBeforeDecoding) {
    const std::string huge = write("huge.tif", tiff({{256, 100000}, {257, 100000}}, 64));
    EXPECT_NE(errorOf([&] { readImage(huge); }).find("is 100000x100000 pixels (allowed: up to"),
              std::string::npos);
    // 8192 x 8192, three 16-bit samples in one strip: 384 MiB to decode at once.
    const std::string strip =
        write("strip.tif", tiff({{256, 8192}, {257, 8192}, {258, 16}, {277, 3}}, 100000));
    const std::string e = errorOf([&] { readImage(strip); });
    EXPECT_NE(e.find("one strip decodes to 402653184 bytes (allowed: up to 134217728 bytes)"),
              std::string::npos)
        << e;
    const std::string tile =
        write("tile.tif", tiff({{256, 64}, {257, 64}, {322, 1 << 16}, {323, 1 << 16}}, 64));
    EXPECT_NE(errorOf([&] { readImage(tile); }).find("one tile decodes to"), std::string::npos);
    const std::string lost = write("lost.tif", std::string("II\x2a\0", 4) + le32(1u << 30));
    EXPECT_NE(
        errorOf([&] { readImage(lost); }).find("a TIFF's first directory lies within the file"),
        std::string::npos);
}

TEST_F(ImageLimitsTest, RealPngJpegAndTiffStillRead) {
    const cv::Mat bgr(30, 40, CV_8UC3, cv::Scalar(10, 20, 30));
    for (const char* name : {"r.png", "r.jpg", "r.tif"}) {
        ASSERT_TRUE(cv::imwrite(dir.at(name), bgr));
        const Image image = readImage(dir.at(name));
        EXPECT_EQ(image.width, 40) << name;
        EXPECT_EQ(image.height, 30) << name;
    }
}

TEST_F(ImageLimitsTest, CaptureTextFileOverTheLimitIsRefused) {
    const std::filesystem::path capture = dir.path() / "capture";
    std::filesystem::create_directory(capture);
    for (const char* name : {"filenames.txt", "light_directions.txt", "light_intensities.txt",
                             "normals.exr", "mask.png"})
        std::ofstream(capture / name) << "1 0 0\n";
    std::filesystem::resize_file(capture / "filenames.txt", kMaxCaptureTextBytes + 1);
    const std::string e = errorOf([&] { readCapture(capture.string()); });
    EXPECT_NE(e.find("filenames.txt' is 16777217 bytes (allowed: up to 16777216 bytes)"),
              std::string::npos)
        << e;
}

}  // namespace
}  // namespace phongfit
