// Kill tests of `phongfit fit` and `phongfit synth`: after SIGINT, fit writes the best parameters
// so far with "interrupted": true (and its other outputs, all valid); synth keeps every finished
// sample intact, says how to resume, and a rerun completes the dataset without touching them.
// Nothing is ever left under a temporary name.
#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <csignal>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <random>
#include <string>

#include "image.h"
#include "subprocess.h"

namespace phongfit {
namespace {

namespace fs = std::filesystem;

const std::string kSphere = std::string(PHONGFIT_SCENES_DIR) + "/sphere_point.xml";

std::string readBytes(const fs::path& file) {
    std::ifstream in(file, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

class FitSynthInterrupt : public ::testing::Test {
protected:
    void SetUp() override {
        dir_ = fs::temp_directory_path() / ("phongfit_fit_synth_kill_" + std::to_string(getpid()) +
                                            "_" + std::to_string(std::random_device{}()));
        fs::create_directories(dir_);
    }
    void TearDown() override { fs::remove_all(dir_); }

    std::string path(const std::string& name) const { return (dir_ / name).string(); }

    void expectNoTemporaries() const {
        for (const auto& entry : fs::recursive_directory_iterator(dir_))
            EXPECT_EQ(entry.path().filename().string().find(".tmp"), std::string::npos)
                << entry.path();
    }

    // Sample folders that hold truth.json, the mark of a finished sample.
    std::vector<fs::path> finishedSamples(const fs::path& dataset) const {
        std::vector<fs::path> done;
        std::error_code ec;
        for (const auto& entry : fs::recursive_directory_iterator(dataset, ec))
            if (entry.path().filename() == "truth.json") done.push_back(entry.path().parent_path());
        std::sort(done.begin(), done.end());
        return done;
    }

    // An interrupted fit's outputs are complete: fit.json says so and holds finite, energy-
    // conserving parameters, the fitted scene renders, the comparison reads, no temporary is left.
    void expectCompleteInterruptedFit(const nlohmann::json& report, int size) const {
        EXPECT_EQ(report["interrupted"], true);
        const auto& m = report["materials"]["sphere"];
        for (const char* key : {"kd", "ks"}) {
            ASSERT_EQ(m[key].size(), 3u) << key;
            for (int c = 0; c < 3; ++c) {
                EXPECT_TRUE(std::isfinite(m[key][c].get<double>())) << key;
                EXPECT_LE(m["kd"][c].get<double>() + m["ks"][c].get<double>(), 1 + 1e-9);
            }
        }
        EXPECT_TRUE(std::isfinite(m["n"].get<double>()));
        EXPECT_TRUE(std::isfinite(report["rmse"].get<double>()));
        const std::string side = std::to_string(size);
        const auto again =
            test::runPhongfit({"render", path("out/fitted.xml"), "-o", path("again.exr"), "--spp",
                               "1", "-D", "width=" + side, "-D", "height=" + side, "--quiet"});
        EXPECT_EQ(again.exitCode, 0) << again.err;
        EXPECT_EQ(cv::imread(path("out/compare.png")).rows, size);
        expectNoTemporaries();
    }

    fs::path dir_;
};

TEST_F(FitSynthInterrupt, FitWritesBestParametersSoFarAfterSigint) {
    const auto target = test::runPhongfit({"render", kSphere, "-o", path("t.exr"), "--spp", "64",
                                           "-D", "width=40", "-D", "height=40", "--quiet"});
    ASSERT_EQ(target.exitCode, 0) << target.err;
    // Far from the truth, many rounds at many paths: still fitting when round 1 is reported.
    const auto r =
        test::runPhongfit({"fit", "--view", kSphere + ":" + path("t.exr"), "--material", "sphere",
                           "--n", "3000", "--kd", "0.05", "--spp", "256", "--rounds", "100", "-D",
                           "width=40", "-D", "height=40", "-o", path("out")},
                          {[](const std::string&, const std::string& err) {
                               return err.find("round 1:") != std::string::npos;
                           },
                           {SIGINT}});
    ASSERT_EQ(r.exitCode, 0) << r.err;
    EXPECT_EQ(r.err.find("round 3:"), std::string::npos) << "the fit went on after SIGINT";
    const auto report = nlohmann::json::parse(std::ifstream(path("out/fit.json")));
    EXPECT_GE(report["rounds"].size(), 1u);
    EXPECT_LE(report["rounds"].size(), 2u) << "the round under way when the signal came, at most";
    expectCompleteInterruptedFit(report, 40);
}

TEST_F(FitSynthInterrupt, FitInterruptedInItsFirstRoundStillWritesValidOutputs) {
    const std::string cornell = std::string(PHONGFIT_SCENES_DIR) + "/cornell_phong.xml";
    const auto target = test::runPhongfit({"render", cornell, "-o", path("t.exr"), "--spp", "16",
                                           "-D", "width=32", "-D", "height=32", "--quiet"});
    ASSERT_EQ(target.exitCode, 0) << target.err;
    // Recording 2048 paths per pixel of a path-traced scene takes seconds: the signal comes
    // during the first round. The best parameters so far are then the starting ones, or better.
    const auto r =
        test::runPhongfit({"fit", "--view", cornell + ":" + path("t.exr"), "--material", "sphere",
                           "--spp", "2048", "-D", "width=32", "-D", "height=32", "-o", path("out")},
                          {test::after(std::chrono::milliseconds(300)), {SIGINT}});
    ASSERT_EQ(r.exitCode, 0) << r.err;
    expectCompleteInterruptedFit(nlohmann::json::parse(std::ifstream(path("out/fit.json"))), 32);
}

TEST_F(FitSynthInterrupt, SynthKeepsFinishedSamplesAndResumes) {
    const int samples = 12;
    std::ofstream(path("config.json"))
        << nlohmann::json{{"scenes", {kSphere}},
                          {"material", "sphere"},
                          {"samples", samples},
                          {"seed", 5},
                          {"spp", 256},
                          {"albedo", {0.4, 0.95}},
                          {"ks_share", {0.1, 0.6}},
                          {"n", {5, 500}},
                          {"defines", {{"width", 48}, {"height", 48}}}};
    const std::vector<std::string> args = {
        "synth", path("config.json"), "-o", path("dataset"), "--jobs", "1", "--quiet"};
    const fs::path dataset = path("dataset");
    const auto r = test::runPhongfit(args, {[&](const std::string&, const std::string&) {
                                                return !finishedSamples(dataset).empty();
                                            },
                                            {SIGINT}});
    ASSERT_NE(r.exitCode, 0) << "an interrupted dataset is not complete";
    EXPECT_NE(r.err.find("interrupted"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("again to resume"), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(dataset / "index.json"));
    expectNoTemporaries();

    const std::vector<fs::path> finished = finishedSamples(dataset);
    ASSERT_GE(finished.size(), 1u);
    ASSERT_LT(finished.size(), std::size_t(samples));
    std::map<fs::path, std::string> kept;
    for (const fs::path& sample : finished) {
        const Image image = readImage((sample / "image.exr").string());
        EXPECT_EQ(image.width, 48);
        for (const float v : image.rgb) ASSERT_TRUE(std::isfinite(v));
        EXPECT_TRUE(nlohmann::json::accept(std::ifstream(sample / "truth.json")));
        for (const char* file : {"image.exr", "truth.json", "scene.xml"})
            kept[sample / file] = readBytes(sample / file);
    }

    const auto resumed = test::runPhongfit(args);
    ASSERT_EQ(resumed.exitCode, 0) << resumed.err;
    const auto index = nlohmann::json::parse(std::ifstream(dataset / "index.json"));
    EXPECT_EQ(index["count"], samples);
    EXPECT_EQ(finishedSamples(dataset).size(), std::size_t(samples));
    for (const auto& [file, bytes] : kept) EXPECT_EQ(readBytes(file), bytes) << file;
    expectNoTemporaries();
}

}  // namespace
}  // namespace phongfit
