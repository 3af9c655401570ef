// `phongfit render` end to end: outputs, sidecar, interrupt, and bad input.
#include <gtest/gtest.h>

#include <csignal>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>

#include "image.h"
#include "subprocess.h"
#include "temp_dir.h"

namespace phongfit {
namespace {

namespace fs = std::filesystem;

class RenderCommand : public ::testing::Test {
protected:
    std::string path(const std::string& name) const { return (dir_ / name).string(); }
    const test::TempDir temp_{"render"};
    const fs::path& dir_ = temp_.path();
};

const std::string kScenes = PHONGFIT_SCENES_DIR;

TEST_F(RenderCommand, WritesExrPngAndSidecar) {
    const auto r = test::runPhongfit({"render", kScenes + "/sphere_point.xml", "-o", path("a.exr"),
                                      "--png", path("a.png"), "--spp", "4", "-D", "width=32", "-D",
                                      "height=24", "--seed", "3", "--quiet"});
    ASSERT_EQ(r.exitCode, 0) << r.err;
    EXPECT_NE(r.out.find("rendered 32x24 at 4 spp"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("Mrays/s"), std::string::npos);
    const Image image = readImage(path("a.exr"));
    EXPECT_EQ(image.width, 32);
    EXPECT_EQ(image.height, 24);
    double sum = 0;
    for (float v : image.rgb) sum += v;
    EXPECT_GT(sum, 0);
    EXPECT_EQ(readImage(path("a.png")).width, 32);
    const auto sidecar = nlohmann::json::parse(std::ifstream(path("a.exr.json")));
    EXPECT_EQ(sidecar["seed"], 3);
    EXPECT_EQ(sidecar["spp"], 4);
    EXPECT_EQ(sidecar["sampler"], "mixture");
    EXPECT_EQ(sidecar["pixel_sampler"], "sobol");  // as the scene names it
    EXPECT_EQ(sidecar["samples"], 4 * 32 * 24);
    EXPECT_EQ(sidecar["interrupted"], false);
    EXPECT_GT(sidecar["rays"].get<double>(), 0);
    EXPECT_EQ(sidecar["defines"]["width"], "32");
    // What a fit checks its scene against (render_sidecar.h): the scene's box, depth 2.
    EXPECT_EQ(sidecar["pixel_filter"], nlohmann::json({{"type", "box"}}));
    EXPECT_EQ(sidecar["max_depth"], 2);
}

// --pixel-sampler overrides the scene's <sampler type>: a different image of the same mean; a name
// that is not one is refused on one line.
TEST_F(RenderCommand, PixelSamplerOverridesTheScenes) {
    const std::vector<std::string> args = {
        "render", kScenes + "/sphere_point.xml", "--spp", "64", "-D", "width=32", "-D", "height=24",
        "--quiet"};
    auto with = [&](std::vector<std::string> extra) {
        std::vector<std::string> all = args;
        all.insert(all.end(), extra.begin(), extra.end());
        return test::runPhongfit(all);
    };
    ASSERT_EQ(with({"-o", path("s.exr")}).exitCode, 0);  // the scene names sobol
    const auto r = with({"-o", path("i.exr"), "--pixel-sampler", "independent"});
    ASSERT_EQ(r.exitCode, 0) << r.err;
    EXPECT_EQ(nlohmann::json::parse(std::ifstream(path("i.exr.json")))["pixel_sampler"],
              "independent");
    const Image independent = readImage(path("i.exr")), sobol = readImage(path("s.exr"));
    ASSERT_EQ(independent.rgb.size(), sobol.rgb.size());
    double a = 0, b = 0;
    for (std::size_t i = 0; i < sobol.rgb.size(); ++i) {
        a += independent.rgb[i];
        b += sobol.rgb[i];
    }
    EXPECT_NE(independent.rgb, sobol.rgb);
    EXPECT_NEAR(b / a, 1, 0.01);
    const auto bad = with({"-o", path("x.exr"), "--pixel-sampler", "halton"});
    EXPECT_NE(bad.exitCode, 0);
    EXPECT_NE(bad.err.find("--pixel-sampler"), std::string::npos) << bad.err;
    EXPECT_FALSE(fs::exists(path("x.exr")));
}

TEST_F(RenderCommand, SigintWritesAValidPartialImage) {
    const auto r =
        test::runPhongfit({"render", kScenes + "/cornell_phong.xml", "-o", path("c.exr"), "--spp",
                           "100000", "-D", "width=64", "-D", "height=64", "--quiet"},
                          {test::after(std::chrono::milliseconds(1500)), {SIGINT}});
    ASSERT_EQ(r.exitCode, 0) << r.err;
    EXPECT_NE(r.out.find("interrupted: the image holds"), std::string::npos) << r.out;
    const Image image = readImage(path("c.exr"));
    ASSERT_EQ(image.pixelCount(), 64u * 64u);
    int black = 0;
    for (std::size_t p = 0; p < image.pixelCount(); ++p) {
        ASSERT_TRUE(std::isfinite(image.rgb[3 * p]));
        black += image.rgb[3 * p] == 0 && image.rgb[3 * p + 1] == 0 && image.rgb[3 * p + 2] == 0;
    }
    EXPECT_LT(black, 64 * 64 / 10) << "every pixel should hold samples";
    const auto sidecar = nlohmann::json::parse(std::ifstream(path("c.exr.json")));
    EXPECT_EQ(sidecar["interrupted"], true);
    EXPECT_GE(sidecar["samples"].get<double>(), 64 * 64);
    EXPECT_LT(sidecar["samples"].get<double>(), 100000.0 * 64 * 64);
    for (const auto& entry : fs::directory_iterator(dir_))
        EXPECT_EQ(entry.path().string().find(".tmp"), std::string::npos) << entry.path();
}

TEST_F(RenderCommand, BadInputGivesOneLineAndNoOutput) {
    const std::vector<std::pair<std::vector<std::string>, std::string>> cases = {
        {{"render", path("missing.xml"), "-o", path("x.exr")}, "missing.xml"},
        {{"render", kScenes + "/sphere_point.xml", "-o", path("x.exr"), "-D", "kd=0.9", "-D",
          "ks=0.3"},
         "exceeds 1"},
        {{"render", kScenes + "/sphere_point.xml", "-o", path("x.exr"), "-D", "width=0"}, "width"},
        {{"render", kScenes + "/sphere_point.xml", "-o", path("x.exr"), "--sampler", "bogus"},
         "bogus"},
        {{"render", kScenes + "/sphere_point.xml", "-o", path("no/such/dir/x.exr"), "--spp", "1"},
         "no/such/dir"},
    };
    for (const auto& [args, fragment] : cases) {
        const auto r = test::runPhongfit(args);
        EXPECT_NE(r.exitCode, 0) << fragment;
        EXPECT_NE(r.err.find(fragment), std::string::npos) << r.err;
        EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
        EXPECT_FALSE(fs::exists(path("x.exr"))) << fragment;
    }
}

}  // namespace
}  // namespace phongfit
