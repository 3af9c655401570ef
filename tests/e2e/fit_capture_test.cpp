// `phongfit fit --capture` end to end on a synthetic capture: fit.json and compare.png, and bad
// input refused with one line and nothing written.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <string>
#include <vector>

#include "image.h"
#include "subprocess.h"
#include "synthetic_capture.h"
#include "temp_dir.h"

namespace phongfit {
namespace {

namespace fs = std::filesystem;
using test::Synthetic;

class CaptureCommand : public ::testing::Test {
protected:
    void SetUp() override { Synthetic().write(dir_.path()); }
    std::string out(const std::string& name) const { return (dir_.path() / name).string(); }

    test::TempDir dir_{"capture_command"};
};

TEST_F(CaptureCommand, WritesReportAndComparison) {
    const auto r =
        test::runPhongfit({"fit", "--capture", dir_.path().string(), "--lights", "1-20",
                           "--holdout", "21-30", "--threads", "2", "-o", out("fit"), "--quiet"});
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

// --albedo per-pixel: a kd per mask pixel (kd.exr, kd.png), one ks and n, the held-out lights
// against the per-pixel Lambertian baseline.
TEST_F(CaptureCommand, PerPixelAlbedoWritesTheMapAndTheHoldoutComparison) {
    const auto r =
        test::runPhongfit({"fit", "--capture", dir_.path().string(), "--albedo", "per-pixel",
                           "--holdout", "21-30", "--threads", "2", "-o", out("map"), "--quiet"});
    ASSERT_EQ(r.exitCode, 0) << r.err;
    EXPECT_NE(r.out.find("capture, per-pixel albedo: ks = "), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("per-pixel Lambertian"), std::string::npos) << r.out;

    const auto report = nlohmann::json::parse(std::ifstream(out("map/fit.json")));
    EXPECT_EQ(report["albedo"], "per-pixel");
    EXPECT_EQ(report["model"]["albedo"], "per-pixel");
    const Synthetic truth;
    for (int c = 0; c < 3; ++c)
        EXPECT_NEAR(report["ks"][c].get<double>(), truth.truth.ks[c], 0.05 * truth.truth.ks[c]);
    EXPECT_NEAR(report["n"].get<double>(), truth.truth.n, 0.1 * truth.truth.n);
    EXPECT_GT(report["n_std"].get<double>(), 0);
    EXPECT_EQ(report["unconstrained"].size(), 0u);
    const int fitted = report["kd_map"]["fitted_pixels"].get<int>();
    EXPECT_EQ(fitted + report["pixels"]["too_few_pairs"].get<int>(),
              report["capture"]["mask_pixels"].get<int>());
    const auto& h = report["holdout"];
    ASSERT_EQ(h["per_light"].size(), 10u);
    EXPECT_LT(h["rmse"].get<double>(), h["lambertian_rmse"].get<double>());
    EXPECT_EQ(report["compare"]["rows"], nlohmann::json({"phong", "lambertian per pixel"}));

    // The map: the truth's kd at the centre of the sphere, black outside the mask.
    const Image kd = readImage(out("map/kd.exr"));
    ASSERT_EQ(kd.width, Synthetic::kSize);
    ASSERT_EQ(kd.height, Synthetic::kSize);
    const Color<float> centre = kd.at(Synthetic::kSize / 2, Synthetic::kSize / 2);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(centre[c], truth.truth.kd[c], 0.02) << c;
    EXPECT_TRUE((kd.at(0, 0) == 0).all());
    EXPECT_FALSE(cv::imread(out("map/kd.png")).empty());
    EXPECT_FALSE(cv::imread(out("map/compare.png")).empty());
    EXPECT_FALSE(fs::exists(out("map/materials.png")));

    // --materials 2: a lobe per material (here both the truth's) and the material map.
    const auto k =
        test::runPhongfit({"fit", "--capture", dir_.path().string(), "--albedo", "per-pixel",
                           "--materials", "2", "--threads", "2", "-o", out("two"), "--quiet"});
    ASSERT_EQ(k.exitCode, 0) << k.err;
    EXPECT_NE(k.out.find("  material 2 ("), std::string::npos) << k.out;
    const auto two = nlohmann::json::parse(std::ifstream(out("two/fit.json")));
    ASSERT_EQ(two["lobes"].size(), 2u);
    EXPECT_EQ(two["model"]["materials"], 2);
    EXPECT_FALSE(two.contains("n")) << "with several lobes, none stands for the object";
    for (const auto& lobe : two["lobes"])
        EXPECT_NEAR(lobe["n"].get<double>(), truth.truth.n, 0.1 * truth.truth.n);
    EXPECT_EQ(two["lobes"][0]["pixels"].get<int>() + two["lobes"][1]["pixels"].get<int>(),
              two["kd_map"]["fitted_pixels"].get<int>());
    const cv::Mat materials = cv::imread(out("two/materials.png"));
    ASSERT_FALSE(materials.empty());
    EXPECT_EQ(materials.cols, Synthetic::kSize);
}

// A light_intensities.txt with one value for every light reads as relative intensities: kd and
// ks in image units, no energy bound, said on the console and in fit.json; --intensities
// calibrated takes them as absolute and warns when the fit ends on the energy bound.
TEST_F(CaptureCommand, EqualIntensitiesAreTakenAsRelative) {
    const test::TempDir relative("capture_relative");
    Synthetic synth;
    synth.commonIntensity = 0.3;
    synth.write(relative.path());
    const auto r = test::runPhongfit({"fit", "--capture", relative.path().string(), "--threads",
                                      "2", "-o", out("relative"), "--quiet"});
    ASSERT_EQ(r.exitCode, 0) << r.err;
    EXPECT_NE(r.out.find("light intensities: relative (every light has the same intensity"),
              std::string::npos)
        << r.out;
    EXPECT_EQ(r.out.find("warning"), std::string::npos) << r.out;
    const auto report = nlohmann::json::parse(std::ifstream(out("relative/fit.json")));
    const double scale = synth.commonIntensity / Synthetic::kWrittenIntensity;
    EXPECT_NEAR(report["materials"]["capture"]["kd"][0].get<double>(), scale * synth.truth.kd[0],
                0.02 * scale * synth.truth.kd[0]);
    EXPECT_NE(report["units"].get<std::string>().find("no energy bound"), std::string::npos);

    const auto c =
        test::runPhongfit({"fit", "--capture", relative.path().string(), "--intensities",
                           "calibrated", "--threads", "2", "-o", out("calibrated"), "--quiet"});
    ASSERT_EQ(c.exitCode, 0) << c.err;
    EXPECT_NE(c.out.find("light intensities: calibrated\n"), std::string::npos) << c.out;
    EXPECT_NE(c.out.find("warning: the fit ended on kd + ks = 1"), std::string::npos) << c.out;
    const auto calibrated = nlohmann::json::parse(std::ifstream(out("calibrated/fit.json")));
    EXPECT_TRUE(calibrated["energy_bound_reached"].get<bool>());
}

// The photographs' decoding is checked against the model: linear codes read as sRGB (the 8-bit
// default) and sRGB codes read as linear are both named, with the flag that reads them right; the
// right reading gives no warning.
TEST_F(CaptureCommand, WrongDecodingIsNamed) {
    struct Case {
        std::string dir;
        std::vector<std::string> flags;
        std::string warning;  // empty: none
    };
    // The synthetic capture's 16-bit linear codes, re-encoded as 8-bit sRGB.
    const test::TempDir srgb("capture_srgb");
    for (const auto& entry : fs::directory_iterator(dir_.path())) {
        const fs::path to = srgb.path() / entry.path().filename();
        const std::string name = entry.path().filename().string();
        if (name.size() != 7 || entry.path().extension() != ".png") {
            fs::copy_file(entry.path(), to);
            continue;
        }
        const cv::Mat linear = cv::imread(entry.path().string(), cv::IMREAD_UNCHANGED);
        cv::Mat encoded(linear.size(), CV_8UC3);
        for (int y = 0; y < linear.rows; ++y)
            for (int x = 0; x < linear.cols; ++x)
                for (int c = 0; c < 3; ++c)
                    encoded.at<cv::Vec3b>(y, x)[c] = cv::saturate_cast<uchar>(
                        255 * linearToSrgb(linear.at<cv::Vec3w>(y, x)[c] / 65535.0) + 0.5);
        cv::imwrite(to.string(), encoded);
    }
    const std::string pot2 = PHONGFIT_POT2_DIR;
    const std::vector<Case> cases = {
        {pot2, {"--lights", "1-32"}, "warning: the photographs look linear, not sRGB"},
        {pot2, {"--lights", "1-32", "--linear"}, ""},
        {srgb.path().string(), {"--linear"}, "warning: the photographs look sRGB, not linear"},
        {srgb.path().string(), {}, ""},
    };
    for (const Case& c : cases) {
        std::vector<std::string> args = {"fit",           "--capture", c.dir, "--albedo",
                                         "per-pixel",     "--threads", "2",   "-o",
                                         out("decoding"), "--quiet"};
        args.insert(args.end(), c.flags.begin(), c.flags.end());
        const auto r = test::runPhongfit(args);
        ASSERT_EQ(r.exitCode, 0) << r.err;
        const auto report = nlohmann::json::parse(std::ifstream(out("decoding/fit.json")));
        EXPECT_EQ(report["decoding_check"]["other_fits_better"].get<bool>(), !c.warning.empty())
            << c.dir << " " << report["decoding_check"].dump();
        if (c.warning.empty())
            EXPECT_EQ(r.out.find("warning"), std::string::npos) << r.out;
        else
            EXPECT_NE(r.out.find(c.warning), std::string::npos) << r.out;
    }
}

// DiLiGenT's pot2 (the public 8-bit linear crop) has 73 zero normals inside its mask: they are
// left out and counted, and the rest is fitted.
TEST_F(CaptureCommand, RealCaptureWithZeroNormalsIsFittedWithThemCounted) {
    const auto r = test::runPhongfit({"fit", "--capture", PHONGFIT_POT2_DIR, "--linear", "--lights",
                                      "1-8", "--threads", "2", "-o", out("pot2"), "--quiet"});
    ASSERT_EQ(r.exitCode, 0) << r.err;
    EXPECT_NE(r.out.find("left out 73 pixels of the mask whose normal is zero, not unit or not "
                         "finite"),
              std::string::npos)
        << r.out;
    EXPECT_NE(r.out.find("photographs: 8-bit, read as linear\n"), std::string::npos) << r.out;
    const auto report = nlohmann::json::parse(std::ifstream(out("pot2/fit.json")));
    EXPECT_EQ(report["decoding"], "8-bit, read as linear");
    EXPECT_EQ(report["pixels"]["bad_normals"], 73);
    EXPECT_EQ(report["pixels"]["used"], report["capture"]["mask_pixels"]);
    EXPECT_GT(report["pixels"]["used"].get<int>(), 10000);
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
        {{"--capture", dir, "--albedo", "per-pixel", "--loss", "huber"},
         "--albedo per-pixel fits least squares"},
        {{"--capture", dir, "--albedo", "texture"}, "--albedo"},
        {{"--capture", dir, "--intensities", "guessed"}, "--intensities"},
        {{"--capture", dir, "--materials", "2"}, "--materials 2: applies to --albedo per-pixel"},
        {{"--capture", dir, "--albedo", "per-pixel", "--materials", "17"}, "--materials"},
        {{"--view", "a.xml:b.exr", "--albedo", "per-pixel"}, "--albedo applies to --capture"},
    };
    for (const Case& c : cases) {
        std::vector<std::string> args = {"fit"};
        args.insert(args.end(), c.args.begin(), c.args.end());
        args.insert(args.end(), {"-o", out("refused"), "--quiet"});
        const auto r = test::runPhongfit(args);
        EXPECT_NE(r.exitCode, 0) << c.fragment;
        EXPECT_NE(r.err.find(c.fragment), std::string::npos)
            << "expected '" << c.fragment << "' in: " << r.err;
        EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
        EXPECT_FALSE(fs::exists(out("refused"))) << c.fragment;
    }
}
}  // namespace
}  // namespace phongfit
