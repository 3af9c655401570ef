// Round trips through the executable: render an image with known parameters, fit it back from a
// start far from the truth (n off by 100x), compare: kd and ks within 2%, n within 5% (issue 4),
// on the single sphere for n = 1, 30, 1000, 10000 and on the path-traced Cornell box, plus the
// extreme cases.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <optional>
#include <random>
#include <tuple>
#include <utility>

#include "image.h"
#include "precision_claim.h"
#include "subprocess.h"
#include "temp_dir.h"

namespace phongfit {
namespace {

namespace fs = std::filesystem;

const std::string kLit = PHONGFIT_TEST_SCENES_DIR "/sphere_lit.xml";
const std::string kCornell = PHONGFIT_SCENES_DIR "/cornell_phong.xml";
const std::string kPoint = PHONGFIT_SCENES_DIR "/sphere_point.xml";
const std::string kOrbit = PHONGFIT_SCENES_DIR "/sphere_orbit.xml";
const std::string kQuad = PHONGFIT_SCENES_DIR "/sphere_quad.xml";
const std::string kEnvmap = PHONGFIT_SCENES_DIR "/sphere_envmap.xml";
const std::string kSharpArea = PHONGFIT_SCENES_DIR "/sphere_sharp_area.xml";

class RoundTrip : public ::testing::Test {
protected:
    std::string path(const std::string& name) const { return (dir_ / name).string(); }

    static std::vector<std::string> defines(const std::map<std::string, std::string>& d) {
        std::vector<std::string> args;
        for (const auto& [k, v] : d) args.insert(args.end(), {"-D", k + "=" + v});
        return args;
    }

    // Renders `scene` with `truth` defines into NAME.exr, with $PHONGFIT_TEST_RENDER_EXE if set:
    // the sanitized run (scripts/sanitize.sh) renders the images to fit with the plain build,
    // whose images are the same to the bit, and fits them with the sanitized one.
    std::string render(const std::string& scene, const std::map<std::string, std::string>& truth,
                       const std::string& name, int spp, const std::string& seed = "11") {
        std::vector<std::string> args = {
            PHONGFIT_EXE,        "render", scene, "-o",     path(name + ".exr"), "--spp",
            std::to_string(spp), "--seed", seed,  "--quiet"};
        if (const char* renderer = std::getenv("PHONGFIT_TEST_RENDER_EXE"); renderer && *renderer)
            args[0] = renderer;
        const auto d = defines(truth);
        args.insert(args.end(), d.begin(), d.end());
        const auto r = test::runProcess(args);
        EXPECT_EQ(r.exitCode, 0) << r.err;
        return path(name + ".exr");
    }

    // `scene` with its film's box filter replaced by `filter` (empty: no <rfilter>), as NAME.
    std::string withFilter(const std::string& scene, const std::string& name,
                           const std::string& filter) const {
        std::ifstream in(scene);
        std::string xml((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
        const std::string box = R"(<rfilter type="box"/>)";
        EXPECT_NE(xml.find(box), std::string::npos) << scene;
        xml.replace(xml.find(box), box.size(), filter);
        std::ofstream(path(name)) << xml;
        return path(name);
    }

    // Fits `views` (scene:image) with extra arguments; returns fit.json.
    nlohmann::json fit(const std::vector<std::string>& views, std::vector<std::string> extra,
                       const std::string& name, int seed = 3) {
        std::vector<std::string> args = {"fit",      "--material", "sphere", "-o",
                                         path(name), "--quiet",    "--seed", std::to_string(seed)};
        for (const std::string& v : views) args.insert(args.end(), {"--view", v});
        args.insert(args.end(), extra.begin(), extra.end());
        const auto r = test::runPhongfit(args);
        EXPECT_EQ(r.exitCode, 0) << r.err;
        const auto report = nlohmann::json::parse(std::ifstream(path(name) + "/fit.json"));
        const auto precision = std::find(extra.begin(), extra.end(), "--precision");
        test::expectPrecisionClaimHolds(report,
                                        precision != extra.end() && precision + 1 != extra.end()
                                            ? std::stod(*(precision + 1))
                                            : 0.01);
        return report;
    }

    // fit.json of `view` (scene:image) fitted as scripts/random_round_trips.py fits: from kd and ks
    // 0.3 and n 100 times broader than `truth`'s, with `truth`'s defines, at recording seed 0.
    nlohmann::json fitFromFar(const std::string& view,
                              const std::map<std::string, std::string>& truth) {
        const std::string start = fmt::format("{:.6g}", std::stod(truth.at("n")) / 100);
        std::vector<std::string> extra = {"--kd", "0.3", "--ks", "0.3", "--n", start};
        const auto d = defines(truth);
        extra.insert(extra.end(), d.begin(), d.end());
        return fit({view}, extra, "fit", 0);
    }

    // The recovery matrix's sphere under the 40-degree light (its radius 2.418 at the scene's
    // distance) at 128 x 128 with n 30000 (or `n`): the view of its image rendered at `spp` and the
    // fit's arguments from kd, ks 0.3 and n 100 times broader.
    struct LargeLightCase {
        std::string view;
        std::vector<std::string> extra;
    };
    LargeLightCase largeLightSphere(const std::string& kd, const std::string& ks,
                                    const std::string& name, int spp,
                                    const std::string& n = "30000") {
        const std::map<std::string, std::string> scene = {{"width", "128"},
                                                          {"height", "128"},
                                                          {"light_radius", "2.418"},
                                                          {"radiance", "8.17"},
                                                          {"sky", "0"}};
        std::map<std::string, std::string> truth = scene;
        truth.insert({{"kd", kd}, {"ks", ks}, {"n", n}});
        LargeLightCase c{kSharpArea + ":" + render(kSharpArea, truth, name, spp),
                         {"--kd", "0.3", "--ks", "0.3", "--n", std::to_string(std::stod(n) / 100)}};
        const std::vector<std::string> d = defines(scene);
        c.extra.insert(c.extra.end(), d.begin(), d.end());
        return c;
    }

    const test::TempDir temp_{"roundtrip"};
    const fs::path& dir_ = temp_.path();
};

void expectRecovered(const nlohmann::json& m, double kd, double ks, double n,
                     const std::string& what) {
    for (int c = 0; c < 3; ++c) {
        EXPECT_NEAR(m["kd"][c].get<double>(), kd, 0.02 * kd + 1e-4) << what << " kd channel " << c;
        EXPECT_NEAR(m["ks"][c].get<double>(), ks, 0.02 * ks + 1e-4) << what << " ks channel " << c;
    }
    EXPECT_NEAR(m["n"].get<double>(), n, 0.05 * n) << what;
}

// Every kd and ks channel and n (unless it is nullopt: unconstrained) within 3 of their reported
// standard errors of the truth.
void expectCovered(const nlohmann::json& m, const std::array<double, 3>& kd,
                   const std::array<double, 3>& ks, std::optional<double> n,
                   const std::string& what) {
    for (int c = 0; c < 3; ++c) {
        EXPECT_LT(std::abs(m["kd"][c].get<double>() - kd[c]), 3 * m["kd_std"][c].get<double>())
            << what << " kd channel " << c;
        EXPECT_LT(std::abs(m["ks"][c].get<double>() - ks[c]), 3 * m["ks_std"][c].get<double>())
            << what << " ks channel " << c;
    }
    if (n) {
        EXPECT_LT(std::abs(m["n"].get<double>() - *n), 3 * m["n_std"].get<double>())
            << what << ": n " << m["n"].get<double>() << " +- " << m["n_std"].get<double>();
    }
}

struct SphereCase {
    double kd, ks, n, startN;
    const char* fov;  // narrow enough for the highlight to cover pixels
    const char* spp;  // recorded per pixel: a highlight smaller than a pixel needs more
};

class SphereRoundTrip : public RoundTrip, public ::testing::WithParamInterface<SphereCase> {};

TEST_P(SphereRoundTrip, RecoversKdKsAndN) {
    const SphereCase& c = GetParam();
    const std::map<std::string, std::string> truth = {{"kd", std::to_string(c.kd)},
                                                      {"ks", std::to_string(c.ks)},
                                                      {"n", std::to_string(c.n)},
                                                      {"fov", c.fov},
                                                      {"light_x", "1"},
                                                      {"light_y", "1.5"}};
    const std::string image = render(kLit, truth, "truth", 256);
    // The scene's own values are the truth: start elsewhere, with n off by 100x.
    std::vector<std::string> extra = {
        "--kd", "0.2", "--ks", "0.1", "--n", std::to_string(c.startN), "--spp", c.spp};
    const auto d = defines(truth);
    extra.insert(extra.end(), d.begin(), d.end());
    const auto report = fit({kLit + ":" + image}, extra, "fit");
    expectRecovered(report["materials"]["sphere"], c.kd, c.ks, c.n, "n = " + std::to_string(c.n));
    EXPECT_TRUE(report["materials"]["sphere"]["unconstrained"].empty());
}

INSTANTIATE_TEST_SUITE_P(ExponentGrid, SphereRoundTrip,
                         ::testing::Values(SphereCase{0.5, 0.4, 1, 100, "24", "4"},
                                           SphereCase{0.5, 0.3, 30, 3000, "24", "4"},
                                           SphereCase{0.5, 0.3, 30, 0.3, "24", "4"},
                                           SphereCase{0.3, 0.6, 1000, 10, "6", "4"},
                                           SphereCase{0.3, 0.6, 10000, 100, "2", "16"}),
                         [](const ::testing::TestParamInfo<SphereCase>& info) {
                             const auto name = [](double v) {
                                 std::string s = fmt::format("{:g}", v);
                                 std::replace(s.begin(), s.end(), '.', 'p');
                                 return s;
                             };
                             return fmt::format("n{}_from{}", name(info.param.n),
                                                name(info.param.startN));
                         });

// Path tracing at depth 5 (interreflections between the sphere and the walls, an area light):
// the recorded paths are noisy, so this is where the estimator must be unbiased. 128 x 128 and 64
// paths per pixel and round: the standard errors are then about 0.4% (kd), 1.2% (ks), 3% (n).
// The image's noise, added to them once the rounds met the precision, takes them past it: the
// noise floor (converged), not rounds that disagree.
TEST_F(RoundTrip, CornellBoxFromAStartWithNOffBy100x) {
    const std::map<std::string, std::string> size = {{"width", "128"}, {"height", "128"}};
    const std::string image = render(kCornell, size, "cornell", 512);
    std::vector<std::string> extra = {"--kd", "0.3", "--ks", "0.4", "--n", "3000", "--spp", "64"};
    const auto d = defines(size);
    extra.insert(extra.end(), d.begin(), d.end());
    const auto report = fit({kCornell + ":" + image}, extra, "fit");
    expectRecovered(report["materials"]["sphere"], 0.5, 0.2, 30, "Cornell box");
    EXPECT_TRUE(report["materials"]["sphere"]["unconstrained"].empty());
    EXPECT_TRUE(report["converged"].get<bool>());
}

// At 64 x 64 the sphere covers a few hundred pixels: the smoothed instruments of the moment
// equations blur its highlight and their solutions wandered (n from 30 to 142 within a round,
// reported as 142 +- 30). The round then keeps the cross-product least squares, whose errors are
// larger than at 128 x 128 but honest: the truth is within 3 standard errors.
TEST_F(RoundTrip, SmallCornellBoxStaysWithinItsStandardErrors) {
    const std::map<std::string, std::string> size = {{"width", "64"}, {"height", "64"}};
    const std::string image = render(kCornell, size, "cornell", 1024);
    std::vector<std::string> extra = {"--kd", "0.25", "--ks", "0.45", "--n", "3000", "--spp", "64"};
    const auto d = defines(size);
    extra.insert(extra.end(), d.begin(), d.end());
    const auto m = fit({kCornell + ":" + image}, extra, "fit")["materials"]["sphere"];
    expectCovered(m, {0.5, 0.5, 0.5}, {0.2, 0.2, 0.2}, 30, "small cornell");
    for (int c = 0; c < 3; ++c) {
        EXPECT_LT(m["kd_std"][c].get<double>(), 0.05);
        EXPECT_LT(m["ks_std"][c].get<double>(), 0.03);
    }
    EXPECT_LT(m["n_std"].get<double>(), 10);
}

// The Cornell box under a point light at 64 x 64, tent-filtered (kd 0.843, ks 0.0773, n 139, from
// n 1.39): round 0 showed the lobe (ks 0.10 +- 0.016, n 51 +- 13); round 1, recorded there at 4
// paths a pixel, sent n to 1e6, where ks and n were held, ks at its start 0.3, and kd made up for
// it to the end: 0.66 +- 0.02, ten standard errors off, ks and n "unconstrained". Recorded again
// where the lobe was seen (lost_lobe.h): kd 0.841 +- 0.007, ks 0.078 +- 0.003, n 133 +- 21.
TEST_F(RoundTrip, ALobeLostToTheBoundIsRecordedAgainWhereItWasSeen) {
    const std::string scene = withFilter(PHONGFIT_SCENES_DIR "/cornell_point.xml",
                                         "cornell_point_tent.xml", R"(<rfilter type="tent"/>)");
    const std::map<std::string, std::string> truth = {
        {"width", "64"}, {"height", "64"}, {"kd", "0.843"},  {"ks", "0.0773"},
        {"n", "139.2"},  {"spp", "256"},   {"maxDepth", "5"}};
    const std::string image = render(scene, truth, "lost", 256, "0");
    const auto m = fitFromFar(scene + ":" + image, truth)["materials"]["sphere"];
    EXPECT_TRUE(m["unconstrained"].empty()) << m["unconstrained"];
    expectCovered(m, {0.843, 0.843, 0.843}, {0.0773, 0.0773, 0.0773}, 139.2, "lost lobe");
}

// The Cornell box under a point light at 128 x 128, Gaussian-filtered, n 15977 (kd 0.428, ks
// 0.396), its image of 256 paths a pixel: a highlight a tenth of a pixel wide, whose four pixels
// vary by 50% and more between such images (at n 1132, by 3%). The fit ends at n 1132, whose
// image-noise standard error (s 0.61 in log n) reached 7000, the truth 4.5 of them away. Taken
// where the lobe is 3 of those sharper too, the noise there reaches the truth.
TEST_F(RoundTrip, ASubPixelHighlightsNoiseWhereTheLobeIsSharperReachesIt) {
    const std::string scene =
        withFilter(PHONGFIT_SCENES_DIR "/cornell_point.xml", "cornell_point_gaussian.xml",
                   R"(<rfilter type="gaussian"/>)");
    const std::map<std::string, std::string> truth = {
        {"width", "128"}, {"height", "128"}, {"kd", "0.427669"}, {"ks", "0.39574"},
        {"n", "15977.2"}, {"spp", "256"},    {"maxDepth", "5"}};
    const std::string image = render(scene, truth, "sharper", 256, "0");
    const auto m = fitFromFar(scene + ":" + image, truth)["materials"]["sphere"];
    EXPECT_GT(m["image_noise_std"]["log_n_sharper"].get<double>(), m["log_n_std"].get<double>());
    expectCovered(m, {0.427669, 0.427669, 0.427669}, {0.39574, 0.39574, 0.39574}, 15977.2,
                  "sharper lobe's noise");
}

// The Cornell box under its area light at 96 x 96 (kd 0.746, 0.601, 0.392, ks 0.245, n 4475; 256
// paths a pixel), from n 44.75: the rounds converged at n 380 +- 182 after a round of 16 times the
// first's paths, the probe from 1600 at half the first's paths came back to 158 +- 66, and the fit
// ended n 380 +- 410, the truth 10 standard errors off. That probe's return was its few paths' pull
// towards the broad lobes they reach (pulledBroader), and it was probed again with the converged
// round's paths. Since the anchors' standard errors take the recordings' part (sessions 85-86) no
// round claims n resolved this early: at 16 times the first's paths the round says n 2833 +- 5958,
// most of it the image's noise, and the fit ends "unresolved" (in 25 recording seeds, and 3 each on
// 8 more images, no probe was pulled; pulledBroader's own test keeps the case).
TEST_F(RoundTrip, AnAreaLitLobeTheRoundsDoNotResolveIsSaidToBeUnresolved) {
    const std::map<std::string, std::string> truth = {
        {"width", "96"},    {"height", "96"}, {"kd", "0.746232,0.601046,0.392068"},
        {"ks", "0.245421"}, {"n", "4475.37"}, {"spp", "256"},
        {"maxDepth", "5"}};
    const std::string cornell = PHONGFIT_SCENES_DIR "/cornell_area.xml";
    const std::string image = render(cornell, truth, "pulled", 256, "0");
    const auto report = fitFromFar(cornell + ":" + image, truth);
    EXPECT_EQ(report["stop_reason"], "unresolved");
    EXPECT_FALSE(report["converged"].get<bool>());
    const nlohmann::json& m = report["materials"]["sphere"];
    EXPECT_GE(m["n_std"].get<double>(), m["n"].get<double>());
    expectCovered(m, {0.746232, 0.601046, 0.392068}, {0.245421, 0.245421, 0.245421}, 4475.37,
                  "area-lit lobe");
}

// The Cornell box under its 5-degree area light at 128 x 128, tent-filtered (kd 0.236, 0.601,
// 0.022, ks 0.217, n 11771; 256 paths a pixel): the light's reflection is half a pixel across, and
// the sampled recordings pull n broader. The rounds held n at 1672 +- 243, 2079 +- 500 and,
// recorded at 8317, 1891; the fit ended n 1891 +- 1723, the truth 5.7 standard errors off, though
// the image itself fits the truth's renders better than the estimate's. The pixels that hold n,
// rendered as the image was where the lobe is sharper, say how far the image allows it.
TEST_F(RoundTrip, ASharperLobeTheImageDoesNotRuleOutIsWithinTheStandardErrors) {
    const std::string scene = withFilter(PHONGFIT_SCENES_DIR "/cornell_area.xml",
                                         "cornell_area_tent.xml", R"(<rfilter type="tent"/>)");
    const std::map<std::string, std::string> truth = {
        {"width", "128"},   {"height", "128"}, {"kd", "0.236372,0.601142,0.0224418"},
        {"ks", "0.216867"}, {"n", "11771.1"},  {"spp", "256"},
        {"maxDepth", "5"}};
    const std::string image = render(scene, truth, "allowed", 256, "0");
    const auto m = fitFromFar(scene + ":" + image, truth)["materials"]["sphere"];
    EXPECT_GT(m["image_noise_std"]["log_n_sharper"].get<double>(), m["log_n_std"].get<double>());
    expectCovered(m, {0.236372, 0.601142, 0.0224418}, {0.216867, 0.216867, 0.216867}, 11771.1,
                  "sharper lobe the image allows");
}

// The Cornell box under its area light at 96 x 96, rendered with a tent (kd 0.334, ks 0.666, n 2.7:
// kd + ks = 1), its sidecar gone and read through a film that names no filter: the silhouette
// against the walls does not tell the tent from phongfit's box, while the fit as a box is swayed
// by it, kd 0.354 +- 0.0045 and ks 0.640 +- 0.0046, four standard errors off. Fitted with Mitsuba's
// Gaussian too (untoldFilters), the standard errors hold both fits, and the truth.
TEST_F(RoundTrip, AFilterTheEdgesCannotTellIsFittedBothWays) {
    const std::string cornell = PHONGFIT_SCENES_DIR "/cornell_area.xml";
    const std::string tent =
        withFilter(cornell, "cornell_area_tent.xml", R"(<rfilter type="tent"/>)");
    const std::string unnamed = withFilter(cornell, "cornell_area_none.xml", "");
    const std::map<std::string, std::string> truth = {
        {"width", "96"},  {"height", "96"}, {"kd", "0.334487"}, {"ks", "0.665513"},
        {"n", "2.69818"}, {"spp", "256"},   {"maxDepth", "5"}};
    const std::string image = render(tent, truth, "untold", 256, "0");
    fs::remove(image + ".json");
    const auto report = fitFromFar(unnamed + ":" + image, truth);
    const nlohmann::json& filter = report["views"][0]["pixel_filter"];
    EXPECT_EQ(filter["also_fitted"]["type"], "gaussian") << filter;
    expectCovered(report["materials"]["sphere"], {0.334487, 0.334487, 0.334487},
                  {0.665513, 0.665513, 0.665513}, 2.69818, "untold filter");
}

// A lobeless point-lit sphere at 96 x 96, tent-filtered, coloured (kd 0.175, 0.844, 0.362, ks 0),
// from ks 0.3 and n 0.25: n went broader to 0.028, where the lobe is a second diffuse term, and ks
// and n were held as collinear with kd, ks at its start: kd 0, 0.587, 0.106 +- 0.007, "images
// disagree". A ks held with its n is held at 0 (holding.cpp): the images show no lobe.
TEST_F(RoundTrip, AShapelessLobeHeldWithItsExponentLeavesKdWhole) {
    const std::string scene =
        withFilter(kPoint, "sphere_point_tent.xml", R"(<rfilter type="tent"/>)");
    const std::map<std::string, std::string> truth = {
        {"width", "96"}, {"height", "96"}, {"kd", "0.175186,0.843822,0.362406"},
        {"ks", "0"},     {"n", "25.2376"}, {"spp", "1024"}};
    const std::string image = render(scene, truth, "shapeless", 1024, "0");
    const auto m = fitFromFar(scene + ":" + image, truth)["materials"]["sphere"];
    const std::array<double, 3> kd = {0.175186, 0.843822, 0.362406};
    for (int c = 0; c < 3; ++c) {
        EXPECT_LT(std::abs(m["kd"][c].get<double>() - kd[c]), 3 * m["kd_std"][c].get<double>())
            << m;
        EXPECT_LT(m["ks"][c].get<double>(), 1e-3) << m;
    }
}

// n = 50000 under a point light at 128 x 128, grey: the highlight is smaller than a pixel, and ks
// and log n correlate to 0.98. The lobe test must not count that trade-off against the lobe (with n
// free, ks was under 2 standard errors and n was held at the start, 100, biasing ks), and round
// 0, recorded at that far start, must not pass for converged on its large standard errors. Two
// recording seeds: with seed 1 the per-pixel standard errors alone put ks 57 of them off
// (0.2539 +- 0.00007); the rounds' scatter (round_scatter.h) says 0.0015.
class SubPixelHighlight : public RoundTrip, public ::testing::WithParamInterface<int> {};

TEST_P(SubPixelHighlight, KeepsItsExponentFree) {
    const std::map<std::string, std::string> truth = {
        {"kd", "0.6"}, {"ks", "0.25"}, {"n", "50000"}};
    const std::string image = render(kPoint, truth, "sharp", 256);
    const auto report = fit({kPoint + ":" + image},
                            {"--grey", "--kd", "0.25", "--ks", "0.25", "--n", "100", "--spp", "16"},
                            "fit", GetParam());
    const auto& m = report["materials"]["sphere"];
    EXPECT_TRUE(m["unconstrained"].empty()) << m["unconstrained"].dump();
    EXPECT_GE(report["rounds"].size(), 2u);
    // A point light seen directly: the recordings replay any lobe alike, no sharper probe. The
    // moment equations have no root in reach here: each solve stops after kMomentIterations and
    // the next pass goes on with the instruments moved (before that cap, rounds crawled for up to
    // 860 Ceres iterations to the same estimate; then at most 260). The later rounds' passes end
    // far less precise than the anchor and give up after two (kHopelessPrecision): at most 151
    // iterations, the same estimates (212-260 before). Moment solves already hopeless at the
    // anchor, and agreeing with it, are not started (kMomentDisagreement): the rounds after the
    // first took 254 and 166 iterations in all for the two seeds, 395 and 368 before. A pass with
    // no finite standard errors counts as hopeless: 212 and 202 (seed 1 had crawled through five
    // such passes in one round).
    int later = 0;
    for (const auto& r : report["rounds"]) {
        EXPECT_FALSE(r["probe"].get<bool>()) << r.dump();
        EXPECT_LE(r["iterations"].get<int>(), r["round"].get<int>() == 0 ? 250 : 160) << r.dump();
        if (r["round"].get<int>() > 0) later += r["iterations"].get<int>();
    }
    EXPECT_LE(later, 300);
    for (int c = 0; c < 3; ++c) {
        EXPECT_NEAR(m["kd"][c].get<double>(), 0.6, 0.02 * 0.6);
        const double ks = m["ks"][c].get<double>(), ksStd = m["ks_std"][c].get<double>();
        EXPECT_LT(std::abs(ks - 0.25), 3 * ksStd) << ks << " +- " << ksStd;
        EXPECT_LT(ksStd, 0.1);
    }
    // n is within 3x of the truth, or else within 3 standard errors and the fit not converged: the
    // images do not hold it (at the default --precision the extra paths find n 3.3e5 +- 2.1e5).
    const double n = m["n"].get<double>(), nStd = m["n_std"].get<double>();
    if (n < 50000 / 3.0 || n > 50000 * 3.0) {
        EXPECT_LT(std::abs(n - 50000), 3 * nStd);
        EXPECT_FALSE(report["converged"].get<bool>());
    }
}

INSTANTIATE_TEST_SUITE_P(RoundTrip, SubPixelHighlight, ::testing::Values(3, 1));

// The third outside set's 0018: a point-lit sphere at 256 x 256 whose highlight is a tenth of a
// pixel (kd 0.05, ks 0.9, n 200000), its image rendered with 256 Sobol points a pixel, as its scene
// says. One pixel holds ks, and the image's noise there (3.6% in ks over image seeds) is in no
// other pixel; the smooth pixels, which Sobol points render almost without noise, show none to
// model it on. At image seeds 1 and 2 the fit (recording seed 0) said ks 0.9351 and 0.8569 +-
// 0.005 before that pixel was rendered anew as the scene renders it (FitOptions::renderedNoise):
// +- 0.021 and 0.020 since. Told the image has no noise (--image-spp 0) it still says +- 0.005.
class HighlightPixelNoise : public RoundTrip, public ::testing::WithParamInterface<const char*> {};

TEST_P(HighlightPixelNoise, IsRenderedAsTheSceneRendersIt) {
    const std::map<std::string, std::string> truth = {{"kd", "0.05"},    {"ks", "0.9"},
                                                      {"n", "200000"},   {"width", "256"},
                                                      {"height", "256"}, {"spp", "256"}};
    const std::string view = kPoint + ":" + render(kPoint, truth, "tiny", 256, GetParam());
    std::vector<std::string> args = {"--kd", "0.3", "--ks", "0.3", "--n", "2000"};
    const std::vector<std::string> d = defines(truth);
    args.insert(args.end(), d.begin(), d.end());
    const auto rendered = fit({view}, args, "rendered", 0)["materials"]["sphere"];
    args.insert(args.end(), {"--image-spp", "0"});
    const auto modelled = fit({view}, args, "modelled", 0)["materials"]["sphere"];
    for (int c = 0; c < 3; ++c) {
        const double ks = rendered["ks"][c].get<double>(),
                     std = rendered["ks_std"][c].get<double>();
        EXPECT_LT(std::abs(ks - 0.9), 3 * std) << ks << " +- " << std;
        EXPECT_LT(std, 0.05) << "the pixel's noise is a few percent of ks, not more";
        EXPECT_EQ(modelled["ks"][c].get<double>(), ks) << "only the standard errors change";
        const double claimed = modelled["ks_std"][c].get<double>();
        EXPECT_GT(std::abs(ks - 0.9), 3 * claimed) << ks << " +- " << claimed;
    }
}

INSTANTIATE_TEST_SUITE_P(RoundTrip, HighlightPixelNoise, ::testing::Values("1", "2"));

// A backlit sphere (stiff-case study sample 35): at 4 paths round 0, recorded at the start
// (n = 100 for a true 10.7), sees too little of the lobe and holds n there; held for good, ks
// stayed small and kd went to 0.96 +- 0.14, 4.6 standard errors off. The lobe test is decided
// anew each round: a later round frees n, and the estimate's errors cover the truth. Whether the
// last round holds n again is the image's noise (256 paths a pixel: kd's standard error is 0.4 or
// more at every seed, the noise floor): seeds 1-8 end with n held in 3 of 8, before the moment
// solves' iteration cap (c6bcf14) as after.
TEST_F(RoundTrip, GrazingHighlightReleasesAnExponentHeldInRoundZero) {
    const std::map<std::string, std::string> truth = {{"kd", "0.31"},       {"ks", "0.29"},
                                                      {"n", "10.65"},       {"light_x", "-2.005"},
                                                      {"light_y", "2.976"}, {"light_z", "-6.092"}};
    const std::string image = render(kOrbit, truth, "grazing", 256);
    std::vector<std::string> extra = {"--grey", "--kd", "0.25",  "--ks", "0.25",
                                      "--n",    "100",  "--spp", "4"};
    const auto d = defines(truth);
    extra.insert(extra.end(), d.begin(), d.end());
    const auto report = fit({kOrbit + ":" + image}, extra, "fit");
    bool released = false;
    for (std::size_t r = 1; r < report["rounds"].size(); ++r)
        released = released || report["rounds"][r]["materials"]["sphere"]["unconstrained"].empty();
    EXPECT_TRUE(released);
    const auto& m = report["materials"]["sphere"];
    EXPECT_LT(std::abs(m["kd"][0].get<double>() - 0.31), 3 * m["kd_std"][0].get<double>());
    EXPECT_LT(std::abs(m["ks"][0].get<double>() - 0.29), 3 * m["ks_std"][0].get<double>());
    if (m["unconstrained"].empty()) {
        EXPECT_LT(std::abs(m["n"].get<double>() - 10.65), 3 * m["n_std"].get<double>());
    }
}

// Issue 12's area-light case at 128 x 128: the highlight is the quad light's reflection, a few
// pixels across, with a lobe (n = 5000) much narrower than the light. Recorded at 4 paths per
// pixel everywhere, the paths rarely land in it and the fit ends near n = 550 +- 360; with paths
// spent where they inform the estimate (--adaptive-spp) every parameter is recovered and
// covered by its standard error. The estimate settles; n's 1% precision takes more than the six
// rounds (the paths still hold most of its variance: not the images' noise floor), or more paths
// than the pixels holding the highlight can take ("path cap").
TEST_F(RoundTrip, AreaLightSharpLobeIsFoundWithAdaptivePaths) {
    const std::map<std::string, std::string> size = {{"width", "128"}, {"height", "128"}};
    const std::string image = render(kQuad, size, "quad", 512);
    std::vector<std::string> extra = {"--kd", "0.3", "--ks",           "0.3",
                                      "--n",  "10",  "--adaptive-spp", "4"};
    const auto d = defines(size);
    extra.insert(extra.end(), d.begin(), d.end());
    const auto report = fit({kQuad + ":" + image}, extra, "fit");
    const auto& m = report["materials"]["sphere"];
    const std::string stop = report["stop_reason"];
    EXPECT_TRUE(stop == "precision" || stop == "noise floor" || stop == "precision not met" ||
                stop == "path cap")
        << stop;
    EXPECT_TRUE(m["unconstrained"].empty()) << m["unconstrained"].dump();
    for (int c = 0; c < 3; ++c) {
        const double kd = m["kd"][c].get<double>(), ks = m["ks"][c].get<double>();
        EXPECT_NEAR(kd, 0.3, 0.02 * 0.3);
        EXPECT_NEAR(ks, 0.6, 0.04 * 0.6);
        EXPECT_LT(std::abs(kd - 0.3), 3 * m["kd_std"][c].get<double>());
        EXPECT_LT(std::abs(ks - 0.6), 3 * m["ks_std"][c].get<double>());
    }
    const double n = m["n"].get<double>(), nStd = m["n_std"].get<double>();
    EXPECT_LT(std::abs(n - 5000), 3 * nStd) << n << " +- " << nStd;
    EXPECT_LT(nStd, 0.3 * 5000) << "the lobe is resolved";
}

// The recovery matrix's sphere under the 40-degree light, with a lobe far narrower than a pixel's
// reach (n 30000, at 128 x 128; largeLightSphere): the pixels at the edge of the light's
// reflection hold n, and once they carry the most paths a recording gives a pixel, more paths
// cannot meet the precision. The fit ends there, before the rounds run out, not converged, with the
// truth within 3 standard errors: at recording seed 3 "path cap" (the paths still hold most of n's
// variance, but the pixels cannot take more); at seed 5 (the seed this test ran alone until the
// anchors' standard errors took the recordings' part, sessions 85-86) "unresolved": at 16 times
// the first round's paths the image's noise holds the larger part of n's variance, and n's standard
// error is larger than n (49635 +- 611943 in its last round).
TEST_F(RoundTrip, LobeHeldByPixelsAtTheirPathCapEndsThere) {
    const LargeLightCase c = largeLightSphere("0.45", "0.5", "wide", 256);
    for (const auto& [seed, stop] : {std::pair{3, "path cap"}, std::pair{5, "unresolved"}}) {
        const auto report = fit({c.view}, c.extra, "fit" + std::to_string(seed), seed);
        EXPECT_EQ(report["stop_reason"], stop) << seed;
        EXPECT_LT(report["rounds"].size(), 6u) << seed;
        EXPECT_FALSE(report["converged"].get<bool>()) << seed;
        const nlohmann::json& m = report["materials"]["sphere"];
        if (std::string(stop) == "unresolved") {
            EXPECT_GE(m["n_std"].get<double>(), m["n"].get<double>()) << seed;
        }
        expectCovered(m, {0.45, 0.45, 0.45}, {0.5, 0.5, 0.5}, 30000,
                      "40-degree light, n 30000, seed " + std::to_string(seed));
    }
}

// The same scene rendered at 1024 paths, with the light sampled as before rings
// (--sampled-area-lights): rounds that climb towards a lobe sharper than their recordings resolve
// settle round by round short of it (seed 1: 1977, 6364, 7883, 9156 +- 6245, 3.3 standard errors
// short; seed 2: 5539 +- 1163, 21 short, before n's drift was judged in log n), and had ended
// "precision not met". Never recorded at twice their n, they now probe its sharper side in their
// last round, which goes on sharper ("sharper lobe": seed 1 from 31532 to 32896, n 7883 +- 992117;
// seed 2 from 19487 to 24383, n 4872 +- 995128; kd and ks within 0.7%): the truth is covered.
TEST_F(RoundTrip, ClimbThatSettlesShortOfTheLobeHasItsSharperSideProbed) {
    LargeLightCase c = largeLightSphere("0.45", "0.5", "climb", 1024);
    c.extra.push_back("--sampled-area-lights");
    for (const int seed : {1, 2}) {
        const auto report = fit({c.view}, c.extra, "fit", seed);
        EXPECT_EQ(report["stop_reason"], "sharper lobe") << seed;
        EXPECT_TRUE(report["rounds"].back()["probe"].get<bool>()) << seed;
        EXPECT_FALSE(report["converged"].get<bool>()) << seed;
        expectCovered(report["materials"]["sphere"], {0.45, 0.45, 0.45}, {0.5, 0.5, 0.5}, 30000,
                      "climb, seed " + std::to_string(seed));
    }
}

// ks 0.05: seed 0 climbs 237, 1127, 1318, 3821 and settles in its last round at 6524 +- 1945,
// a move of 1.4 of its standard errors; with no round left for a sharper probe it had ended
// "converged" (n +- 4468, 5.3 standard errors short). A lobe still climbing is not converged, and
// its drift covers the truth.
TEST_F(RoundTrip, ClimbThatSettlesInTheLastRoundIsNotConverged) {
    LargeLightCase c = largeLightSphere("0.7", "0.05", "climb", 1024);
    c.extra.push_back("--sampled-area-lights");
    const auto report = fit({c.view}, c.extra, "fit", 0);
    EXPECT_EQ(report["stop_reason"], "sharper lobe");
    EXPECT_FALSE(report["converged"].get<bool>());
    EXPECT_EQ(report["rounds"].size(), 6u);
    expectCovered(report["materials"]["sphere"], {0.7, 0.7, 0.7}, {0.05, 0.05, 0.05}, 30000,
                  "climb, ks 0.05");
}

// The two climbs above with the light integrated by rings (the default). A lobe of n 30000 at
// 128 x 128 is far narrower than a pixel's reach, and with the light's reflection exact in the
// recordings the fit no longer climbs: it says the images do not hold n (seed 1: 5816 +- 5e5;
// seed 2: 1e6 +- 2e6; ks 0.05: 22459 +- 2.7e6), not converged, kd and ks covered.
TEST_F(RoundTrip, RingsSayASubPixelLobesExponentIsNotHeld) {
    for (const auto& [kd, ks, seed] : {std::tuple{"0.45", "0.5", 1}, std::tuple{"0.45", "0.5", 2},
                                       std::tuple{"0.7", "0.05", 0}}) {
        const LargeLightCase c = largeLightSphere(kd, ks, "rings", 1024);
        const auto report = fit({c.view}, c.extra, "rings", seed);
        const auto& m = report["materials"]["sphere"];
        const double kdv = std::stod(kd), ksv = std::stod(ks);
        const std::string what = std::string("rings, ks ") + ks + ", seed " + std::to_string(seed);
        EXPECT_FALSE(report["converged"].get<bool>()) << what;
        EXPECT_GT(m["n_std"].get<double>(), 30000) << what;
        expectCovered(m, {kdv, kdv, kdv}, {ksv, ksv, ksv}, 30000, what);
        // Bound from below only: n's standard error reaches log n's 3 standard errors up.
        const double n = m["n"].get<double>(), s = m["log_n_std"].get<double>();
        EXPECT_GE(3 * m["n_std"].get<double>(),
                  (1 - 1e-12) * std::min(n * std::expm1(3 * s), 1e6 - n))
            << what << ": n " << n << ", log n +- " << s;
    }
}

// The 40-degree light at n 3000, ks 0.05 (the recovery matrix's cell 0055 at 128 x 128): the
// rounds at 4 paths a pixel hold n to about 5% and the precision target asks 1%, so the paths
// grow 16x. Each pixel's first paths are ringed, its extra ones sampled, far noisier on the
// highlight; as one mean that round fell to n 2304 +- 2300, ks 0.0512 +- 0.0011 and the fit ended
// "path cap", n 23% off. Each kind's mean weighted by the inverse of its variance (PathGroups),
// the grown round is at least as precise as the rounds before it and shows the images' noise
// floor: n 3200 +- 160, ks 0.04999 +- 0.00008.
TEST_F(RoundTrip, GrownRoundsOfRingedRecordingsKeepTheRingsPrecision) {
    const LargeLightCase c = largeLightSphere("0.7", "0.05", "grown", 1024, "3000");
    const auto report = fit({c.view}, c.extra, "fit");
    const auto& rounds = report["rounds"];
    std::size_t grown = 1;
    while (grown < rounds.size() && rounds[grown]["path_factor"].get<double>() <= 1) ++grown;
    ASSERT_LT(grown, rounds.size()) << "a round grew the paths";
    const auto& before = rounds[grown - 1]["materials"]["sphere"];
    const auto& after = rounds[grown]["materials"]["sphere"];
    EXPECT_LT(after["n_std"].get<double>(), 1.5 * before["n_std"].get<double>());
    for (int ch = 0; ch < 3; ++ch)
        EXPECT_LT(after["ks_std"][ch].get<double>(), 1.5 * before["ks_std"][ch].get<double>());
    EXPECT_EQ(report["stop_reason"], "noise floor");
    expectCovered(report["materials"]["sphere"], {0.7, 0.7, 0.7}, {0.05, 0.05, 0.05}, 3000,
                  "40-degree light, n 3000, ks 0.05");
}

// Images from an independent renderer: Tungsten's renders of sphere_quad.xml
// (tests/data/tungsten/README.md), its own sampler, noise and Phong code, fitted at the defaults
// from kd, ks 0.3 and n far off. Seen on them: n 5128 +- 190 for 5000 and 3058 +- 63 for 3000
// (seed 0), 4806 +- 310 and 3066 +- 44000 (seed 3, the test's: a sharper probe that did not come
// back widens n's error), kd and ks within 0.5%, "not converged" after six rounds; on the face
// kd + ks = 1 (kd 0.2, ks 0.8, n 1500 from 15): kd 0.19999 and 0.20001 +- 1.1e-5, ks 0.7997 and
// 0.7976 +- 0.0015, n 1501 +- 7 and 1510 +- 7, converged (seeds 0 and 3); no lobe: ks 0, n
// unconstrained.
TEST_F(RoundTrip, TungstenRendersOfTheQuadLitSphereAreRecovered) {
    struct Case {
        const char* image;
        std::array<double, 3> kd, ks;
        double n;
        const char* startN;
    };
    const std::array<double, 3> grey3{0.3, 0.3, 0.3}, grey6{0.6, 0.6, 0.6};
    for (const Case& c :
         {Case{"sphere_quad_n5000", grey3, grey6, 5000, "10"},
          Case{"sphere_quad_coloured_n3000",
               {0.3, 0.7 / 3, 0.5 / 3},
               {0.6, 1.4 / 3, 1.0 / 3},
               3000,
               "30"},
          Case{"sphere_quad_face_n1500", {0.2, 0.2, 0.2}, {0.8, 0.8, 0.8}, 1500, "15"},
          Case{"sphere_quad_no_lobe", grey6, {0, 0, 0}, 0, "1"}}) {
        const auto report = fit({kQuad + ":" + PHONGFIT_TUNGSTEN_DIR "/" + c.image + ".exr"},
                                {"--kd", "0.3", "--ks", "0.3", "--n", c.startN}, c.image);
        const auto& m = report["materials"]["sphere"];
        for (int ch = 0; ch < 3; ++ch) {
            EXPECT_NEAR(m["kd"][ch].get<double>(), c.kd[ch], std::max(0.02 * c.kd[ch], 0.003))
                << c.image;
            EXPECT_NEAR(m["ks"][ch].get<double>(), c.ks[ch], std::max(0.02 * c.ks[ch], 0.003))
                << c.image;
        }
        const std::string unconstrained = m["unconstrained"].dump();
        if (c.n == 0) {
            expectCovered(m, c.kd, c.ks, std::nullopt, c.image);
            EXPECT_NE(unconstrained.find("\"n\""), std::string::npos) << unconstrained;
            continue;
        }
        expectCovered(m, c.kd, c.ks, c.n, c.image);
        EXPECT_EQ(unconstrained, "[]") << c.image;
        EXPECT_NEAR(m["n"].get<double>(), c.n, 0.05 * c.n) << c.image;
    }
}

// A sharp lobe under a point light from Tungsten: n 5008 +- 48 (seed 0) and 5012 +- 530
// (seed 3) for 5000 from 50, ks within 0.3%, converged.
TEST_F(RoundTrip, TungstenPointLitSharpLobeIsRecovered) {
    const auto report = fit({kPoint + ":" + PHONGFIT_TUNGSTEN_DIR "/sphere_point_n5000.exr"},
                            {"--kd", "0.3", "--ks", "0.3", "--n", "50"}, "point");
    const auto& m = report["materials"]["sphere"];
    expectRecovered(m, 0.5, 0.3, 5000, "tungsten point");
    expectCovered(m, {0.5, 0.5, 0.5}, {0.3, 0.3, 0.3}, 5000, "tungsten point");
}

// The Cornell box from Tungsten (tests/data/tungsten/README.md), indirect light to 64 bounces:
// the walls' light reaches the sphere through recorded paths of many vertices, replayed. Seen:
// kd within 0.3%, ks 0.25%, n 30.08 +- 0.12 (seed 0) and 30.05 +- 0.18 (seed 3), converged.
TEST_F(RoundTrip, TungstenCornellBoxIsRecovered) {
    const auto report = fit({kCornell + ":" + PHONGFIT_TUNGSTEN_DIR "/cornell_phong_n30.exr"},
                            {"-D", "maxDepth=64", "-D", "width=128", "-D", "height=128", "--kd",
                             "0.3", "--ks", "0.3", "--n", "3000"},
                            "cornell");
    const auto& m = report["materials"]["sphere"];
    expectRecovered(m, 0.5, 0.2, 30, "tungsten cornell");
    expectCovered(m, {0.5, 0.5, 0.5}, {0.2, 0.2, 0.2}, 30, "tungsten cornell");
    EXPECT_TRUE(report["converged"].get<bool>());
}

// Issue 14: a coloured Phong sphere under the real Kerner light probe (tiled, mip-mapped, half
// float), turned by 60 degrees: the recorded light samples come from the envmap's sampler and
// replay like any other; one convex object needs direct light only.
TEST_F(RoundTrip, SphereUnderTheKernerProbeIsRecovered) {
    const std::map<std::string, std::string> truth = {
        {"kd", "0.4, 0.3, 0.2"}, {"ks", "0.3"}, {"n", "100"}, {"rotate", "60"}};
    const std::string image = render(kEnvmap, truth, "probe", 256);
    std::vector<std::string> extra = {"--kd", "0.3",   "--ks", "0.3", "--n",
                                      "1000", "--spp", "16",   "-D",  "rotate=60"};
    const nlohmann::json report = fit({kEnvmap + ":" + image}, extra, "fit");
    const auto& m = report["materials"]["sphere"];
    const std::array<double, 3> kd = {0.4, 0.3, 0.2};
    for (int c = 0; c < 3; ++c) {
        EXPECT_NEAR(m["kd"][c].get<double>(), kd[c], 0.02 * kd[c]) << "kd channel " << c;
        EXPECT_NEAR(m["ks"][c].get<double>(), 0.3, 0.02 * 0.3) << "ks channel " << c;
    }
    EXPECT_NEAR(m["n"].get<double>(), 100, 5);
    expectCovered(m, kd, {0.3, 0.3, 0.3}, 100, "probe");
    EXPECT_TRUE(report["converged"].get<bool>());
    EXPECT_EQ(report["views"][0]["max_depth"].get<int>(), 2) << "direct light only";
    // Light samples and lobe samples both reach the lobe: a converged lobe is probed sharper.
    EXPECT_TRUE(report["rounds"].back()["probe"].get<bool>());
}

// outside_third.json's cell 0025 as `synth` renders it: a faint broad lobe (kd 0.5, ks 0.01,
// n 150) under the Kerner probe, fitted from a sharp start (n 15000) at recording seed 0. Pooled
// least squares in the start's scan kept the start (the broad lobe adds more of the recordings'
// variance than squared error it removes): ks went to 0, n was held, and the fit "converged" in
// two rounds with kd 1.3% high, 8.8 of its standard errors (1 of the 6 recording seeds measured;
// the others found the lobe). The cross products overrule that pick (start_scan.cpp,
// crossSignificant).
TEST_F(RoundTrip, AFaintBroadLobeIsFoundFromASharpStart) {
    const std::map<std::string, std::string> truth = {
        {"kd", "0.5"}, {"ks", "0.01"}, {"n", "150"}, {"width", "256"}, {"height", "256"}};
    const std::string image = render(kEnvmap, truth, "faint", 256, "8446970460851969503");
    std::vector<std::string> extra = {"--grey",    "--kd",  "0.3",       "--ks", "0.3",
                                      "--n",       "15000", "--rounds",  "2",    "-D",
                                      "width=256", "-D",    "height=256"};
    const auto m = fit({kEnvmap + ":" + image}, extra, "fit", 0)["materials"]["sphere"];
    const auto& u = m["unconstrained"];
    EXPECT_EQ(std::find(u.begin(), u.end(), "n"), u.end()) << u.dump();
    expectCovered(m, {0.5, 0.5, 0.5}, {0.01, 0.01, 0.01}, 150, "faint lobe");
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(m["kd"][c].get<double>(), 0.5, 0.0025) << c;
}

// Seed 88's c014 (random round trips): a sharp lobe under the Kerner probe at 128 x 128.
const std::map<std::string, std::string> kProbeSunTruth = {
    {"kd", "0.350056"}, {"ks", "0.37232"}, {"n", "6198.62"}, {"width", "128"}, {"height", "128"}};

// c014's image from 1024 Sobol points a pixel. ks's noise in the image sits in the few pixels that
// reflect the probe's sun (up to 56 where the sphere is 0.1-0.7); none holds a quarter of ks's
// information, and the model's kappa, read off smooth pixels that Sobol points render almost
// without noise, put ks's image noise at 0.0019. Images at six seeds scatter by 0.0033 (their means
// over recording seeds). At this image seed and recording seed 0 the fit said ks 0.3657 +-
// 0.0019, 3.4 of them off, until the sun's brightest pixels were rendered anew (kHeldShare a
// twentieth): +- 0.0032.
TEST_F(RoundTrip, ASharpLobeReflectingTheProbesSunTakesTheNoiseOfThosePixels) {
    const std::map<std::string, std::string>& truth = kProbeSunTruth;
    const std::string image = render(kEnvmap, truth, "sun", 1024, "5");
    const auto m = fitFromFar(kEnvmap + ":" + image, truth)["materials"]["sphere"];
    for (int c = 0; c < 3; ++c) {
        EXPECT_GT(m["image_noise_std"]["ks"][c].get<double>(), 0.0028) << "channel " << c;
        EXPECT_LT(std::abs(m["ks"][c].get<double>() - 0.37232), 3 * m["ks_std"][c].get<double>())
            << m["ks"][c].get<double>() << " +- " << m["ks_std"][c].get<double>();
    }
}

// One round of the image above at the truth, 32 paths a pixel: its estimate is mostly an anchor of
// the moments (cross products, or pooled least squares), whose standard errors took each pixel's
// score as fitted. The pixels reflecting the sun hold ks, and each pulls the estimate towards
// itself, shrinking its own score: at recording seeds 5, 6 and 9 the round said ks 0.4275 +-
// 0.0084, 0.4123 +- 0.0038 and 0.4481 +- 0.0120, 6.6, 10.4 and 6.3 of them off (rms 2.98 over 30
// seeds). With the recordings' part of each pixel's term added where it says more (anchorScores:
// the image's noise cancels in it, and no fit absorbs it), rms 0.97 (kd 0.90, log n 0.82): seeds 5
// and 6 say 0.4275 +- 0.064 and 0.4123 +- 0.115, and seed 9 keeps the moments, 0.3718 +- 0.0011.
TEST_F(RoundTrip, ARoundsStandardErrorsUnderTheProbesSunCoverItsRecordingsNoise) {
    const std::map<std::string, std::string>& truth = kProbeSunTruth;
    const std::string image = render(kEnvmap, truth, "sun", 1024, "5");
    // From the truth: the scene's defaults.
    std::vector<std::string> extra = defines(truth);
    extra.insert(extra.end(), {"--spp", "32", "--rounds", "1"});
    for (int seed : {5, 6, 9}) {
        const auto report = fit({kEnvmap + ":" + image}, extra, "fit" + std::to_string(seed), seed);
        const auto& m = report["rounds"][0]["materials"]["sphere"];
        for (const char* p : {"kd", "ks"})
            for (int c = 0; c < 3; ++c)
                EXPECT_LT(std::abs(m[p][c].get<double>() - std::stod(truth.at(p))),
                          3 * m[std::string(p) + "_std"][c].get<double>())
                    << "seed " << seed << ": " << p << "[" << c << "] " << m[p][c].get<double>()
                    << " +- " << m[std::string(p) + "_std"][c].get<double>();
    }
}

TEST_F(RoundTrip, NoSpecularLobeLeavesNUnconstrained) {
    const std::map<std::string, std::string> truth = {{"kd", "0.6"}, {"ks", "0"}, {"n", "30"}};
    const std::string image = render(kLit, truth, "diffuse", 64);
    std::vector<std::string> extra = {"--ks", "0.2", "--n", "50"};
    const auto d = defines(truth);
    extra.insert(extra.end(), d.begin(), d.end());
    const auto m = fit({kLit + ":" + image}, extra, "fit")["materials"]["sphere"];
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(m["kd"][c].get<double>(), 0.6, 0.012);
    const auto& u = m["unconstrained"];
    EXPECT_NE(std::find(u.begin(), u.end(), "n"), u.end()) << u.dump();
    EXPECT_LE(m["n"].get<double>(), 50) << "held at its start, or where it went broader";
    for (int c = 0; c < 3; ++c) EXPECT_LT(m["ks"][c].get<double>(), 0.01);
}

// Issue 12's no-lobe case: a point-lit coloured sphere with ks = 0. n used to run to its lower
// bound, where the lobe is a flat second diffuse term, and come back with ks 0.0009 +- 0.0004
// (2.4 standard errors, enough to count as a lobe) and kd 0.15% low; from a start at 300 it
// stopped at n = 0.00101, just off the bound. Below n = 0.01 n is held and reported
// unconstrained, from a start far below or far above.
TEST_F(RoundTrip, NoLobeLeavesNUnconstrainedEvenAtItsLowerBound) {
    const std::map<std::string, std::string> truth = {
        {"kd", "0.6,0.5,0.4"}, {"ks", "0"}, {"n", "30"}, {"width", "128"}, {"height", "128"}};
    const std::string image = render(kPoint, truth, "nolobe", 256);
    for (const char* start : {"0.3", "300", "3000"}) {
        std::vector<std::string> extra = {"--kd", "0.3", "--ks", "0.3", "--n", start};
        const auto d = defines(truth);
        extra.insert(extra.end(), d.begin(), d.end());
        const auto m = fit({kPoint + ":" + image}, extra, "fit")["materials"]["sphere"];
        const auto& u = m["unconstrained"];
        EXPECT_NE(std::find(u.begin(), u.end(), "n"), u.end()) << start << ": " << u.dump();
        const double kd[3] = {0.6, 0.5, 0.4};
        for (int c = 0; c < 3; ++c) {
            EXPECT_NEAR(m["kd"][c].get<double>(), kd[c], 0.002 * kd[c]) << start;
            EXPECT_LT(m["ks"][c].get<double>(), 0.003) << start;
        }
    }
}

// No lobe under the Kerner probe (kd 0.5, ks 0; 64 x 64, 256 paths a pixel), from n 0.1: n is held
// and its ks is a lobe's at an exponent the images do not determine. Asked for 0.001 (1% of
// kPrecisionFloor), that ks took the paths to 16, 32, 12 and 16 times the first round's and ended
// "precision not met" after six rounds (6.5 s; 17.9 s at 96 x 96, seed 91's c009); asked for 1%
// of the albedo, kd + ks, the fit ends "precision" at 32 times (2.5 s), kd 0.5% off.
TEST_F(RoundTrip, NoLobeUnderTheProbeMeetsThePrecisionOfItsAlbedo) {
    const std::map<std::string, std::string> truth = {
        {"kd", "0.5"}, {"ks", "0"}, {"n", "10"}, {"width", "64"}, {"height", "64"}};
    const std::string image = render(kEnvmap, truth, "lobeless", 256);
    const nlohmann::json report = fitFromFar(kEnvmap + ":" + image, truth);
    EXPECT_EQ(report["stop_reason"], "precision");
    EXPECT_TRUE(report["converged"].get<bool>());
    EXPECT_LE(report["rounds"].size(), 4u);
    const auto& m = report["materials"]["sphere"];
    const auto& u = m["unconstrained"];
    EXPECT_NE(std::find(u.begin(), u.end(), "n"), u.end()) << u.dump();
    for (int c = 0; c < 3; ++c) {
        EXPECT_NEAR(m["kd"][c].get<double>(), 0.5, 0.01) << c;
        EXPECT_LE(m["ks_std"][c].get<double>(), 0.01 * 0.5 * 1.01) << c;
    }
    expectCovered(m, {0.5, 0.5, 0.5}, {0, 0, 0}, std::nullopt, "no lobe under the probe");
}

// --precision: once the estimate stops moving, rounds record more paths where they inform it
// until every free parameter's relative standard error is below the target. At 4 paths per
// pixel the point-lit coloured lobe (a few pixels across at 64 x 64) stops at ks +- 3%, n +- 5%;
// asked for 0.5%, the paths grow and the fit reports "precision" with errors that cover the
// truth. An image rendered at 4 paths per pixel holds too little to reach it: "noise floor".
TEST_F(RoundTrip, PrecisionTargetSpendsPathsUntilMetOrAtTheImagesNoiseFloor) {
    const std::map<std::string, std::string> truth = {
        {"kd", "0.45,0.4,0.3"}, {"ks", "0.5"}, {"n", "300"}, {"width", "64"}, {"height", "64"}};
    std::vector<std::string> extra = {"--kd", "0.3",   "--ks",        "0.3",
                                      "--n",  "30000", "--precision", "0.005"};
    const auto d = defines(truth);
    extra.insert(extra.end(), d.begin(), d.end());
    const auto report = fit({kPoint + ":" + render(kPoint, truth, "clean", 256)}, extra, "fit");
    EXPECT_EQ(report["stop_reason"], "precision");
    EXPECT_TRUE(report["converged"].get<bool>());
    const auto& rounds = report["rounds"];
    ASSERT_GE(rounds.size(), 3u);
    // The converged round's paths (a sharper probe may follow it: sharper_probe.h).
    const auto converged =
        std::find_if(rounds.rbegin(), rounds.rend(),
                     [](const nlohmann::json& r) { return !r["probe"].get<bool>(); });
    ASSERT_NE(converged, rounds.rend());
    EXPECT_GT((*converged)["paths"].get<double>(), 1.5 * rounds[0]["paths"].get<double>());
    const auto& m = report["materials"]["sphere"];
    const std::array<double, 3> kd = {0.45, 0.4, 0.3};
    for (int c = 0; c < 3; ++c) {
        EXPECT_LE(m["kd_std"][c].get<double>(), 0.005 * kd[c]);
        EXPECT_LE(m["ks_std"][c].get<double>(), 0.005 * 0.5);
    }
    EXPECT_LE(m["n_std"].get<double>(), 0.005 * m["n"].get<double>());
    expectCovered(m, kd, {0.5, 0.5, 0.5}, 300, "precision");

    const auto noisy = fit({kPoint + ":" + render(kPoint, truth, "noisy", 4)}, extra, "noisy");
    EXPECT_EQ(noisy["stop_reason"], "noise floor");
    // The image's share is told apart from the paths': no round records more than it takes to
    // see that more paths do not help (kMostPathGrowth, 16 times the first round's).
    for (const auto& r : noisy["rounds"]) EXPECT_LE(r["path_factor"].get<double>(), 16) << r.dump();
}

TEST_F(RoundTrip, NoDiffuseAndEnergyConservingExtremes) {
    for (const auto& [kd, ks] : {std::pair{0.0, 0.7}, std::pair{0.35, 0.65}}) {
        const std::map<std::string, std::string> truth = {{"kd", std::to_string(kd)},
                                                          {"ks", std::to_string(ks)},
                                                          {"n", "40"},
                                                          {"light_x", "1"},
                                                          {"light_y", "1.5"}};
        const std::string image = render(kLit, truth, "extreme", 256);
        std::vector<std::string> extra = {"--kd", "0.3", "--ks", "0.3", "--n", "10"};
        const auto d = defines(truth);
        extra.insert(extra.end(), d.begin(), d.end());
        const auto m = fit({kLit + ":" + image}, extra, "fit")["materials"]["sphere"];
        for (int c = 0; c < 3; ++c) {
            EXPECT_NEAR(m["kd"][c].get<double>(), kd, 0.02 * kd + 0.005) << "kd + ks = " << kd + ks;
            EXPECT_NEAR(m["ks"][c].get<double>(), ks, 0.02 * ks) << "kd + ks = " << kd + ks;
            EXPECT_LE(m["kd"][c].get<double>() + m["ks"][c].get<double>(), 1 + 1e-9);
        }
        EXPECT_NEAR(m["n"].get<double>(), 40, 2);
    }
}

TEST_F(RoundTrip, LdrPhotoWithClippedHighlightsIsFittedWithoutThem) {
    const std::map<std::string, std::string> truth = {
        {"light_x", "1"}, {"light_y", "1.5"}, {"intensity", "60"}};
    const Image hdr = readImage(render(kLit, truth, "hdr", 256));
    writePng(hdr, path("photo.png"));  // 8-bit sRGB: the highlight clips at 255
    const Image ldr = readImage(path("photo.png"));
    const auto clipped = std::count(ldr.clipped.begin(), ldr.clipped.end(), 1);
    ASSERT_GT(clipped, 10) << "the test needs clipped highlight pixels";

    std::vector<std::string> extra = {"--kd", "0.2", "--ks", "0.1", "--n", "300"};
    const auto d = defines(truth);
    extra.insert(extra.end(), d.begin(), d.end());
    const auto report = fit({kLit + ":" + path("photo.png")}, extra, "fit");
    EXPECT_EQ(report["views"][0]["pixels_clipped"].get<long>(), clipped);
    // 8-bit quantisation: a looser bound than for EXR.
    const auto& m = report["materials"]["sphere"];
    for (int c = 0; c < 3; ++c) {
        EXPECT_NEAR(m["kd"][c].get<double>(), 0.5, 0.02);
        EXPECT_NEAR(m["ks"][c].get<double>(), 0.3, 0.02);
    }
    EXPECT_NEAR(m["n"].get<double>(), 30, 3);
}

// An image `gain` times brighter than the scene renders it, as a photograph of unknown exposure.
std::string scaled(const std::string& exr, double gain, const std::string& out) {
    Image image = readImage(exr);
    for (float& v : image.rgb) v = float(v * gain);
    writeExr(image, out);
    return out;
}

// In the Cornell box the walls, of known reflectance, fix the exposure, and interreflections
// make the image non-linear in kd: the exposure is recovered with the materials. Without
// --fit-exposure the same image pins kd + ks at 1 and fits badly.
TEST_F(RoundTrip, CornellBoxWithUnknownExposure) {
    const std::map<std::string, std::string> size = {{"width", "128"}, {"height", "128"}};
    const std::string image =
        scaled(render(kCornell, size, "cornell", 512), 2.5, path("bright.exr"));
    std::vector<std::string> extra = {"--kd", "0.3", "--ks", "0.05", "--n", "300", "--spp", "64"};
    const auto d = defines(size);
    extra.insert(extra.end(), d.begin(), d.end());
    std::vector<std::string> withExposure = extra;
    withExposure.push_back("--fit-exposure");
    const auto report = fit({kCornell + ":" + image}, withExposure, "fit");
    const auto& e = report["exposure"];
    EXPECT_FALSE(e["unconstrained"].get<bool>());
    EXPECT_NEAR(e["value"].get<double>(), 2.5, 0.02 * 2.5);
    EXPECT_LT(std::abs(e["value"].get<double>() - 2.5), 3 * e["std"].get<double>());
    expectRecovered(report["materials"]["sphere"], 0.5, 0.2, 30, "Cornell box, exposure fitted");
    for (const auto& r : report["rounds"]) EXPECT_TRUE(r.contains("exposure"));

    const auto fixed = fit({kCornell + ":" + image}, extra, "fixed");
    EXPECT_FALSE(fixed.contains("exposure"));
    EXPECT_GT(fixed["rmse"].get<double>(), 2 * report["rmse"].get<double>());
}

// One sphere under a point light: scaling kd and ks scales the image, so only s kd, s ks and n are
// seen. The exposure is reported unconstrained and held where the start matches the image's
// brightness or, from a start as bright as kd + ks = 1 allows, as far above that as keeping
// kd + ks <= 1 needs; the products and n are recovered either way.
TEST_F(RoundTrip, DirectLightLeavesTheExposureUnconstrained) {
    const std::map<std::string, std::string> truth = {{"light_x", "1"}, {"light_y", "1.5"}};
    const std::string image = scaled(render(kLit, truth, "truth", 256), 2.5, path("bright.exr"));
    const auto d = defines(truth);
    for (const auto& [start, ks] : {std::pair{"0.3", "0.05"}, std::pair{"0.7", "0.3"}}) {
        std::vector<std::string> extra = {
            "--fit-exposure", "--kd", start, "--ks", ks, "--n", "300"};
        extra.insert(extra.end(), d.begin(), d.end());
        const auto report = fit({kLit + ":" + image}, extra, fmt::format("fit{}", start));
        const auto& e = report["exposure"];
        EXPECT_TRUE(e["unconstrained"].get<bool>()) << "start kd " << start;
        EXPECT_EQ(e["std"].get<double>(), 0);
        const double s = e["value"].get<double>();
        const auto& m = report["materials"]["sphere"];
        double highest = 0;
        for (int c = 0; c < 3; ++c) {
            const double kd = m["kd"][c].get<double>(), ks = m["ks"][c].get<double>();
            highest = std::max(highest, kd + ks);
            EXPECT_NEAR(s * kd, 2.5 * 0.5, 0.02 * 2.5 * 0.5) << "start kd " << start;
            EXPECT_NEAR(s * ks, 2.5 * 0.3, 0.02 * 2.5 * 0.3) << "start kd " << start;
            EXPECT_LE(kd + ks, 1 + 1e-9);
        }
        EXPECT_NEAR(m["n"].get<double>(), 30, 0.05 * 30) << "start kd " << start;
        // The bright start's brightness match leaves the fit wanting kd + ks > 1.
        if (std::string(start) == "0.7")
            EXPECT_NEAR(highest, 1, 0.005);
        else
            EXPECT_LT(highest, 0.9);
    }
}

TEST_F(RoundTrip, TwoViewsFittedJointlyBeatEitherAlone) {
    const std::map<std::string, std::string> a = {
        {"light_x", "2"}, {"light_y", "0"}, {"light_z", "5"}};
    const std::map<std::string, std::string> b = {
        {"light_x", "-1"}, {"light_y", "2"}, {"light_z", "6"}};
    const std::string imageA = render(kLit, a, "a", 64), imageB = render(kLit, b, "b", 64);
    // Each view's defines go into its scene through a copy with the light baked in.
    auto bake = [&](const std::map<std::string, std::string>& d, const std::string& name) {
        std::ifstream in(kLit);
        std::string xml((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
        for (const auto& [k, v] : d) {
            const std::string from = "name=\"" + k + "\" value=\"";
            const auto at = xml.find(from);
            const auto end = xml.find('"', at + from.size());
            xml.replace(at + from.size(), end - at - from.size(), v);
        }
        std::ofstream(path(name)) << xml;
        return path(name);
    };
    const std::string sceneA = bake(a, "a.xml"), sceneB = bake(b, "b.xml");
    // Without a precision target every round records the same paths per view and no fit pools
    // its rounds (pooled_rounds.h): the standard errors compare what the views hold, not how many
    // rounds a fit took (a view fitted alone whose third round pooled with its second had the
    // joint fit's paths and its ks +- 0.00125 against 0.00132).
    const std::vector<std::string> start = {"--kd", "0.2", "--ks",        "0.1",
                                            "--n",  "300", "--precision", "0"};
    const auto ma = fit({sceneA + ":" + imageA}, start, "fa")["materials"]["sphere"];
    const auto mb = fit({sceneB + ":" + imageB}, start, "fb")["materials"]["sphere"];
    const auto mj =
        fit({sceneA + ":" + imageA, sceneB + ":" + imageB}, start, "fj")["materials"]["sphere"];
    EXPECT_LT(mj["n_std"].get<double>(),
              std::min(ma["n_std"].get<double>(), mb["n_std"].get<double>()));
    for (const char* key : {"kd_std", "ks_std"})
        for (int c = 0; c < 3; ++c)
            EXPECT_LT(mj[key][c].get<double>(),
                      std::min(ma[key][c].get<double>(), mb[key][c].get<double>()))
                << key << " channel " << c;
    expectRecovered(mj, 0.5, 0.3, 30, "joint");
}

}  // namespace
}  // namespace phongfit
