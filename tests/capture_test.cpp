// Photometric-stereo captures: the loader and its errors, recovery of known parameters from a
// synthetic capture, the real DiLiGenT ball (held-out prediction against Lambertian, stability of
// the exponent between halves of the lights), and `phongfit fit --capture` end to end.
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
#include "subprocess.h"
#include "temp_dir.h"

namespace phongfit {
namespace {

namespace fs = std::filesystem;

const std::string kBall = PHONGFIT_BALL_DIR;

// A sphere under distant lights, rendered with the project's BRDF on the known normals, with
// Gaussian noise, written as linear 16-bit PNGs (so the brightest highlights clip at 65535).
struct Synthetic {
    static constexpr int kSize = 48;
    static constexpr int kLights = 30;
    static constexpr double kNoise = 0.002;  // in 16-bit linear units, before quantisation
    PhongMaterial truth;

    Synthetic() {
        truth.kd = Color3(0.4, 0.3, 0.2);
        truth.ks = Color3(0.2, 0.25, 0.3);
        truth.n = 60;
    }

    static Vec3d lightDirection(int i) {
        // Rings of lights at 10 to 50 degrees from the view, as in a photometric-stereo dome.
        const double theta = (10 + 40 * double(i % 5) / 4) * kPi / 180;
        const double phi = 2 * kPi * i / kLights + i % 5;
        return Vec3d(std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi),
                     std::cos(theta));
    }

    static std::optional<Vec3d> normal(int x, int y) {
        const double r = 0.45 * kSize;
        const double nx = (x + 0.5 - kSize / 2.0) / r, ny = (kSize / 2.0 - y - 0.5) / r;
        const double z2 = 1 - nx * nx - ny * ny;
        if (z2 <= 0.01) return std::nullopt;
        return Vec3d(nx, ny, std::sqrt(z2));
    }

    void write(const fs::path& dir) const {
        std::mt19937 rng(7);
        std::normal_distribution<double> noise(0, kNoise);
        std::uniform_real_distribution<double> intensity(0.25, 0.45);
        Image normals(kSize, kSize);
        cv::Mat mask(kSize, kSize, CV_8U, cv::Scalar(0));
        for (int y = 0; y < kSize; ++y)
            for (int x = 0; x < kSize; ++x)
                if (const auto n = normal(x, y)) {
                    normals.set(x, y, n->cast<float>().array());
                    mask.at<uchar>(y, x) = 255;
                }
        writeExr(normals, (dir / "normals.exr").string());
        cv::imwrite((dir / "mask.png").string(), mask);
        std::ofstream names(dir / "filenames.txt"), directions(dir / "light_directions.txt"),
            intensities(dir / "light_intensities.txt");
        for (int i = 0; i < kLights; ++i) {
            const Vec3d l = lightDirection(i);
            const Color3 e(intensity(rng), intensity(rng), intensity(rng));
            const std::string name = fmt::format("{:03d}.png", i + 1);
            names << name << "\n";
            directions << fmt::format("{} {} {}\n", l.x(), l.y(), l.z());
            intensities << fmt::format("{} {} {}\n", e[0], e[1], e[2]);
            cv::Mat image(kSize, kSize, CV_16UC3, cv::Scalar(0, 0, 0));
            for (int y = 0; y < kSize; ++y)
                for (int x = 0; x < kSize; ++x) {
                    const auto n = normal(x, y);
                    if (!n) continue;
                    const Frame<double> frame(*n);
                    const Vec3d wi = frame.toLocal(l), wo = frame.toLocal(Vec3d(0, 0, 1));
                    const Color3 f = phongEval(truth, wi, wo);
                    for (int c = 0; c < 3; ++c) {
                        const double v = e[c] * std::max(wi.z(), 0.0) * f[c] + noise(rng);
                        image.at<cv::Vec3w>(y, x)[2 - c] =
                            cv::saturate_cast<ushort>(std::lround(65535 * std::clamp(v, 0.0, 1.0)));
                    }
                }
            cv::imwrite((dir / name).string(), image);
        }
    }
};

std::vector<int> range(int first, int last, int step = 1) {
    std::vector<int> v;
    for (int i = first; i <= last; i += step) v.push_back(i);
    return v;
}

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

TEST_F(CaptureTest, NonUnitNormalInsideTheMaskIsNamed) {
    Image normals = readImage((dir_.path() / "normals.exr").string());
    const int x = Synthetic::kSize / 2, y = Synthetic::kSize / 3;
    normals.set(x, y, normals.at(x, y) * 1.1f);
    writeExr(normals, (dir_.path() / "normals.exr").string());
    const std::string error = loadError();
    EXPECT_NE(error.find("normals.exr"), std::string::npos) << error;
    EXPECT_NE(error.find(fmt::format("pixel ({}, {})", x, y)), std::string::npos) << error;
    EXPECT_NE(error.find("must be unit"), std::string::npos) << error;
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
        const std::string error = errorOf([&] { parseLightList(text, 10, "--holdout"); });
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

class CaptureCommand : public CaptureTest {
protected:
    test::ProcessResult run(std::vector<std::string> args) const {
        args.insert(args.begin(), PHONGFIT_EXE);
        return test::runProcess(args);
    }
    std::string out(const std::string& name) const { return (dir_.path() / name).string(); }
};

TEST_F(CaptureCommand, WritesReportAndComparison) {
    const auto r = run({"fit", "--capture", dir_.path().string(), "--lights", "1-20", "--holdout",
                        "21-30", "--threads", "2", "-o", out("fit"), "--quiet"});
    ASSERT_EQ(r.exitCode, 0) << r.err;
    EXPECT_NE(r.out.find("capture: kd = "), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("held out 10 lights"), std::string::npos) << r.out;

    const auto report = nlohmann::json::parse(std::ifstream(out("fit/fit.json")));
    const auto& m = report["materials"]["capture"];
    for (const char* key : {"kd", "ks", "kd_std", "ks_std"}) ASSERT_EQ(m[key].size(), 3u) << key;
    EXPECT_NEAR(m["n"].get<double>(), Synthetic().truth.n, 0.1 * Synthetic().truth.n);
    const auto& h = report["holdout"];
    for (const char* key : {"rmse", "rel_rmse", "lambertian_rmse", "lambertian_rel_rmse"})
        EXPECT_TRUE(h[key].is_number()) << key;
    EXPECT_LT(h["rmse"].get<double>(), h["lambertian_rmse"].get<double>());
    ASSERT_EQ(h["per_light"].size(), 10u);
    EXPECT_EQ(h["per_light"][0]["light"], 21);
    EXPECT_EQ(report["capture"]["lights"].size(), 20u);
    EXPECT_EQ(report["model"]["lobes"], nlohmann::json({"diffuse", "specular"}));
    EXPECT_FALSE(report["left_out"].empty());
    EXPECT_GT(report["pairs"]["left_out"]["clipped"].get<int>(), 0);
    EXPECT_EQ(report["lambertian"]["materials"]["capture"]["ks"], nlohmann::json({0, 0, 0}));

    // Two rows (Phong, Lambertian) of three panels, cropped to the mask.
    const cv::Mat compare = cv::imread(out("fit/compare.png"));
    ASSERT_FALSE(compare.empty());
    EXPECT_EQ(compare.cols % 3, 0);
    EXPECT_EQ(compare.rows % 2, 0);
    EXPECT_LE(compare.cols, 3 * Synthetic::kSize);
}

TEST_F(CaptureCommand, BadInputIsRefusedWithOneLineAndNothingWritten) {
    cv::imwrite(out("012.png"),
                cv::Mat(Synthetic::kSize, Synthetic::kSize, CV_16UC3, cv::Scalar(0, 0, 0)));
    const std::string dir = dir_.path().string();
    struct Case {
        std::vector<std::string> args;
        std::string fragment;
    };
    const std::vector<Case> cases = {
        {{"--capture", dir}, out("012.png") + "' is black"},
        {{"--capture", dir, "--lights", "1-11", "--holdout", "11-12"}, "light 11 is in both"},
        {{"--capture", dir, "--lights", "1-31"}, "light 31 does not exist"},
        {{"--capture", dir, "--holdout", "1-30"}, "none is left to fit"},
        {{"--capture", dir, "--min-cos", "1"}, "--min-cos"},
        {{"--capture", dir, "--spp", "4"}, "--spp applies to scene fits"},
        // Every scene-only option is refused, not silently ignored (they form one option group).
        {{"--capture", dir, "--direct-spp", "8"}, "--direct-spp applies to scene fits"},
        {{"--capture", dir, "--compare-spp", "8"}, "--compare-spp applies to scene fits"},
        {{"--capture", dir, "-D", "a=1"}, "-D applies to scene fits"},
        {{"--capture", dir, "--rounds", "2"}, "--rounds applies to scene fits"},
        {{"--view", "a.xml:b.exr", "--min-cos", "0.1"}, "--min-cos applies to --capture"},
        {{"--view", "a.xml:b.exr", "--holdout", "1"}, "--holdout applies to --capture"},
        {{"--capture", out("nowhere")}, "nowhere': no such folder"},
        {{"--capture", dir, "--view", "a.xml:b.exr"}, "exactly one of --view"},
        {{}, "exactly one of --view"},
    };
    for (const Case& c : cases) {
        std::vector<std::string> args = {"fit"};
        args.insert(args.end(), c.args.begin(), c.args.end());
        args.insert(args.end(), {"-o", out("refused"), "--quiet"});
        const auto r = run(args);
        EXPECT_NE(r.exitCode, 0) << c.fragment;
        EXPECT_NE(r.err.find(c.fragment), std::string::npos)
            << "expected '" << c.fragment << "' in: " << r.err;
        EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
        EXPECT_FALSE(fs::exists(out("refused"))) << c.fragment;
    }
}

}  // namespace
}  // namespace phongfit
