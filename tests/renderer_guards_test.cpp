// The renderer's guards: a non-finite sample is dropped, counted and traced back to its pixel,
// path depth and material (in RenderStats and the render sidecar), and a path recording that would
// not fit in memory is refused up front, naming the flag that lowers it.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>
#include <string>

#include "error.h"
#include "image.h"
#include "renderer.h"
#include "scene_parser.h"
#include "subprocess.h"

namespace phongfit {
namespace {

namespace fs = std::filesystem;

// A sphere ("hot", in the right half of the image) lit by a point light just above it, so strong by
// default that its irradiance overflows to infinity.
std::string overflowingScene(int size) {
    return R"(<scene version="0.6.0">
    <default name="intensity" value="1e308"/>
    <integrator type="direct"/>
    <sensor type="perspective">
        <float name="fov" value="50"/>
        <transform name="toWorld">
            <lookat origin="0, 0, 5" target="0, 0, 0" up="0, 1, 0"/>
        </transform>
        <sampler type="independent"><integer name="sampleCount" value="2"/></sampler>
        <film type="hdrfilm">
            <integer name="width" value=")" +
           std::to_string(size) + R"("/>
            <integer name="height" value=")" +
           std::to_string(size) + R"("/>
        </film>
    </sensor>
    <bsdf type="phong" id="hot"/>
    <shape type="sphere">
        <point name="center" x="1" y="0" z="0"/>
        <float name="radius" value="0.5"/>
        <ref id="hot"/>
    </shape>
    <emitter type="point">
        <point name="position" x="1" y="0" z="0.7"/>
        <spectrum name="intensity" value="$intensity"/>
    </emitter>
</scene>
)";
}

RenderResult renderWithThreads(const Renderer& renderer, int threads) {
    RenderOptions options;
    options.threads = threads;
    options.quiet = true;
    return renderer.render(options);
}

TEST(RendererGuards, NonFiniteSamplesAreDroppedAndTracedToPixelDepthAndMaterial) {
    const Renderer renderer(parseScene(overflowingScene(24), "overflow.xml"));
    const int hot = renderer.scene().findBsdf("hot");
    const RenderResult r = renderWithThreads(renderer, 2);
    for (const float v : r.rgb) ASSERT_TRUE(std::isfinite(v));
    ASSERT_GT(r.stats.nonFinite, 0u);
    ASSERT_EQ(r.stats.nonFiniteFirst.size(), std::min<std::size_t>(r.stats.nonFinite, 10));
    for (std::size_t i = 0; i < r.stats.nonFiniteFirst.size(); ++i) {
        const NonFiniteSample& n = r.stats.nonFiniteFirst[i];
        EXPECT_EQ(n.depth, 1) << "the light's overflow is in the direct light of the first hit";
        EXPECT_EQ(n.bsdf, hot);
        EXPECT_GE(n.x, r.width / 2) << "the hot sphere is in the right half";
        EXPECT_LT(r.sampleCount[std::size_t(n.y) * r.width + n.x], 2u)
            << "the sample was left out of its pixel";
        if (i > 0) {
            const NonFiniteSample& m = r.stats.nonFiniteFirst[i - 1];
            EXPECT_LT(std::tie(m.y, m.x, m.sample), std::tie(n.y, n.x, n.sample))
                << "the first ones in pixel order";
        }
    }
    const RenderResult single = renderWithThreads(renderer, 1);
    ASSERT_EQ(single.stats.nonFiniteFirst.size(), r.stats.nonFiniteFirst.size());
    for (std::size_t i = 0; i < r.stats.nonFiniteFirst.size(); ++i) {
        const NonFiniteSample &a = single.stats.nonFiniteFirst[i], &b = r.stats.nonFiniteFirst[i];
        EXPECT_EQ(std::tie(a.x, a.y, a.sample, a.depth, a.bsdf),
                  std::tie(b.x, b.y, b.sample, b.depth, b.bsdf))
            << "whatever the thread count";
    }
}

TEST(RendererGuards, RenderSidecarSaysWhereNonFiniteSamplesCameFrom) {
    const fs::path dir =
        fs::temp_directory_path() / ("phongfit_guards_" + std::to_string(getpid()) + "_" +
                                     std::to_string(std::random_device{}()));
    fs::create_directories(dir);
    std::ofstream(dir / "s.xml") << overflowingScene(16);
    const auto r = test::runPhongfit(
        {"render", (dir / "s.xml").string(), "-o", (dir / "out.exr").string(), "--quiet"});
    ASSERT_EQ(r.exitCode, 0) << r.err;
    EXPECT_NE(r.out.find("material 'hot'"), std::string::npos) << r.out;
    const auto sidecar = nlohmann::json::parse(std::ifstream(dir / "out.exr.json"));
    ASSERT_GT(sidecar["non_finite_samples"].get<int>(), 0);
    const auto& first = sidecar["non_finite_first"];
    ASSERT_GE(first.size(), 1u);
    EXPECT_EQ(first[0]["material"], "hot");
    EXPECT_EQ(first[0]["depth"], 1);
    EXPECT_EQ(first[0]["pixel"].size(), 2u);
    EXPECT_TRUE(first[0]["sample"].is_number_integer());
    const Image image = readImage((dir / "out.exr").string());
    for (const float v : image.rgb) EXPECT_TRUE(std::isfinite(v));
    fs::remove_all(dir);
}

// A recording leaves out the same samples: with no fitted material it is the render, counts and
// diagnosis included, and each pixel is the mean of the samples it kept.
TEST(RendererGuards, RecordingLeavesOutTheNonFiniteSamplesARenderDoes) {
    const Renderer renderer(parseScene(overflowingScene(24), "overflow.xml"));
    const RenderResult image = renderWithThreads(renderer, 2);
    RecordOptions options;
    options.spp = 2;
    options.threads = 2;
    const RecordResult recorded = renderer.record(options);
    const RenderStats& s = recorded.stats;
    ASSERT_GT(s.nonFinite, 0u);
    EXPECT_EQ(s.nonFinite, image.stats.nonFinite);
    EXPECT_EQ(s.samples, image.stats.samples);
    ASSERT_EQ(s.nonFiniteFirst.size(), image.stats.nonFiniteFirst.size());
    for (std::size_t i = 0; i < s.nonFiniteFirst.size(); ++i) {
        const NonFiniteSample &a = s.nonFiniteFirst[i], &b = image.stats.nonFiniteFirst[i];
        EXPECT_EQ(std::tie(a.x, a.y, a.sample, a.depth, a.bsdf),
                  std::tie(b.x, b.y, b.sample, b.depth, b.bsdf));
    }
    for (std::size_t p = 0; p < recorded.paths.background.size(); ++p)
        for (int c = 0; c < 3; ++c)
            EXPECT_FLOAT_EQ(recorded.paths.background[p][c], image.rgb[3 * p + c]) << p;
}

TEST(RendererGuards, RecordingOfAFittedMaterialCountsAndTracesNonFiniteSamples) {
    const Renderer renderer(parseScene(overflowingScene(24), "overflow.xml"));
    const int hot = renderer.scene().findBsdf("hot");
    RecordOptions options;
    options.spp = 2;
    options.fittedBsdfs = {hot};
    options.theta0 = {renderer.scene().bsdfs[hot].params};
    const RecordResult recorded = renderer.record(options);
    const RenderStats& s = recorded.stats;
    ASSERT_GT(s.nonFinite, 0u);
    EXPECT_EQ(s.samples + s.nonFinite, 2u * 24 * 24) << "every sample kept or counted";
    ASSERT_EQ(s.nonFiniteFirst.size(), std::min<std::size_t>(s.nonFinite, 10));
    for (const NonFiniteSample& n : s.nonFiniteFirst) {
        EXPECT_EQ(n.depth, 1);
        EXPECT_EQ(n.bsdf, hot);
        EXPECT_GE(n.x, 12) << "the hot sphere is in the right half";
    }
    for (const PathTerm& t : recorded.paths.terms) EXPECT_TRUE(t.constant.allFinite());
    for (const Color<float>& b : recorded.paths.background) EXPECT_TRUE(b.allFinite());
}

// The overflowing scene with a moderate light: a recording of the sphere's paths.
RecordOptions recordHot(const Renderer& renderer, int spp) {
    RecordOptions options;
    options.spp = spp;
    options.fittedBsdfs = {renderer.scene().findBsdf("hot")};
    options.theta0 = {renderer.scene().bsdfs[options.fittedBsdfs[0]].params};
    return options;
}

TEST(RendererGuards, RecordingThatWouldExhaustMemoryIsRefusedNamingTheFlag) {
    const Renderer renderer(parseScene(overflowingScene(2000), "big.xml", {{"intensity", "1"}}));
    const RecordOptions options = recordHot(renderer, 1 << 20);
    try {
        renderer.record(options);
        FAIL() << "a recording of terabytes was attempted";
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find("lower --spp"), std::string::npos) << e.what();
        EXPECT_NE(std::string(e.what()).find("2000x2000"), std::string::npos) << e.what();
    }
}

TEST(RendererGuards, RecordingThatFitsIsNotRefused) {
    const Renderer renderer(parseScene(overflowingScene(16), "small.xml", {{"intensity", "1"}}));
    const PathSet paths = renderer.record(recordHot(renderer, 4)).paths;
    EXPECT_EQ(paths.width, 16);
    EXPECT_GT(paths.terms.size(), 0u);
}

}  // namespace
}  // namespace phongfit
