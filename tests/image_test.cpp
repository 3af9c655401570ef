#include "image.h"

#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfOutputFile.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <opencv2/imgcodecs.hpp>
#include <random>

#include "error.h"
#include "raw_exr.h"
#include "temp_dir.h"

namespace phongfit {
namespace {

namespace fs = std::filesystem;

// The sRGB decoding formula (IEC 61966-2-1), written out independently of image.cpp.
double srgbFormula(double v) {
    return v <= 0.04045 ? v / 12.92 : std::pow((v + 0.055) / 1.055, 2.4);
}

class ImageTest : public ::testing::Test {
protected:
    std::string path(const std::string& name) const { return (dir_ / name).string(); }
    bool dirIsEmpty() const { return fs::is_empty(dir_); }

    // Error message of `f`, or "" if it did not throw Error.
    template <typename F>
    static std::string errorOf(F&& f) {
        try {
            f();
        } catch (const Error& e) {
            return e.what();
        }
        return "";
    }

    // An EXR holding float channels named in `names`, each filled with `value`.
    void writeExrChannels(const std::string& file, const std::vector<std::string>& names, int width,
                          int height, float value) {
        Imf::Header header(width, height);
        Imf::FrameBuffer frame;
        std::vector<std::vector<float>> planes(names.size(),
                                               std::vector<float>(width * height, value));
        for (std::size_t c = 0; c < names.size(); ++c) {
            header.channels().insert(names[c], Imf::Channel(Imf::FLOAT));
            frame.insert(names[c], Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(planes[c].data()),
                                              sizeof(float), sizeof(float) * width));
        }
        Imf::OutputFile out(file.c_str(), header);
        out.setFrameBuffer(frame);
        out.writePixels(height);
    }

    // A float RGB EXR framed in `display` whose data window `data` holds, at pixel (x, y), the
    // values of placedValue: each value says where it was written.
    void writeWindowedExr(const std::string& file, const Imath::Box2i& display,
                          const Imath::Box2i& data) {
        Image pixels(data.max.x - data.min.x + 1, data.max.y - data.min.y + 1);
        for (int y = 0; y < pixels.height; ++y)
            for (int x = 0; x < pixels.width; ++x)
                for (int c = 0; c < 3; ++c)
                    pixels.rgb[3 * pixels.index(x, y) + c] =
                        placedValue(x + data.min.x, y + data.min.y, c);
        test::writeRawExr(pixels, display, data, file);
    }
    static float placedValue(int x, int y, int c) { return float(1000 * y + x) + 0.1f * float(c); }

    const test::TempDir temp_{"image"};
    const fs::path& dir_ = temp_.path();
};

TEST_F(ImageTest, ExrRoundTripIsBitExact) {
    Image image(7, 5);
    std::mt19937 rng(7);
    std::uniform_real_distribution<float> u(-1e3f, 1e3f);
    for (float& v : image.rgb) v = u(rng);
    image.rgb[0] = std::numeric_limits<float>::denorm_min();
    image.rgb[1] = std::numeric_limits<float>::max();
    image.rgb[2] = -0.0f;
    writeExr(image, path("a.exr"));
    const Image back = readImage(path("a.exr"));
    ASSERT_EQ(back.width, 7);
    ASSERT_EQ(back.height, 5);
    ASSERT_EQ(back.rgb.size(), image.rgb.size());
    EXPECT_EQ(std::memcmp(back.rgb.data(), image.rgb.data(), image.rgb.size() * sizeof(float)), 0);
    EXPECT_EQ(back.clipped, std::vector<std::uint8_t>(35, 0));
    // Row 0 is the top and x runs along a row.
    EXPECT_EQ(back.at(6, 4)[2], image.rgb[3 * 34 + 2]);
    EXPECT_EQ(back.decoding, "EXR, linear");
}

TEST_F(ImageTest, ExrMissingChannelIsAnErrorNamingFileAndChannels) {
    writeExrChannels(path("rg.exr"), {"R", "G"}, 4, 3, 0.5f);
    const std::string message = errorOf([&] { readImage(path("rg.exr")); });
    EXPECT_NE(message.find("rg.exr"), std::string::npos) << message;
    EXPECT_NE(message.find("[G, R]"), std::string::npos) << message;
    EXPECT_NE(message.find("R, G and B"), std::string::npos) << message;
}

TEST_F(ImageTest, ExrSingleLuminanceChannelIsReadAsGrey) {
    writeExrChannels(path("y.exr"), {"Y"}, 4, 3, 0.25f);
    const Image image = readImage(path("y.exr"));
    ASSERT_EQ(image.pixelCount(), 12u);
    for (float v : image.rgb) EXPECT_EQ(v, 0.25f);
}

// A crop window's render (pbrt's cropwindow): the data window inside the display window.
TEST_F(ImageTest, ExrIsReadInItsDataWindowOrFramedInItsDisplayWindow) {
    const Imath::Box2i display({0, 0}, {5, 4}), data({2, 1}, {4, 3});
    writeWindowedExr(path("crop.exr"), display, data);
    const Image cropped = readImage(path("crop.exr"));
    ASSERT_EQ(cropped.width, 3);
    ASSERT_EQ(cropped.height, 3);
    EXPECT_TRUE(cropped.noData.empty());
    for (int y = 0; y < 3; ++y)
        for (int x = 0; x < 3; ++x)
            for (int c = 0; c < 3; ++c)
                EXPECT_EQ(cropped.at(x, y)[c], placedValue(x + 2, y + 1, c));

    ReadOptions framed;
    framed.exrDisplayWindow = true;
    const Image image = readImage(path("crop.exr"), framed);
    ASSERT_EQ(image.width, 6);
    ASSERT_EQ(image.height, 5);
    ASSERT_EQ(image.noData.size(), 30u);
    for (int y = 0; y < 5; ++y)
        for (int x = 0; x < 6; ++x) {
            const bool inside = x >= 2 && x <= 4 && y >= 1 && y <= 3;
            EXPECT_EQ(image.noData[image.index(x, y)], inside ? 0 : 1) << x << ", " << y;
            for (int c = 0; c < 3; ++c)
                EXPECT_EQ(image.at(x, y)[c], inside ? placedValue(x, y, c) : 0.0f);
        }
}

// An overscan (data beyond the frame, at negative coordinates too) is cut to the frame; a frame
// that does not start at 0 starts the image.
TEST_F(ImageTest, ExrDataBeyondTheDisplayWindowIsCutToIt) {
    const Imath::Box2i display({-3, 2}, {4, 6}), data({-5, -1}, {7, 8});
    writeWindowedExr(path("overscan.exr"), display, data);
    ReadOptions framed;
    framed.exrDisplayWindow = true;
    const Image image = readImage(path("overscan.exr"), framed);
    ASSERT_EQ(image.width, 8);
    ASSERT_EQ(image.height, 5);
    EXPECT_TRUE(image.noData.empty());
    for (int y = 0; y < 5; ++y)
        for (int x = 0; x < 8; ++x)
            for (int c = 0; c < 3; ++c) EXPECT_EQ(image.at(x, y)[c], placedValue(x - 3, y + 2, c));
}

TEST_F(ImageTest, ExrDataWindowOutsideItsDisplayWindowLeavesEveryPixelWithoutData) {
    writeWindowedExr(path("apart.exr"), Imath::Box2i({0, 0}, {3, 2}),
                     Imath::Box2i({10, 0}, {12, 2}));
    ReadOptions framed;
    framed.exrDisplayWindow = true;
    const Image image = readImage(path("apart.exr"), framed);
    ASSERT_EQ(image.pixelCount(), 12u);
    EXPECT_EQ(image.noData, std::vector<std::uint8_t>(12, 1));
    for (float v : image.rgb) EXPECT_EQ(v, 0.0f);
}

// A few bytes of data framed in a display window of 2^28 pixels: refused before it is allocated.
TEST_F(ImageTest, ExrDisplayWindowIsWithinTheImageLimits) {
    writeWindowedExr(path("vast.exr"), Imath::Box2i({0, 0}, {16383, 16383}),
                     Imath::Box2i({0, 0}, {1, 1}));
    EXPECT_EQ(readImage(path("vast.exr")).pixelCount(), 4u);
    ReadOptions framed;
    framed.exrDisplayWindow = true;
    const std::string message = errorOf([&] { readImage(path("vast.exr"), framed); });
    EXPECT_NE(message.find("vast.exr"), std::string::npos) << message;
    EXPECT_NE(message.find("16384x16384"), std::string::npos) << message;
}

TEST_F(ImageTest, Png8BitIsDecodedWithTheSrgbCurveInRgbOrder) {
    cv::Mat bgr(2, 3, CV_8UC3);
    for (int y = 0; y < 2; ++y)
        for (int x = 0; x < 3; ++x)
            bgr.at<cv::Vec3b>(y, x) = cv::Vec3b(uchar(10 + 40 * x), uchar(5 + 100 * y), uchar(200));
    ASSERT_TRUE(cv::imwrite(path("a.png"), bgr));
    const Image image = readImage(path("a.png"));
    ASSERT_EQ(image.width, 3);
    ASSERT_EQ(image.height, 2);
    for (int y = 0; y < 2; ++y) {
        for (int x = 0; x < 3; ++x) {
            const Color<float> c = image.at(x, y);
            EXPECT_NEAR(c[0], srgbFormula(200 / 255.0), 1e-6);
            EXPECT_NEAR(c[1], srgbFormula((5 + 100 * y) / 255.0), 1e-6);
            EXPECT_NEAR(c[2], srgbFormula((10 + 40 * x) / 255.0), 1e-6);
        }
    }
    EXPECT_EQ(image.decoding, "8-bit, decoded with the sRGB curve (the default for 8-bit)");
}

TEST_F(ImageTest, Png8BitWithGivenGammaOrLinear) {
    cv::Mat grey(1, 2, CV_8UC1);
    grey.at<uchar>(0, 0) = 51;
    grey.at<uchar>(0, 1) = 128;
    ASSERT_TRUE(cv::imwrite(path("g.png"), grey));
    const Image gamma = readImage(path("g.png"), {Encoding::Gamma, 2.2});
    EXPECT_NEAR(gamma.at(1, 0)[1], std::pow(128 / 255.0, 2.2), 1e-6);
    const Image linear = readImage(path("g.png"), {Encoding::Linear});
    EXPECT_NEAR(linear.at(0, 0)[0], 51 / 255.0, 1e-7);
    EXPECT_NEAR(linear.at(0, 0)[2], 51 / 255.0, 1e-7);  // grey fills all channels
    // What was chosen is said, so a linear capture decoded as sRGB can be told.
    EXPECT_EQ(gamma.decoding, "8-bit, decoded as value^2.2");
    EXPECT_EQ(linear.decoding, "8-bit, read as linear");
    EXPECT_EQ(readImage(path("g.png"), {Encoding::Srgb}).decoding,
              "8-bit, decoded with the sRGB curve");
}

TEST_F(ImageTest, Png16BitIsLinearByDefaultAndFlagsClipping) {
    cv::Mat bgr(1, 3, CV_16UC3);
    bgr.at<cv::Vec3w>(0, 0) = cv::Vec3w(1000, 20000, 40000);
    bgr.at<cv::Vec3w>(0, 1) = cv::Vec3w(65535, 0, 1);
    bgr.at<cv::Vec3w>(0, 2) = cv::Vec3w(65534, 65534, 65534);
    ASSERT_TRUE(cv::imwrite(path("w.png"), bgr));
    const Image image = readImage(path("w.png"));
    EXPECT_NEAR(image.at(0, 0)[0], 40000 / 65535.0, 1e-7);
    EXPECT_NEAR(image.at(0, 0)[1], 20000 / 65535.0, 1e-7);
    EXPECT_NEAR(image.at(0, 0)[2], 1000 / 65535.0, 1e-7);
    EXPECT_EQ(image.clipped, (std::vector<std::uint8_t>{0, 1, 0}));
    EXPECT_EQ(image.decoding, "16-bit, read as linear (the default for 16-bit)");
}

TEST_F(ImageTest, Png8BitClippedWhereAnyChannelIs255) {
    cv::Mat bgr(2, 2, CV_8UC3, cv::Scalar(100, 100, 100));
    bgr.at<cv::Vec3b>(0, 1) = cv::Vec3b(255, 0, 0);
    bgr.at<cv::Vec3b>(1, 0) = cv::Vec3b(254, 254, 254);
    bgr.at<cv::Vec3b>(1, 1) = cv::Vec3b(0, 0, 255);
    ASSERT_TRUE(cv::imwrite(path("c.png"), bgr));
    EXPECT_EQ(readImage(path("c.png")).clipped, (std::vector<std::uint8_t>{0, 1, 0, 1}));
}

TEST_F(ImageTest, AlphaIsIgnored) {
    cv::Mat bgra(1, 1, CV_8UC4, cv::Scalar(10, 20, 30, 40));
    ASSERT_TRUE(cv::imwrite(path("alpha.png"), bgra));
    const Image image = readImage(path("alpha.png"), {Encoding::Linear});
    EXPECT_NEAR(image.at(0, 0)[0], 30 / 255.0, 1e-7);
    EXPECT_NEAR(image.at(0, 0)[2], 10 / 255.0, 1e-7);
}

TEST_F(ImageTest, UnreadableFilesAreErrorsNamingTheFile) {
    EXPECT_NE(errorOf([&] { readImage(path("missing.png")); }).find("missing.png"),
              std::string::npos);
    std::ofstream(path("junk.png")) << "not a png";
    EXPECT_NE(errorOf([&] { readImage(path("junk.png")); }).find("junk.png"), std::string::npos);
    std::ofstream(path("junk.exr")) << "not an exr";
    EXPECT_NE(errorOf([&] { readImage(path("junk.exr")); }).find("junk.exr"), std::string::npos);
    std::ofstream(path("a.bmp")) << "whatever";
    const std::string unknown = errorOf([&] { readImage(path("a.bmp")); });
    EXPECT_NE(unknown.find("a.bmp"), std::string::npos) << unknown;
    EXPECT_NE(unknown.find(".exr"), std::string::npos) << unknown;  // lists what is allowed
}

TEST_F(ImageTest, MaskIsNonzeroAndItsSizeMustMatch) {
    cv::Mat mask(2, 3, CV_16UC1, cv::Scalar(0));
    mask.at<std::uint16_t>(0, 1) = 1;
    mask.at<std::uint16_t>(1, 2) = 65535;
    ASSERT_TRUE(cv::imwrite(path("m.png"), mask));
    EXPECT_EQ(readMask(path("m.png"), 3, 2), (std::vector<std::uint8_t>{0, 1, 0, 0, 0, 1}));
    const std::string message = errorOf([&] { readMask(path("m.png"), 4, 2); });
    EXPECT_NE(message.find("m.png"), std::string::npos) << message;
    EXPECT_NE(message.find("3x2"), std::string::npos) << message;
    EXPECT_NE(message.find("4x2"), std::string::npos) << message;
}

TEST_F(ImageTest, ColourMaskUsesAnyColourChannel) {
    cv::Mat mask(1, 3, CV_8UC3, cv::Scalar(0, 0, 0));
    mask.at<cv::Vec3b>(0, 0) = cv::Vec3b(0, 0, 1);
    mask.at<cv::Vec3b>(0, 2) = cv::Vec3b(0, 7, 0);
    ASSERT_TRUE(cv::imwrite(path("m8.png"), mask));
    EXPECT_EQ(readMask(path("m8.png"), 3, 1), (std::vector<std::uint8_t>{1, 0, 1}));
}

TEST_F(ImageTest, NonFiniteValuesAreRefusedAndNoFileIsLeft) {
    Image image(4, 3);
    image.rgb[3 * (1 * 4 + 2) + 1] = std::numeric_limits<float>::quiet_NaN();
    image.rgb[3 * (2 * 4 + 3) + 0] = std::numeric_limits<float>::infinity();
    for (const std::string name : {"n.exr", "n.png"}) {
        const std::string message = errorOf([&] {
            if (name == "n.exr")
                writeExr(image, path(name));
            else
                writePng(image, path(name));
        });
        EXPECT_NE(message.find(name), std::string::npos) << message;
        EXPECT_NE(message.find("2 non-finite"), std::string::npos) << message;
        EXPECT_NE(message.find("(2, 1) channel G"), std::string::npos) << message;
    }
    EXPECT_TRUE(dirIsEmpty());
}

TEST_F(ImageTest, WritePngEncodesSrgbWithExposure) {
    Image image(2, 1);
    image.set(0, 0, Color<float>(0.25f, 0.0f, 2.0f));  // times exposure 2: 0.5, 0, clamped 1
    image.set(1, 0, Color<float>(0.001f, 0.1f, 0.5f));
    writePng(image, path("o.png"), 2.0);
    const cv::Mat bgr = cv::imread(path("o.png"), cv::IMREAD_UNCHANGED);
    ASSERT_EQ(bgr.type(), CV_8UC3);
    const auto encode = [](double v) {
        return int(
            std::lround(255 * (v <= 0.0031308 ? 12.92 * v : 1.055 * std::pow(v, 1 / 2.4) - 0.055)));
    };
    EXPECT_EQ(bgr.at<cv::Vec3b>(0, 0), cv::Vec3b(255, 0, uchar(encode(0.5))));
    EXPECT_EQ(bgr.at<cv::Vec3b>(0, 1),
              cv::Vec3b(uchar(encode(1.0)), uchar(encode(0.2)), uchar(encode(0.002))));
    // Written as sRGB, read back as sRGB: the round trip is within 8-bit quantization.
    const Image back = readImage(path("o.png"));
    EXPECT_NEAR(back.at(1, 0)[1], 0.2, 0.002);
}

}  // namespace
}  // namespace phongfit
