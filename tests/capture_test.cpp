// Photometric-stereo captures: the loader and its errors, recovery of known parameters from a
// synthetic capture, the real DiLiGenT ball (held-out prediction against Lambertian, stability of
// the exponent between halves of the lights), (`phongfit fit --capture` end to end:
// e2e/fit_capture_test.cpp).
#include "capture.h"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <optional>
#include <random>
#include <stdexcept>

#include "capture_fit.h"
#include "error.h"
#include "error_of.h"
#include "image.h"
#include "phong_brdf.h"
#include "raw_exr.h"
#include "synthetic_capture.h"
#include "temp_dir.h"

namespace phongfit {
namespace {

namespace fs = std::filesystem;

const std::string kBall = PHONGFIT_BALL_DIR;
using test::range;
using test::Synthetic;

using test::errorOf;

class CaptureTest : public ::testing::Test {
protected:
    void SetUp() override { Synthetic().write(dir_.path()); }

    std::string loadError(const CaptureReadOptions& options = {}) const {
        return errorOf([&] {
            const Capture c = readCapture(dir_.path().string(), options);
            readCaptureImages(c, range(0, int(c.lights.size()) - 1), options, 2);
        });
    }
    void writeLines(const std::string& name, const std::vector<std::string>& lines) const {
        std::ofstream out(dir_.path() / name);
        for (const std::string& l : lines) out << l << "\n";
    }
    std::vector<std::string> readLines(const std::string& name) const {
        std::ifstream in(dir_.path() / name);
        std::vector<std::string> lines;
        for (std::string l; std::getline(in, l);) lines.push_back(l);
        return lines;
    }

    test::TempDir dir_{"capture"};
};

TEST_F(CaptureTest, LoaderReadsTheLayoutAndMarksClippedPixels) {
    const Capture c = readCapture(dir_.path().string());
    ASSERT_EQ(c.lights.size(), std::size_t(Synthetic::kLights));
    EXPECT_EQ(c.width, Synthetic::kSize);
    EXPECT_EQ(c.lights[4].number, 5);
    EXPECT_NEAR((c.lights[4].direction - Synthetic::lightDirection(4)).norm(), 0, 1e-5);
    std::size_t inside = 0;
    for (int y = 0; y < Synthetic::kSize; ++y)
        for (int x = 0; x < Synthetic::kSize; ++x) inside += Synthetic::normal(x, y).has_value();
    EXPECT_EQ(c.pixels.size(), inside);
    for (const Vec3d& n : c.normals) EXPECT_NEAR(n.norm(), 1, 1e-9);

    const std::vector<CaptureImage> images = readCaptureImages(c, range(0, 29), {}, 2);
    std::size_t clipped = 0;
    for (const CaptureImage& image : images)
        for (PixelState s : image.state) clipped += s == PixelState::Clipped;
    EXPECT_GT(clipped, 0u) << "the synthetic highlights must clip, or clipping goes untested";
    // --saturation clips more: everything at or above the given linear value.
    CaptureReadOptions low;
    low.saturation = 0.05;
    std::size_t clippedLow = 0;
    for (const CaptureImage& image : readCaptureImages(c, range(0, 29), low, 2))
        for (PixelState s : image.state) clippedLow += s == PixelState::Clipped;
    EXPECT_GT(clippedLow, clipped);
}

TEST_F(CaptureTest, SyntheticCaptureIsRecovered) {
    const Synthetic synth;
    const Capture c = readCapture(dir_.path().string());
    CaptureFitOptions options;
    options.fit.threads = 2;
    const CaptureFit fit = fitCapture(c, readCaptureImages(c, range(0, 23), {}, 2),
                                      readCaptureImages(c, range(24, 29), {}, 2), options);
    const MaterialFit& m = fit.phong.materials[0];
    EXPECT_TRUE(fit.phong.converged);
    EXPECT_TRUE(m.unconstrained.empty());
    for (int ch = 0; ch < 3; ++ch) {
        EXPECT_NEAR(m.kd[ch], synth.truth.kd[ch], 0.02 * synth.truth.kd[ch]) << ch;
        EXPECT_NEAR(m.ks[ch], synth.truth.ks[ch], 0.02 * synth.truth.ks[ch]) << ch;
    }
    EXPECT_NEAR(m.n, synth.truth.n, 0.05 * synth.truth.n);
    EXPECT_GT(fit.model.leftOut.at("clipped"), 0u);
    EXPECT_GT(fit.model.leftOut.at("below_min_cos"), 0u);
    EXPECT_EQ(fit.model.used + fit.model.leftOut.at("clipped") +
                  fit.model.leftOut.at("below_min_cos") + fit.model.leftOut.at("facing_away") +
                  fit.model.leftOut.at("non_finite"),
              fit.model.pairs);
    // The held-out lights are predicted to the noise level (in normalised units: the noise over
    // the light's intensity); without the lobe they are not.
    ASSERT_TRUE(fit.holdout);
    EXPECT_EQ(fit.holdout->perLight.size(), 6u);
    double noiseSquares = 0;
    for (int l = 24; l < 30; ++l)
        noiseSquares += (Synthetic::kNoise / c.lights[l].intensity).square().sum();
    EXPECT_LT(fit.holdout->phong.rmse, 1.1 * std::sqrt(noiseSquares / 18));
    EXPECT_GT(fit.holdout->lambertian.rmse, 3 * fit.holdout->phong.rmse);
    // The Lambertian-only fit holds the lobe at zero.
    ASSERT_TRUE(fit.lambertian);
    const MaterialFit& lambertian = fit.lambertian->materials[0];
    EXPECT_TRUE((lambertian.ks == 0).all());
    EXPECT_NE(std::find(lambertian.unconstrained.begin(), lambertian.unconstrained.end(), "ks"),
              lambertian.unconstrained.end());
}

// Every light at one unknown intensity (the file says 0.1 for each, the images were taken at 0.3):
// kd and ks come out three times the truth, beyond kd + ks = 1, and n unchanged. Taken as
// calibrated, the fit stops on the energy bound and says so.
TEST(CaptureIntensities, RelativeIntensitiesAreFittedInImageUnitsWithoutEnergyBound) {
    const test::TempDir dir("capture_relative");
    Synthetic synth;
    synth.commonIntensity = 0.3;
    synth.write(dir.path());
    const double scale = synth.commonIntensity / Synthetic::kWrittenIntensity;
    const Capture c = readCapture(dir.path().string());
    const std::vector<CaptureImage> images = readCaptureImages(c, range(0, 29), {}, 2);
    CaptureFitOptions options;
    options.fit.threads = 2;
    options.relativeIntensities = true;
    const CaptureFit fit = fitCapture(c, images, {}, options);
    const MaterialFit& m = fit.phong.materials[0];
    EXPECT_TRUE(fit.phong.converged);
    EXPECT_FALSE(fit.energyBoundReached);
    EXPECT_GT((m.kd + m.ks).maxCoeff(), 1);
    for (int ch = 0; ch < 3; ++ch) {
        EXPECT_NEAR(m.kd[ch], scale * synth.truth.kd[ch], 0.02 * scale * synth.truth.kd[ch]);
        EXPECT_NEAR(m.ks[ch], scale * synth.truth.ks[ch], 0.02 * scale * synth.truth.ks[ch]);
        EXPECT_LT(std::abs(m.ks[ch] - scale * synth.truth.ks[ch]), 3 * m.ksStd[ch]) << ch;
    }
    EXPECT_NEAR(m.n, synth.truth.n, 0.05 * synth.truth.n);

    options.relativeIntensities = false;
    const CaptureFit calibrated = fitCapture(c, images, {}, options);
    EXPECT_TRUE(calibrated.energyBoundReached);
}

// A few NaN pixels are left out and counted; more than kMaxNonFiniteFraction of the pairs is an
// error naming the count and the limit.
TEST_F(CaptureTest, NonFinitePixelsAreLeftOutUpToALimit) {
    const Capture c = readCapture(dir_.path().string());
    std::vector<CaptureImage> images = readCaptureImages(c, range(0, 9), {}, 2);
    const auto spoil = [&](std::size_t every) {
        std::vector<CaptureImage> out = images;
        for (CaptureImage& image : out)
            for (std::size_t i = 0; i < image.state.size(); i += every)
                image.state[i] = PixelState::NonFinite;
        return out;
    };
    const CaptureModel few = buildUsableModel(c, spoil(100), 0.05, "fitted");
    EXPECT_GT(few.leftOut.at("non_finite"), 0u);
    const std::string error = errorOf([&] { buildUsableModel(c, spoil(10), 0.05, "fitted"); });
    EXPECT_NE(error.find("are NaN or infinite, more than the 5%"), std::string::npos) << error;
}

TEST_F(CaptureTest, MissingFilesAreNamed) {
    for (const char* name : {"filenames.txt", "light_directions.txt", "light_intensities.txt",
                             "mask.png", "normals.exr", "007.png"}) {
        const fs::path file = dir_.path() / name, moved = dir_.path() / "moved";
        fs::rename(file, moved);
        const std::string error = loadError();
        EXPECT_NE(error.find(file.string()), std::string::npos) << name << ": " << error;
        fs::rename(moved, file);
    }
    EXPECT_NE(errorOf([] { readCapture("/nonexistent/capture"); }).find("/nonexistent/capture"),
              std::string::npos);
}

TEST_F(CaptureTest, CountsThatDisagreeAreNamed) {
    std::vector<std::string> lines = readLines("light_directions.txt");
    lines.pop_back();
    writeLines("light_directions.txt", lines);
    const std::string error = loadError();
    EXPECT_NE(error.find("light_directions.txt' has 29 lines"), std::string::npos) << error;
    EXPECT_NE(error.find("filenames.txt' has 30 lines"), std::string::npos) << error;
}

TEST_F(CaptureTest, MalformedLinesAreNamedWithTheirLine) {
    std::vector<std::string> lines = readLines("light_intensities.txt");
    lines[2] = "1 2";
    writeLines("light_intensities.txt", lines);
    EXPECT_NE(loadError().find("light_intensities.txt:3: '1 2' is not three finite numbers"),
              std::string::npos)
        << loadError();
    lines[2] = "1 0 1";
    writeLines("light_intensities.txt", lines);
    EXPECT_NE(loadError().find("light_intensities.txt:3"), std::string::npos) << loadError();

    lines[2] = "1 1 1";
    writeLines("light_intensities.txt", lines);
    lines = readLines("light_directions.txt");
    lines[4] = "0 0 2";
    writeLines("light_directions.txt", lines);
    EXPECT_NE(loadError().find("light_directions.txt:5: light direction"), std::string::npos)
        << loadError();
}

// Real data has a few bad normals (DiLiGenT's pot2: 73 zero normals inside its mask): they are left
// out and counted.
TEST_F(CaptureTest, BadNormalsInsideTheMaskAreLeftOutAndCounted) {
    const Capture before = readCapture(dir_.path().string());
    Image normals = readImage((dir_.path() / "normals.exr").string());
    const int y = Synthetic::kSize / 2;
    const std::vector<int> xs = {Synthetic::kSize / 2 - 1, Synthetic::kSize / 2,
                                 Synthetic::kSize / 2 + 1};
    normals.set(xs[0], y, normals.at(xs[0], y) * 1.1f);
    normals.set(xs[1], y, Color<float>::Zero());
    normals.set(xs[2], y, Color<float>::Constant(std::nanf("")));
    test::writeRawExr(normals, (dir_.path() / "normals.exr").string());
    const Capture c = readCapture(dir_.path().string());
    EXPECT_EQ(c.badNormals, 3u);
    EXPECT_EQ(c.pixels.size() + 3, before.pixels.size());
    EXPECT_EQ(c.normals.size(), c.pixels.size());
    for (int x : xs)
        EXPECT_EQ(
            std::count(c.pixels.begin(), c.pixels.end(), std::uint32_t(y * Synthetic::kSize + x)),
            0)
            << x;
    // The photographs are read on the pixels kept.
    const std::vector<CaptureImage> images =
        readCaptureImages(c, range(0, int(c.lights.size()) - 1), {}, 2);
    EXPECT_EQ(images[0].rgb.size(), c.pixels.size());
}

// Bad normals over much of the mask mean the normals do not belong to the capture: an error
// naming the file, the count and the first one.
TEST_F(CaptureTest, BadNormalsAboveTheLimitAreAnError) {
    Image normals = readImage((dir_.path() / "normals.exr").string());
    for (int y = 0; y < Synthetic::kSize; ++y)
        for (int x = 0; x < Synthetic::kSize; ++x) normals.set(x, y, normals.at(x, y) * 1.1f);
    writeExr(normals, (dir_.path() / "normals.exr").string());
    const std::string error = loadError();
    EXPECT_NE(error.find("normals.exr"), std::string::npos) << error;
    EXPECT_NE(error.find("have no unit normal"), std::string::npos) << error;
    EXPECT_NE(error.find("the first at pixel ("), std::string::npos) << error;
    EXPECT_NE(error.find("has length 1.1"), std::string::npos) << error;
    EXPECT_NE(error.find("Above 5%"), std::string::npos) << error;
}

TEST_F(CaptureTest, BlackImageIsNamed) {
    cv::imwrite((dir_.path() / "012.png").string(),
                cv::Mat(Synthetic::kSize, Synthetic::kSize, CV_16UC3, cv::Scalar(0, 0, 0)));
    const std::string error = loadError();
    EXPECT_NE(error.find((dir_.path() / "012.png").string() + "' is black"), std::string::npos)
        << error;
}

TEST_F(CaptureTest, WrongSizesAreNamed) {
    CaptureReadOptions ownMask;
    ownMask.mask = (dir_.path() / "mine.png").string();
    fs::copy_file(dir_.path() / "mask.png", ownMask.mask);
    cv::imwrite((dir_.path() / "mask.png").string(),
                cv::Mat(Synthetic::kSize - 1, Synthetic::kSize, CV_8U, cv::Scalar(255)));
    std::string error = loadError();
    EXPECT_NE(error.find("mask.png' is 48x47"), std::string::npos) << error;

    cv::imwrite((dir_.path() / "003.png").string(),
                cv::Mat(10, 10, CV_16UC3, cv::Scalar(100, 100, 100)));
    error = loadError(ownMask);
    EXPECT_NE(error.find("003.png' is 10x10"), std::string::npos) << error;
}

TEST(LightList, RangesAndListsParseAndErrorsAreClear) {
    EXPECT_EQ(parseLightList("1-3,7, 9-10", 10, "--lights"), (std::vector<int>{0, 1, 2, 6, 8, 9}));
    EXPECT_EQ(parseLightList("5", 5, "--lights"), (std::vector<int>{4}));
    for (const auto& [text, fragment] :
         std::vector<std::pair<std::string, std::string>>{{"0-3", "light 0 does not exist"},
                                                          {"1-11", "light 11 does not exist"},
                                                          {"4-2", "'4-2' is descending"},
                                                          {"1,2,2", "light 2 is listed twice"},
                                                          {"1,,2", "'' is not a number"},
                                                          {"a", "'a' is not a number"}}) {
        const std::string error =
            errorOf([&, &text = text] { parseLightList(text, 10, "--holdout"); });
        EXPECT_NE(error.find("--holdout '" + text + "'"), std::string::npos) << error;
        EXPECT_NE(error.find(fragment), std::string::npos) << error;
    }
}

// The real capture, every `stride`-th mask pixel of it. Fails (never skips) if the data is missing.
Capture loadBall(std::size_t stride) {
    if (!fs::is_directory(kBall))
        throw std::runtime_error(
            "the DiLiGenT ball is missing at '" + kBall +
            "': it belongs in shared/data/diligent-ball beside the repository");
    Capture ball = readCapture(kBall);
    std::vector<std::uint32_t> pixels;
    std::vector<Vec3d> normals;
    for (std::size_t i = 0; i < ball.pixels.size(); i += stride) {
        pixels.push_back(ball.pixels[i]);
        normals.push_back(ball.normals[i]);
    }
    ball.pixels = pixels;
    ball.normals = normals;
    return ball;
}

void expectConvergedWithFiniteErrors(const CaptureFit& fit) {
    EXPECT_TRUE(fit.phong.converged);
    const MaterialFit& m = fit.phong.materials[0];
    EXPECT_TRUE(m.unconstrained.empty());
    for (int ch = 0; ch < 3; ++ch) {
        for (double v : {m.kd[ch], m.ks[ch], m.kdStd[ch], m.ksStd[ch]})
            EXPECT_TRUE(std::isfinite(v)) << ch;
        EXPECT_GT(m.kdStd[ch], 0);
        EXPECT_GT(m.ksStd[ch], 0);
        EXPECT_GT(m.ks[ch], 5 * m.ksStd[ch]) << "the ball is glossy: the lobe must be seen";
    }
    EXPECT_TRUE(std::isfinite(m.n));
    EXPECT_TRUE(std::isfinite(m.nStd));
    EXPECT_GT(m.nStd, 0);
    EXPECT_GT(fit.model.leftOut.at("clipped"), 0u) << "the ball's highlights clip";
}

const std::vector<int> kOddLights = range(0, 94, 2);   // lights 1, 3, ..., 95
const std::vector<int> kEvenLights = range(1, 95, 2);  // lights 2, 4, ..., 96

// Fitted on the odd lights, predicting the even ones. Every 4th mask pixel keeps it fast; what the
// lobe buys does not depend on which pixels.
TEST(DiligentBall, PhongPredictsHeldOutLightsClearlyBetterThanLambertian) {
    const Capture ball = loadBall(4);
    ASSERT_EQ(ball.lights.size(), 96u);
    CaptureFitOptions options;
    options.fit.threads = 2;
    const CaptureFit fit = fitCapture(ball, readCaptureImages(ball, kOddLights, {}, 2),
                                      readCaptureImages(ball, kEvenLights, {}, 2), options);
    expectConvergedWithFiniteErrors(fit);
    ASSERT_TRUE(fit.holdout);
    const HoldoutPrediction& h = *fit.holdout;
    EXPECT_EQ(h.perLight.size(), 48u);
    EXPECT_LT(h.phong.rmse, 0.8 * h.lambertian.rmse);
    EXPECT_LT(h.phong.relRmse, 0.8 * h.lambertian.relRmse);
    std::size_t better = 0;
    for (const LightPrediction& l : h.perLight) better += l.phong.rmse < l.lambertian.rmse;
    EXPECT_GE(better, 40u) << "Phong must predict most held-out lights better";
}

// All mask pixels: n rests on the few pixels near each light's highlight, so a pixel subsample
// moves it by more than its standard error.
TEST(DiligentBall, ExponentIsStableBetweenOddAndEvenLights) {
    const Capture ball = loadBall(1);
    CaptureFitOptions options;
    options.fit.threads = 2;
    const CaptureFit odd =
        fitCapture(ball, readCaptureImages(ball, kOddLights, {}, 2), {}, options);
    const CaptureFit even =
        fitCapture(ball, readCaptureImages(ball, kEvenLights, {}, 2), {}, options);
    expectConvergedWithFiniteErrors(odd);
    expectConvergedWithFiniteErrors(even);
    const MaterialFit &a = odd.phong.materials[0], &b = even.phong.materials[0];
    EXPECT_LT(std::abs(a.n - b.n), 2 * std::hypot(a.nStd, b.nStd))
        << "n = " << a.n << " ± " << a.nStd << " (odd lights) vs " << b.n << " ± " << b.nStd
        << " (even lights)";
}
}  // namespace
}  // namespace phongfit
