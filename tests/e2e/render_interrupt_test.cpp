// Kill tests of `phongfit render`: SIGINT/SIGTERM give a valid partial image with its sidecar, a
// second signal ends the run at once without an output, and SIGKILL never leaves a half-written
// file (a previous output survives untouched). Nothing is ever left under a temporary name.
#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <csignal>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <nlohmann/json.hpp>
#include <random>
#include <string>

#include "image.h"
#include "subprocess.h"

namespace phongfit {
namespace {

namespace fs = std::filesystem;
using std::chrono::milliseconds;
using test::after;

const std::string kCornell = std::string(PHONGFIT_SCENES_DIR) + "/cornell_phong.xml";

std::string readBytes(const fs::path& file) {
    std::ifstream in(file, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

class RenderInterrupt : public ::testing::Test {
protected:
    void SetUp() override {
        dir_ = fs::temp_directory_path() / ("phongfit_render_kill_" + std::to_string(getpid()) +
                                            "_" + std::to_string(std::random_device{}()));
        fs::create_directories(dir_);
    }
    void TearDown() override { fs::remove_all(dir_); }

    std::string path(const std::string& name) const { return (dir_ / name).string(); }

    // Renders the Cornell box at `side` x `side` for far longer than the test waits. It prints
    // nothing while it runs (stderr is not a terminal): signals go after a delay counted from
    // the installation of its handler, which comes before the scene is even read.
    test::ProcessResult render(int side, const test::SignalPlan& plan) const {
        return test::runPhongfit(
            {"render", kCornell, "-o", path("out.exr"), "--spp", "100000", "-D",
             "width=" + std::to_string(side), "-D", "height=" + std::to_string(side), "--quiet"},
            plan);
    }

    void expectNoTemporaries() const {
        for (const auto& entry : fs::directory_iterator(dir_))
            EXPECT_EQ(entry.path().filename().string().find(".tmp"), std::string::npos)
                << entry.path();
    }

    // The EXR is complete and finite, and the sidecar says it holds fewer samples than asked.
    void expectValidPartialImage(int side) const {
        const Image image = readImage(path("out.exr"));
        ASSERT_EQ(image.width, side);
        ASSERT_EQ(image.height, side);
        for (const float v : image.rgb) ASSERT_TRUE(std::isfinite(v));
        const auto sidecar = nlohmann::json::parse(std::ifstream(path("out.exr.json")));
        EXPECT_EQ(sidecar["interrupted"], true);
        EXPECT_GE(sidecar["samples"].get<double>(), double(side) * side)
            << "the first pass gives every pixel a sample";
        EXPECT_LT(sidecar["samples"].get<double>(), 100000.0 * side * side);
        expectNoTemporaries();
    }

    fs::path dir_;
};

TEST_F(RenderInterrupt, SigtermWritesAValidPartialImage) {
    const auto r = render(48, {after(milliseconds(1500)), {SIGTERM}});
    ASSERT_EQ(r.exitCode, 0) << r.err;
    EXPECT_NE(r.out.find("interrupted: the image holds"), std::string::npos) << r.out;
    expectValidPartialImage(48);
}

TEST_F(RenderInterrupt, SigintDuringTheFirstPassStillSamplesEveryPixel) {
    // At 640x640 the first pass (one sample per pixel, not interruptible) is still running.
    const auto r = render(640, {after(milliseconds(300)), {SIGINT}});
    ASSERT_EQ(r.exitCode, 0) << r.err;
    expectValidPartialImage(640);
}

TEST_F(RenderInterrupt, SecondSignalEndsAtOnceWithoutOutput) {
    const auto r = render(1024, {after(milliseconds(300)), {SIGINT, SIGINT}, milliseconds(20)});
    EXPECT_EQ(r.exitCode, 128 + SIGINT) << r.err;
    EXPECT_FALSE(fs::exists(path("out.exr")));
    EXPECT_FALSE(fs::exists(path("out.exr.json")));
    expectNoTemporaries();
}

TEST_F(RenderInterrupt, SigkillLeavesThePreviousOutputUntouched) {
    Image old(2, 3);
    old.set(1, 2, Color<float>(0.25f, 0.5f, 1.0f));
    writeExr(old, path("out.exr"));
    const std::string before = readBytes(path("out.exr"));
    const auto r = render(48, {after(milliseconds(2000)), {SIGKILL}});
    EXPECT_EQ(r.signal, SIGKILL);
    EXPECT_EQ(readBytes(path("out.exr")), before);
    EXPECT_FALSE(fs::exists(path("out.exr.json")));
    expectNoTemporaries();
}

}  // namespace
}  // namespace phongfit
