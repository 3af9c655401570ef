// `phongfit fit` end to end: the outputs a user gets, and every kind of bad input refused with one
// line, a non-zero exit and nothing written.
#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfOutputFile.h>
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <map>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <random>

#include "image.h"
#include "precision_claim.h"
#include "raw_exr.h"
#include "subprocess.h"

namespace phongfit {
namespace {

namespace fs = std::filesystem;

const std::string kScenes = PHONGFIT_SCENES_DIR;
const std::string kSphere = kScenes + "/sphere_point.xml";
constexpr int kSize = 40;

class FitCommand : public ::testing::Test {
protected:
    static void SetUpTestSuite() {
        dir_ = fs::temp_directory_path() / ("phongfit_fit_" + std::to_string(getpid()) + "_" +
                                            std::to_string(std::random_device{}()));
        fs::create_directories(dir_);
        const auto r = run({"render", kSphere, "-o", path("sphere.exr"), "--spp", "64", "--quiet"});
        ASSERT_EQ(r.exitCode, 0) << r.err;
    }
    static void TearDownTestSuite() { fs::remove_all(dir_); }

    static std::string path(const std::string& name) { return (dir_ / name).string(); }
    // kSphere with its film's box filter replaced by `filter`, written as `name`.
    static std::string sceneWithFilter(const std::string& name, const std::string& filter) {
        std::ifstream in(kSphere);
        std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
        const std::string box = R"(<rfilter type="box"/>)";
        EXPECT_NE(text.find(box), std::string::npos);
        text.replace(text.find(box), box.size(), filter);
        std::ofstream(path(name)) << text;
        return path(name);
    }
    // `fit` of `image` through `scene` into `out`, at its defaults: what it prints, and fit.json.
    static std::pair<std::string, nlohmann::json> fitWithEdges(const std::string& scene,
                                                               const std::string& image,
                                                               const std::string& out) {
        const auto r =
            run({"fit", "--view", scene + ":" + image, "--material", "sphere", "-o", path(out)});
        EXPECT_EQ(r.exitCode, 0) << r.err;
        return {r.out, nlohmann::json::parse(std::ifstream(path(out + "/fit.json")))};
    }
    static test::ProcessResult run(std::vector<std::string> args) {
        for (const char* d : {"width", "height"}) {
            if (!args.empty() && (args[0] == "render" || args[0] == "fit")) {
                args.push_back("-D");
                args.push_back(std::string(d) + "=" + std::to_string(kSize));
            }
        }
        return test::runPhongfit(args);
    }
    static fs::path dir_;
};
fs::path FitCommand::dir_;

// A PFM (what Tungsten writes without OpenEXR) of the same pixels fits to the same digits as the
// EXR: the reader keeps every float and the rows' order (stored from the bottom up).
TEST_F(FitCommand, APfmImageFitsAsItsExr) {
    const Image image = readImage(path("sphere.exr"));
    std::string bytes =
        "PF\n" + std::to_string(image.width) + " " + std::to_string(image.height) + "\n-1.0\n";
    for (int y = image.height - 1; y >= 0; --y)
        for (int x = 0; x < image.width; ++x)
            for (int c = 0; c < 3; ++c) {
                const float v = image.at(x, y)[c];
                bytes.append(reinterpret_cast<const char*>(&v), sizeof v);
            }
    std::ofstream(path("sphere.pfm"), std::ios::binary) << bytes;
    nlohmann::json materials[2];
    for (const char* format : {"exr", "pfm"}) {
        const std::string out = path(std::string("as_") + format);
        const auto r = run({"fit", "--view", kSphere + ":" + path("sphere.") + format, "--material",
                            "sphere", "--n", "300", "-o", out, "--quiet"});
        ASSERT_EQ(r.exitCode, 0) << r.err;
        materials[format[0] == 'p'] =
            nlohmann::json::parse(std::ifstream(out + "/fit.json"))["materials"];
    }
    EXPECT_EQ(materials[1], materials[0]);
}

// `image` as a float RGB EXR framed in its own size, with data window `data`: the image's pixels
// where the two meet, NaN beyond the frame (overscan).
void writeFramedExr(const Image& image, const Imath::Box2i& data, const std::string& file) {
    Image pixels(data.max.x - data.min.x + 1, data.max.y - data.min.y + 1);
    std::fill(pixels.rgb.begin(), pixels.rgb.end(), std::numeric_limits<float>::quiet_NaN());
    for (int y = data.min.y; y <= data.max.y; ++y)
        for (int x = data.min.x; x <= data.max.x; ++x)
            if (x >= 0 && x < image.width && y >= 0 && y < image.height)
                pixels.set(x - data.min.x, y - data.min.y, image.at(x, y));
    test::writeRawExr(pixels, Imath::Box2i({0, 0}, {image.width - 1, image.height - 1}), data,
                      file);
}

// An EXR is placed in its display window, the frame the renderer rendered: an overscan fits as the
// frame alone (its NaN beyond the frame never read), and a crop window's render fits on the pixels
// it holds, the others left out and counted.
TEST_F(FitCommand, AnExrFitsInItsDisplayWindow) {
    const Image image = readImage(path("sphere.exr"));
    writeFramedExr(image, Imath::Box2i({-2, -3}, {kSize + 1, kSize + 2}), path("overscan.exr"));
    constexpr int kCropX = 16;  // the crop keeps the highlight (the light is up and to the right)
    writeFramedExr(image, Imath::Box2i({kCropX, 0}, {kSize - 1, kSize - 1}), path("crop.exr"));
    std::map<std::string, nlohmann::json> reports;
    std::map<std::string, std::string> outs;
    for (const std::string name : {"sphere", "overscan", "crop"}) {
        const auto r = run({"fit", "--view", kSphere + ":" + path(name + ".exr"), "--material",
                            "sphere", "--n", "300", "-o", path("framed_" + name), "--quiet"});
        ASSERT_EQ(r.exitCode, 0) << r.err;
        reports[name] = nlohmann::json::parse(std::ifstream(path("framed_" + name + "/fit.json")));
        outs[name] = r.out;
    }
    EXPECT_EQ(reports["overscan"]["materials"], reports["sphere"]["materials"]);
    EXPECT_EQ(reports["overscan"]["views"][0]["pixels_without_data"], 0);
    EXPECT_EQ(outs["overscan"].find("data window"), std::string::npos) << outs["overscan"];

    const auto& crop = reports["crop"];
    EXPECT_EQ(crop["views"][0]["pixels_without_data"], kCropX * kSize);
    EXPECT_NE(outs["crop"].find(std::to_string(kCropX * kSize) +
                                " pixels outside the image's data window"),
              std::string::npos)
        << outs["crop"];
    EXPECT_LT(crop["pixels_used"], reports["sphere"]["pixels_used"]);
    // The scene's own parameters, each within 3 of the crop's standard errors.
    const auto& m = crop["materials"]["sphere"];
    for (int c = 0; c < 3; ++c) {
        EXPECT_LE(std::abs(m["kd"][c].get<double>() - 0.5), 3 * m["kd_std"][c].get<double>());
        EXPECT_LE(std::abs(m["ks"][c].get<double>() - 0.3), 3 * m["ks_std"][c].get<double>());
    }
    EXPECT_LE(std::abs(m["n"].get<double>() - 30), 3 * m["n_std"].get<double>());

    // Data wholly beyond the frame: nothing to fit, one line.
    writeFramedExr(image, Imath::Box2i({kSize, 0}, {kSize + 3, 3}), path("apart.exr"));
    const auto r = run({"fit", "--view", kSphere + ":" + path("apart.exr"), "--material", "sphere",
                        "-o", path("framed_apart"), "--quiet"});
    EXPECT_NE(r.exitCode, 0);
    EXPECT_NE(r.err.find("outside the EXR's data window: nothing to fit"), std::string::npos)
        << r.err;
    EXPECT_FALSE(fs::exists(path("framed_apart")));
}

// Pixels left out of a fit are counted by why, in fit.json and on the console: NaN pixels (with
// --ignore-nonfinite) and masked ones.
TEST_F(FitCommand, LeftOutPixelsAreCountedByWhy) {
    Image image = readImage(path("sphere.exr"));
    for (int x : {18, 19, 20}) image.set(x, 20, Color<float>::Constant(std::nanf("")));
    test::writeRawExr(image, path("nan.exr"));
    cv::Mat mask(kSize, kSize, CV_8U, cv::Scalar(255));
    mask(cv::Rect(10, 10, 4, 4)).setTo(0);
    cv::imwrite(path("mask.png"), mask);
    const auto r =
        run({"fit", "--view", kSphere + ":" + path("nan.exr"), "--material", "sphere", "--n", "300",
             "--ignore-nonfinite", "--mask", path("mask.png"), "-o", path("left_out"), "--quiet"});
    ASSERT_EQ(r.exitCode, 0) << r.err;
    const auto view = nlohmann::json::parse(std::ifstream(path("left_out/fit.json")))["views"][0];
    EXPECT_EQ(view["pixels_non_finite"], 3);
    EXPECT_EQ(view["pixels_masked"], 16);
    EXPECT_EQ(view["pixels_clipped"], 0);
    EXPECT_NE(r.out.find("; 16 pixels masked; 3 pixels not finite (--ignore-nonfinite)"),
              std::string::npos)
        << r.out;
    EXPECT_EQ(r.out.find("clipped"), std::string::npos) << r.out;
}

TEST_F(FitCommand, WritesReportFittedSceneAndComparison) {
    const auto r = run({"fit", "--view", kSphere + ":" + path("sphere.exr"), "--material", "sphere",
                        "--n", "300", "--kd", "0.3", "-o", path("out"), "--quiet"});
    ASSERT_EQ(r.exitCode, 0) << r.err;
    EXPECT_NE(r.out.find("sphere: kd = "), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("left out: indirect bounces"), std::string::npos) << r.out;

    const auto report = nlohmann::json::parse(std::ifstream(path("out/fit.json")));
    const auto& m = report["materials"]["sphere"];
    for (const char* key : {"kd", "ks", "kd_std", "ks_std"}) ASSERT_EQ(m[key].size(), 3u) << key;
    EXPECT_TRUE(m["n"].is_number());
    EXPECT_TRUE(m["n_std"].is_number());
    EXPECT_TRUE(m["unconstrained"].is_array());
    EXPECT_TRUE(report["rmse"].is_number());
    EXPECT_GE(report["rounds"].size(), 1u);
    EXPECT_TRUE(report["rounds"][0]["time_s"].is_number());
    // The pixels off the sphere (the background) are left out and record no path.
    const auto& view = report["views"][0];
    const std::size_t off = view["pixels_off_the_materials"].get<std::size_t>();
    EXPECT_GT(off, 0u);
    EXPECT_EQ(view["pixels_masked"].get<std::size_t>() + view["pixels_clipped"].get<std::size_t>() +
                  view["pixels_non_finite"].get<std::size_t>(),
              0u);
    const std::size_t kept = kSize * kSize - off;
    for (const auto& round : report["rounds"]) {
        // Two path sets, each with at least a background colour and a term index per pixel.
        const auto recorded = round["recorded_bytes"].get<std::size_t>();
        EXPECT_GE(recorded, 2u * kSize * kSize * (3 * sizeof(float) + sizeof(std::uint32_t)));
        EXPECT_GT(round["peak_memory_bytes"].get<std::size_t>(), recorded);
        // Two sets of 4 paths per pixel kept.
        EXPECT_EQ(round["paths"].get<std::size_t>(), 2u * 4 * kept);
    }
    // At the default --precision a converged fit met it or the images' noise floor; "precision"
    // holds for the standard errors reported (kd, ks relative to max(value, 0.1), log n).
    const std::string stop = report["stop_reason"];
    if (report["converged"].get<bool>())
        EXPECT_TRUE(stop == "precision" || stop == "noise floor") << stop;
    else
        EXPECT_TRUE(stop == "rounds" || stop == "precision not met" || stop == "unresolved" ||
                    stop == "rounds disagree")
            << stop;
    test::expectPrecisionClaimHolds(report, 0.01);
    EXPECT_FALSE(report.contains("exposure")) << "only with --fit-exposure";
    EXPECT_EQ(report["views"][0]["max_depth"], 2);
    // The image's render settings come from what `phongfit render` wrote beside it, not the
    // scene's sampleCount (4 by default here).
    const auto& as = report["views"][0]["image_rendered_as"];
    EXPECT_EQ(as["spp"], 64) << as.dump();
    EXPECT_EQ(as["pixel_sampler"], "sobol") << as.dump();
    EXPECT_EQ(as["from"], path("sphere.exr") + ".json") << as.dump();
    EXPECT_NEAR(m["n"].get<double>(), 30, 30 * 0.1)
        << "a coarse check; recovery is tested elsewhere";

    // fitted.xml renders, with the fitted values in it.
    const auto again =
        run({"render", path("out/fitted.xml"), "-o", path("again.exr"), "--spp", "4", "--quiet"});
    ASSERT_EQ(again.exitCode, 0) << again.err;
    const cv::Mat compare = cv::imread(path("out/compare.png"));
    EXPECT_EQ(compare.cols, 3 * kSize);
    EXPECT_EQ(compare.rows, kSize);
}

// One sphere under area and environment light needs direct light only when no other surface can
// send light back to it: the area light of sphere_sharp_area.xml is black, that of sphere_quad.xml
// has Mitsuba's default diffuse surface, which reflects the sphere's light back onto it, but the
// scene's own integrator asks for direct light alone. Rings integrate both lights, and fit.json
// says so (the demo's Cornell box samples its light).
TEST_F(FitCommand, LeavesOutIndirectLightOnlyWhereNothingElseReflects) {
    const std::vector<std::array<std::string, 3>> cases = {
        {"sphere_sharp_area.xml", "left out: indirect bounces (one convex object", "rings"},
        {"sphere_quad.xml", "left out: nothing (the scene's integrator is \"direct\"", "rings"}};
    for (const auto& [scene, expected, areaLights] : cases) {
        const std::string file = kScenes + "/" + scene, image = path(scene + ".exr");
        const std::vector<std::string> lobe = {"-D", "n=30", "-D", "spp=16"};
        std::vector<std::string> args = {"render", file, "-o", image, "--quiet"};
        args.insert(args.end(), lobe.begin(), lobe.end());
        ASSERT_EQ(run(args).exitCode, 0);
        args = {"fit", "--view", file + ":" + image,   "--material", "sphere", "--rounds",
                "1",   "-o",     path(scene + "_fit"), "--quiet"};
        args.insert(args.end(), lobe.begin(), lobe.end());
        const auto r = run(args);
        ASSERT_EQ(r.exitCode, 0) << r.err;
        EXPECT_NE(r.out.find(expected), std::string::npos) << scene << ":\n" << r.out;
        const auto report = nlohmann::json::parse(std::ifstream(path(scene + "_fit/fit.json")));
        EXPECT_EQ(report["area_lights"], areaLights) << scene;
        EXPECT_EQ(report["views"][0]["area_lights"], areaLights) << scene;
    }
}

// --time-budget: no round starts past it, the first always runs, and the report says so. A 1e-9 s
// budget is spent before the first round ends; the round's solve stops there.
TEST_F(FitCommand, TimeBudgetStopsTheRoundsAndSaysSo) {
    const auto r =
        run({"fit", "--view", kSphere + ":" + path("sphere.exr"), "--material", "sphere", "--n",
             "300", "--kd", "0.3", "--time-budget", "1e-9", "-o", path("budget"), "--quiet"});
    ASSERT_EQ(r.exitCode, 0) << r.err;
    EXPECT_NE(r.out.find("(not converged: the time budget was spent)"), std::string::npos) << r.out;
    const auto report = nlohmann::json::parse(std::ifstream(path("budget/fit.json")));
    EXPECT_EQ(report["stop_reason"], "time budget");
    EXPECT_FALSE(report["converged"].get<bool>());
    EXPECT_FALSE(report["interrupted"].get<bool>());
    EXPECT_EQ(report["rounds"].size(), 1u);
    EXPECT_EQ(report["area_lights"], "none");  // a point light

    // One round allowed and not enough: the report names the rounds, not the budget.
    const auto once =
        run({"fit", "--view", kSphere + ":" + path("sphere.exr"), "--material", "sphere", "--n",
             "300", "--kd", "0.3", "--rounds", "1", "-o", path("once"), "--quiet"});
    ASSERT_EQ(once.exitCode, 0) << once.err;
    EXPECT_NE(once.out.find("(not converged: 1 round spent and the last still moved)"),
              std::string::npos)
        << once.out;
    EXPECT_EQ(nlohmann::json::parse(std::ifstream(path("once/fit.json")))["stop_reason"], "rounds");
}

// --max-memory below what the process holds: the fit fails before recording, with one line saying
// what it needs and what is available, and writes no report.
TEST_F(FitCommand, MaxMemoryTooSmallFailsBeforeRecording) {
    const auto r = run({"fit", "--view", kSphere + ":" + path("sphere.exr"), "--material", "sphere",
                        "--max-memory", "0.001", "-o", path("no_memory"), "--quiet"});
    EXPECT_NE(r.exitCode, 0);
    EXPECT_NE(r.err.find("the fit's first round"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("MB are available"), std::string::npos) << r.err;
    // Why so little: the limit counts what the process already holds.
    EXPECT_NE(r.err.find("--max-memory 0.001 GB less the"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("MB the process already holds"), std::string::npos) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_FALSE(std::filesystem::exists(path("no_memory/fit.json")));
}

// A recording whose forecast (the renderer's pilot) exceeds what --max-memory leaves after the
// fit's state is refused before tracing, naming the paths, the film and the bytes: 1024 paths a
// pixel in the 51016 pixels on the sphere of a 400x400 film (the rest record none) forecast about
// 2.8 GB, under half this machine's memory but over 2 GB.
TEST_F(FitCommand, MaxMemoryRefusesARecordingThatWouldNotFit) {
    // test::runPhongfit, not run(): this film is not kSize wide.
    const std::vector<std::string> film = {"-D", "width=400", "-D", "height=400"};
    std::vector<std::string> args = {"render",  kSphere, "-o", path("sphere400.exr"),
                                     "--quiet", "--spp", "1"};
    args.insert(args.end(), film.begin(), film.end());
    ASSERT_EQ(test::runPhongfit(args).exitCode, 0);
    const std::string view = kSphere + ":" + path("sphere400.exr");
    args = {"fit",          "--view", view, "--material",          "sphere", "--spp", "1024",
            "--max-memory", "2",      "-o", path("big_recording"), "--quiet"};
    args.insert(args.end(), film.begin(), film.end());
    const auto r = test::runPhongfit(args);
    EXPECT_NE(r.exitCode, 0);
    EXPECT_NE(r.err.find("recording 1024 paths per pixel of the 400x400 film (in "),
              std::string::npos)
        << r.err;
    EXPECT_NE(r.err.find("GB left for it"), std::string::npos) << r.err;
    EXPECT_FALSE(std::filesystem::exists(path("big_recording/fit.json")));
}

void writeExrWithNan(const std::string& file) {
    std::vector<float> plane(kSize * kSize, 0.25f);
    plane[7] = std::nanf("");
    Imf::Header header(kSize, kSize);
    Imf::FrameBuffer frame;
    for (const char* c : {"R", "G", "B"}) {
        header.channels().insert(c, Imf::Channel(Imf::FLOAT));
        frame.insert(c, Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(plane.data()), sizeof(float),
                                   sizeof(float) * kSize));
    }
    Imf::OutputFile out(file.c_str(), header);
    out.setFrameBuffer(frame);
    out.writePixels(kSize);
}

// The main job (README, command 1): render the Cornell box, fit its sphere back, print the table.
TEST_F(FitCommand, DemoRendersFitsBackAndPrintsTheErrors) {
    const auto r = run({"demo", "-o", path("demo"), "--spp", "16", "--quiet"});
    ASSERT_EQ(r.exitCode, 0) << r.err;
    EXPECT_TRUE(fs::exists(path("demo/cornell.exr")));
    EXPECT_TRUE(fs::exists(path("demo/fit/fitted.xml")));
    const auto report = nlohmann::json::parse(std::ifstream(path("demo/fit/fit.json")));
    const auto& m = report["materials"]["sphere"];
    for (int c = 0; c < 3; ++c) {
        EXPECT_NEAR(m["kd"][c].get<double>(), 0.5, 0.02 * 0.5);
        EXPECT_NEAR(m["ks"][c].get<double>(), 0.2, 0.05 * 0.2);
    }
    EXPECT_NEAR(m["n"].get<double>(), 30, 0.1 * 30);
    // Path traced: the walls reflect, and the light is sampled.
    EXPECT_EQ(report["area_lights"], "sampled");
    // A 16-spp image holds n to 1.3%, short of the default 1%, whatever the paths: the rounds
    // stop at its noise floor once the paths have grown kMostPathGrowth (16) times, and no further.
    EXPECT_EQ(report["stop_reason"], "noise floor");
    for (const auto& round : report["rounds"])
        EXPECT_LE(round["path_factor"].get<double>(), 16) << round.dump();
    // The last round probes a sharper lobe, at half the first round's paths, and comes back. The
    // estimate it vouches for holds 16 times the first round's paths: its own, or those of the
    // rounds it pools (pooled_rounds.h).
    const auto& rounds = report["rounds"];
    ASSERT_GE(rounds.size(), 2u);
    EXPECT_TRUE(rounds.back()["probe"].get<bool>());
    EXPECT_EQ(rounds.back()["path_factor"].get<double>(), 0.5);
    const std::size_t converged = rounds.size() - 2;
    const int pooled = rounds[converged]["pooled_rounds"].get<int>();
    ASSERT_LE(std::size_t(pooled), converged + 1);
    double paths = 0;
    for (std::size_t k = converged + 1 - std::size_t(pooled); k <= converged; ++k)
        paths += rounds[k]["path_factor"].get<double>();
    EXPECT_EQ(paths, 16);
    for (const char* row : {"kd.r", "ks.b", "n "})
        EXPECT_NE(r.out.find(row), std::string::npos) << r.out;
}

// The pixel filter an image was rendered with is its scene's: `render`'s sidecar says which, and a
// scene that names another is refused (fitted as a box, a Gaussian-filtered sphere's n comes out
// 20 standard errors low, "converged"). Where neither the film nor a sidecar names it, the fit
// takes phongfit's box and warns: Mitsuba's default is a Gaussian (and fits with it too).
TEST_F(FitCommand, TheImagesPixelFilterIsTheScenesOrTheFitWarns) {
    const std::string gaussian = sceneWithFilter("gaussian.xml", R"(<rfilter type="gaussian"/>)");
    const std::string unnamed = sceneWithFilter("unnamed.xml", "");
    ASSERT_EQ(
        run({"render", gaussian, "-o", path("gaussian.exr"), "--spp", "16", "--quiet"}).exitCode,
        0);
    fs::copy_file(path("sphere.exr"), path("bare.exr"));  // no sidecar
    const auto fit = [&](const std::string& view, const std::string& out) {
        return run({"fit", "--view", view, "--material", "sphere", "--rounds", "1", "-o", path(out),
                    "--quiet"});
    };
    const auto filter = [&](const std::string& out) {
        return nlohmann::json::parse(
            std::ifstream(path(out + "/fit.json")))["views"][0]["pixel_filter"];
    };

    auto r = fit(gaussian + ":" + path("gaussian.exr"), "as_rendered");
    ASSERT_EQ(r.exitCode, 0) << r.err;
    EXPECT_EQ(r.out.find("warning"), std::string::npos) << r.out;
    EXPECT_EQ(filter("as_rendered"),
              nlohmann::json(
                  {{"type", "gaussian"}, {"stddev", 0.5}, {"from", path("gaussian.exr.json")}}));

    r = fit(kSphere + ":" + path("gaussian.exr"), "as_box");
    EXPECT_NE(r.exitCode, 0);
    EXPECT_NE(r.err.find("gaussian.exr.json: the image was rendered with a Gaussian pixel filter "
                         "(stddev 0.5 pixels) but " +
                         kSphere + " says a box pixel filter"),
              std::string::npos)
        << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_FALSE(fs::exists(path("as_box")));

    r = fit(unnamed + ":" + path("bare.exr"), "unnamed");
    ASSERT_EQ(r.exitCode, 0) << r.err;
    EXPECT_NE(r.out.find("warning: " + unnamed + ": the film names no <rfilter>"),
              std::string::npos)
        << r.out;
    // The edges, which tell a Gaussian from a box on this sphere, did not show one: the fit also
    // runs with Mitsuba's Gaussian (untoldFilters), whose estimate renders farther from the image.
    const nlohmann::json unnamedFilter = filter("unnamed");
    EXPECT_EQ(unnamedFilter["type"], "box");
    EXPECT_EQ(unnamedFilter["from"], "default");
    ASSERT_EQ(unnamedFilter["also_fitted"]["type"], "gaussian") << unnamedFilter;
    EXPECT_LT(unnamedFilter["residual_rms"].get<double>(),
              unnamedFilter["also_fitted"]["residual_rms"].get<double>());
    EXPECT_NE(r.out.find("kept the fit with the box for " + path("bare.exr")), std::string::npos)
        << r.out;

    r = fit(kSphere + ":" + path("bare.exr"), "named");
    ASSERT_EQ(r.exitCode, 0) << r.err;
    EXPECT_EQ(r.out.find("warning"), std::string::npos) << r.out;
    EXPECT_EQ(filter("named"), nlohmann::json({{"type", "box"}, {"from", "scene"}}));
}

// Without a sidecar, an image's edges show the filter a scene misstates: the fit names it and
// does not call its estimate converged (edge_agreement.h); the scene that states it agrees, and
// one that names none takes it.
TEST_F(FitCommand, AnImageWhoseEdgesShowAnotherPixelFilterIsNotConverged) {
    const std::string gaussian =
        sceneWithFilter("gaussian_edges.xml", R"(<rfilter type="gaussian"/>)");
    const std::string image = path("gaussian_edges.exr");
    ASSERT_EQ(run({"render", gaussian, "-o", image, "--spp", "16", "--quiet"}).exitCode, 0);
    fs::remove(image + ".json");
    const auto fit = [&](const std::string& scene, const std::string& out) {
        return fitWithEdges(scene, image, out);
    };

    const auto [out, report] = fit(kSphere, "edges_box");
    EXPECT_NE(out.find("warning: " + image + " disagrees with " + kSphere +
                       " where its edges cross pixels: rendered anew at this estimate with a "
                       "gaussian stddev 0.5 pixel filter"),
              std::string::npos)
        << out;
    EXPECT_NE(out.find("(not converged: the estimate settled, but the images disagree"),
              std::string::npos)
        << out;
    EXPECT_FALSE(report["converged"].get<bool>());
    EXPECT_EQ(report["stop_reason"], "images disagree");
    const nlohmann::json& edges = report["views"][0]["edges"];
    EXPECT_EQ(edges["agree"], false);
    EXPECT_EQ(edges["better_pixel_filter"], "gaussian stddev 0.5");
    EXPECT_LT(edges["better_misfit"].get<double>(), 0.1 * edges["misfit"].get<double>());

    const auto [outStated, stated] = fit(gaussian, "edges_gaussian");
    EXPECT_EQ(outStated.find("disagrees"), std::string::npos) << outStated;
    EXPECT_EQ(stated["views"][0]["edges"]["agree"], true);
    EXPECT_EQ(stated["views"][0]["edges"]["better_pixel_filter"], "");
    EXPECT_NE(stated["stop_reason"], "images disagree");

    // A film that names no filter takes the one the edges show, and the fit runs again with it:
    // the estimate is the stated Gaussian's.
    const auto [outUnnamed, unnamed] =
        fit(sceneWithFilter("unnamed_edges.xml", ""), "edges_unnamed");
    EXPECT_NE(
        outUnnamed.find(image + ": its edges, rendered anew at the estimate, fit a gaussian stddev "
                                "0.5 pixel filter far better than phongfit's box"),
        std::string::npos)
        << outUnnamed;
    EXPECT_EQ(outUnnamed.find("disagrees"), std::string::npos) << outUnnamed;
    EXPECT_EQ(unnamed["views"][0]["pixel_filter"],
              nlohmann::json({{"type", "gaussian"}, {"stddev", 0.5}, {"from", "edges"}}));
    EXPECT_EQ(unnamed["views"][0]["edges"]["agree"], true);
    EXPECT_EQ(unnamed["materials"], stated["materials"]);
    EXPECT_GT(unnamed["time_s"].get<double>(), stated["time_s"].get<double>());
}

// An image filtered at a width no renderer defaults to, read through a film that names no filter:
// on this 40x40 film the edges fit a Gaussian of its spread (as standard deviation, a tent's radius
// over sqrt(6)) as well as the tent and name both; the fit runs again with each, keeps the tent,
// whose estimate renders closer to the image (a fit with the Gaussian alone gave n 30.43 +- 0.13
// for 30, "converged"): its estimate is that of a film that states it, with standard errors that
// hold the Gaussian's (kd 0.5012 against 0.5000 +- 0.0004), not converged.
TEST_F(FitCommand, AFilmThatNamesNoFilterTakesTheFilterTheImageShows) {
    const std::string wide = sceneWithFilter(
        "wide_tent.xml", R"(<rfilter type="tent"><float name="radius" value="1.8"/></rfilter>)");
    const std::string image = path("wide_tent.exr");
    ASSERT_EQ(run({"render", wide, "-o", image, "--spp", "256", "--quiet"}).exitCode, 0);
    fs::remove(image + ".json");
    const auto fit = [&](const std::string& scene, const std::string& out) {
        return fitWithEdges(scene, image, out);
    };
    const auto [out, report] = fit(sceneWithFilter("unnamed_wide.xml", ""), "wide_unnamed");
    const nlohmann::json& filter = report["views"][0]["pixel_filter"];
    EXPECT_EQ(filter["from"], "edges") << out;
    ASSERT_EQ(filter["type"], "tent") << out;
    const double radius = filter["radius"].get<double>();
    EXPECT_NEAR(radius, 1.8, 0.1) << out;
    const nlohmann::json& other = filter["also_fitted"];
    ASSERT_EQ(other["type"], "gaussian") << out;
    EXPECT_NEAR(other["stddev"].get<double>(), 1.8 / std::sqrt(6.0), 0.06) << out;
    EXPECT_LT(filter["residual_rms"].get<double>(), 0.6 * other["residual_rms"].get<double>());
    const std::string gaussian = fmt::format("gaussian stddev {:g}", other["stddev"].get<double>());
    const std::string tent = fmt::format("tent radius {:g}", radius);
    for (const std::string& line :
         {image + ": its edges, rendered anew at the estimate, fit a " + gaussian +
              " pixel filter far better than phongfit's box",
          image + ": its edges fit a " + tent + " pixel filter as well as the " + gaussian,
          "kept the fit with the " + tent + " for " + image + ": its estimate, rendered anew"})
        EXPECT_NE(out.find(line), std::string::npos) << line << "\n" << out;
    EXPECT_EQ(report["views"][0]["edges"]["agree"], true);
    const nlohmann::json& sphere = report["materials"]["sphere"];
    EXPECT_LT(std::abs(sphere["n"].get<double>() - 30), 3 * sphere["n_std"].get<double>()) << out;
    const auto [outFound, found] =
        fit(sceneWithFilter(
                "found_wide.xml",
                fmt::format(R"(<rfilter type="tent"><float name="radius" value="{:g}"/></rfilter>)",
                            radius)),
            "wide_found");
    // The same estimate; its standard errors raised to hold the Gaussian's (holdBothFilters).
    const nlohmann::json& stated = found["materials"]["sphere"];
    for (const char* p : {"kd", "ks", "n"}) EXPECT_EQ(sphere[p], stated[p]) << p;
    EXPECT_GE(sphere["n_std"].get<double>(), stated["n_std"].get<double>());
    EXPECT_GT(sphere["kd_std"][0].get<double>(), stated["kd_std"][0].get<double>());
    EXPECT_EQ(report["stop_reason"], "pixel filter unresolved") << out;
    EXPECT_NE(out.find("(not converged: the film names no pixel filter, and the fits with the two "
                       "its image's edges fit alike (above) differ by more than their standard "
                       "errors"),
              std::string::npos)
        << out;
}

TEST_F(FitCommand, BadInputIsRefusedWithOneLineAndNothingWritten) {
    cv::imwrite(path("mask_small.png"), cv::Mat(kSize / 2, kSize, CV_8U, cv::Scalar(255)));
    cv::imwrite(path("mask_zero.png"), cv::Mat(kSize, kSize, CV_8U, cv::Scalar(0)));
    writeExrWithNan(path("nan.exr"));
    Image wrongSize(kSize + 1, kSize);
    writeExr(wrongSize, path("wrong_size.exr"));
    std::ofstream(path("garbage.exr")) << "not an image";
    writeExr(Image(kSize, kSize), path("black.exr"));
    Image glaring = readImage(path("sphere.exr"));
    for (float& v : glaring.rgb) v *= 1e6f;
    writeExr(glaring, path("glaring.exr"));
    const std::string view = kSphere + ":" + path("sphere.exr");
    const std::string cornell = kScenes + "/cornell_phong.xml";
    // Render settings beside an image that are not phongfit render's.
    const auto sidecar = [&](const std::string& name, const std::string& text) {
        fs::copy_file(path("sphere.exr"), path(name + ".exr"),
                      fs::copy_options::overwrite_existing);
        std::ofstream(path(name + ".exr.json")) << text;
        return kSphere + ":" + path(name + ".exr");
    };

    struct Case {
        std::vector<std::string> args;
        std::string fragment;
    };
    const std::vector<Case> cases = {
        {{"--view", kSphere + ":" + path("wrong_size.exr"), "--material", "sphere"},
         "image is 41x40"},
        {{"--view", view, "--material", "sphere", "--mask", path("mask_small.png")},
         "mask_small.png"},
        {{"--view", view, "--material", "ball"}, "no bsdf with id 'ball'"},
        {{"--view", cornell + ":" + path("sphere.exr"), "--material", "white"}, "not 'phong'"},
        {{"--view", view, "--material", "sphere", "--mask", path("mask_zero.png")},
         "every pixel is masked"},
        {{"--view", kSphere + ":" + path("nan.exr"), "--material", "sphere"}, "is not finite"},
        {{"--view", kSphere + ":" + path("missing.exr"), "--material", "sphere"}, "missing.exr"},
        {{"--view", kSphere + ":" + path("garbage.exr"), "--material", "sphere"}, "garbage.exr"},
        {{"--view", path("nope.xml") + ":" + path("sphere.exr"), "--material", "sphere"},
         "nope.xml"},
        {{"--view", "no-colon-here", "--material", "sphere"}, "expected SCENE.xml:IMAGE"},
        {{"--view", view, "--material", "sphere", "--kd", "0.9", "--ks", "0.5"}, "exceeds 1"},
        {{"--view", view, "--material", "sphere", "--kd", "1,2"}, "--kd '1,2'"},
        {{"--view", view, "--material", "sphere", "--loss", "l1"}, "--loss"},
        {{"--view", kSphere + ":" + path("black.exr"), "--material", "sphere", "--fit-exposure"},
         "images are black"},
        {{"--view", kSphere + ":" + path("glaring.exr"), "--material", "sphere", "--fit-exposure"},
         "times as bright as the scene renders them"},
        {{"--capture", path("capture"), "--fit-exposure"},
         "--fit-exposure does not apply to --capture"},
        {{"--view", sidecar("sidecar_text", "spp = 64"), "--material", "sphere"},
         "sidecar_text.exr.json: not a JSON object"},
        {{"--view", sidecar("sidecar_spp", "{\"spp\": -3}"), "--material", "sphere"},
         "spp -3 is not a whole number"},
        {{"--view", sidecar("sidecar_sampler", "{\"spp\": 16, \"pixel_sampler\": \"halton\"}"),
          "--material", "sphere"},
         "pixel_sampler \"halton\" (allowed: independent, sobol, ldsampler)"},
        {{"--view", sidecar("sidecar_strategy", "{\"spp\": 16, \"sampler\": \"importance\"}"),
          "--material", "sphere"},
         "sampler \"importance\" (allowed: "},
        {{"--view",
          sidecar("sidecar_filter",
                  R"({"spp": 64, "pixel_filter": {"type": "gaussian", "stddev": 0.5}})"),
          "--material", "sphere"},
         "rendered with a Gaussian pixel filter (stddev 0.5 pixels) but"},
        {{"--view",
          sidecar("sidecar_tent", R"({"spp": 64, "pixel_filter": {"type": "tent", "radius": 1}})"),
          "--material", "sphere"},
         "rendered with a tent pixel filter (radius 1 pixels) but"},
        {{"--view", sidecar("sidecar_filter_kind", R"({"spp": 64, "pixel_filter": {"type": 1}})"),
          "--material", "sphere"},
         "pixel_filter {\"type\":1} (allowed: "},
        {{"--view", sidecar("sidecar_depth", R"({"spp": 64, "max_depth": 1})"), "--material",
          "sphere"},
         "rendered with depth 1 but"},
        {{"--view",
          sidecar("sidecar_depth_huge", R"({"spp": 64, "max_depth": 18446744073709551615})"),
          "--material", "sphere"},
         "max_depth 18446744073709551615 is not a whole number in [-1, "},
        {{"--view", view, "--material", "sphere", "--image-spp", "-2"}, "--image-spp"},
    };
    for (const Case& c : cases) {
        std::vector<std::string> args = {"fit"};
        args.insert(args.end(), c.args.begin(), c.args.end());
        args.insert(args.end(), {"-o", path("refused"), "--quiet"});
        const auto r = run(args);
        EXPECT_NE(r.exitCode, 0) << c.fragment;
        EXPECT_NE(r.err.find(c.fragment), std::string::npos)
            << "expected '" << c.fragment << "' in: " << r.err;
        EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
        EXPECT_FALSE(fs::exists(path("refused"))) << c.fragment;
    }
}

}  // namespace
}  // namespace phongfit
