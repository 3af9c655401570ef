// PFM reading (pfm_file.h): values, orientation and byte order against OpenCV's own PFM decoder and
// against files written byte by byte here; every malformed header a one-line error before any
// pixel is allocated.
#include "pfm_file.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <cstring>
#include <opencv2/imgcodecs.hpp>
#include <string>
#include <vector>

#include "error_of.h"
#include "image.h"
#include "temp_dir.h"

namespace phongfit {
namespace {

using test::errorOf;

// A PFM file's bytes: `header`, then `values` as floats in the byte order the scale's sign gives.
std::string pfmBytes(const std::string& header, const std::vector<float>& values, bool bigEndian) {
    std::string bytes = header;
    for (float v : values) {
        std::uint32_t w;
        std::memcpy(&w, &v, sizeof w);
        for (int k = 0; k < 4; ++k) {
            const int shift = bigEndian ? 8 * (3 - k) : 8 * k;
            bytes.push_back(char((w >> shift) & 0xff));
        }
    }
    return bytes;
}

// Stored value of pixel (x, y) of the file (rows from the bottom), channel c.
float stored(int x, int y, int c) { return float(1000 * y + 10 * x + c) + 0.25f; }

// A 3 x 2 RGB image, stored bottom row first.
std::vector<float> rgbValues() {
    std::vector<float> v;
    for (int y = 0; y < 2; ++y)
        for (int x = 0; x < 3; ++x)
            for (int c = 0; c < 3; ++c) v.push_back(stored(x, y, c));
    return v;
}

TEST(PfmFile, ReadsRgbTopRowFirstAsOpenCvDoes) {
    test::TempDir dir("pfm");
    const std::string path = dir.write("rgb.pfm", pfmBytes("PF\n3 2\n-1.0\n", rgbValues(), false));
    const Image image = readImage(path);
    ASSERT_EQ(image.width, 3);
    ASSERT_EQ(image.height, 2);
    EXPECT_EQ(image.decoding, "PFM, linear");
    // The file's bottom row (stored first) is the image's row 1.
    for (int y = 0; y < 2; ++y)
        for (int x = 0; x < 3; ++x)
            for (int c = 0; c < 3; ++c)
                EXPECT_EQ(image.at(x, y)[c], stored(x, 1 - y, c)) << x << " " << y << " " << c;
    // OpenCV's decoder, written independently: the same pixels (it gives BGR).
    const cv::Mat mat = cv::imread(path, cv::IMREAD_UNCHANGED);
    ASSERT_EQ(mat.type(), CV_32FC3);
    for (int y = 0; y < 2; ++y)
        for (int x = 0; x < 3; ++x)
            for (int c = 0; c < 3; ++c)
                EXPECT_EQ(image.at(x, y)[c], mat.at<cv::Vec3f>(y, x)[2 - c]) << x << " " << y;
}

TEST(PfmFile, APositiveScaleMeansBigEndianAndItsMagnitudeIsIgnored) {
    test::TempDir dir("pfm");
    const Image little =
        readImage(dir.write("le.pfm", pfmBytes("PF\n3 2\n-1\n", rgbValues(), false)));
    const Image big = readImage(dir.write("be.pfm", pfmBytes("PF 3 2 4.0\n", rgbValues(), true)));
    EXPECT_EQ(big.rgb, little.rgb);
}

TEST(PfmFile, GreyIsTheSameInEveryChannel) {
    test::TempDir dir("pfm");
    const Image image =
        readImage(dir.write("grey.PFM", pfmBytes("Pf\n2 1\n-1.0\n", {0.5f, 2.0f}, false)));
    ASSERT_EQ(image.width, 2);
    for (int c = 0; c < 3; ++c) {
        EXPECT_EQ(image.at(0, 0)[c], 0.5f);
        EXPECT_EQ(image.at(1, 0)[c], 2.0f);
    }
}

TEST(PfmFile, MalformedFilesAreOneLineErrors) {
    test::TempDir dir("pfm");
    const std::vector<float> six(18, 1.0f);
    const std::vector<std::pair<std::string, std::string>> cases = {
        {pfmBytes("P6\n3 2\n255\n", six, false), "does not start with \"PF\""},
        {pfmBytes("PF\n0 2\n-1.0\n", {}, false), "0 x 2 pixels: it has none"},
        {pfmBytes("PF\n-3 2\n-1.0\n", six, false), "its width is '-3'"},
        {pfmBytes("PF\n3 x\n-1.0\n", six, false), "its height is 'x'"},
        {pfmBytes("PF\n3 2\n0\n", six, false), "its scale is '0'"},
        {pfmBytes("PF\n3 2\nnan\n", six, false), "its scale is 'nan'"},
        {"PF\n3 2\n-1.0", "does not end in one whitespace byte"},
        {"PF\n3 2", "its scale is ''"},
        {pfmBytes("PF\n65536 65536\n-1.0\n", six, false),
         "declares 65536 x 65536 pixels, more than the 67108864 allowed"},
        {pfmBytes("PF\n3 2\n-1.0\n", std::vector<float>(17, 1.0f), false),
         "3 x 2 pixels of 3 floats, 72 bytes, but 68 bytes follow it"},
        {pfmBytes("PF\n3 2\n-1.0\n", std::vector<float>(19, 1.0f), false),
         "72 bytes, but 76 bytes follow it"},
        {pfmBytes("PF\n3 2\n-1.0\n\n", six, false), "72 bytes, but 73 bytes follow it"},
    };
    for (const auto& [bytes, message] : cases) {
        const std::string path = dir.write("bad.pfm", bytes);
        const std::string e = errorOf([&] { readImage(path); });
        EXPECT_NE(e.find("cannot read PFM image '" + path + "'"), std::string::npos) << e;
        EXPECT_NE(e.find(message), std::string::npos) << message << ": " << e;
        EXPECT_EQ(e.find('\n'), std::string::npos) << e;
    }
}

}  // namespace
}  // namespace phongfit
