// Rendering and path recording run one tile loop (renderer/tile_loop.h), so they share its
// policies: a recording with no fitted material is the render (same random numbers, same sampler,
// same non-finite samples left out), and a recording polls the interrupt flag as a render does.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>

#include "interrupt.h"
#include "renderer.h"
#include "scene_parser.h"

namespace phongfit {
namespace {

const std::string kCornell = std::string(PHONGFIT_SCENES_DIR) + "/cornell_phong.xml";
constexpr int kSize = 20;  // not a multiple of the 16-pixel tile

Renderer cornell() {
    return Renderer(
        loadScene(kCornell, {{"width", std::to_string(kSize)}, {"height", std::to_string(kSize)}}));
}

// The scene names `sobol`, which recordings take as padded points (docs/design/sampling.md): the
// render to compare with is the padded one.
RenderResult render(const Renderer& renderer, const std::string& sampler) {
    RenderOptions options;
    options.spp = 4;
    options.seed = 9;
    options.sampler = sampler;
    options.pixelSampler = PixelSamplerType::Padded;
    options.quiet = true;
    return renderer.render(options);
}

// All paths fold into the background: the recording's image.
RecordResult recordUnfitted(const Renderer& renderer, const std::string& sampler) {
    RecordOptions options;
    options.spp = 4;
    options.seed = 9;
    options.sampler = sampler;
    return renderer.record(options);
}

// The largest relative difference between a render and an unfitted recording of it; both are the
// mean of the same samples, summed in a different order.
double largestDifference(const RenderResult& image, const PathSet& paths) {
    EXPECT_TRUE(paths.terms.empty());
    double largest = 0;
    for (std::size_t p = 0; p < paths.background.size(); ++p)
        for (int c = 0; c < 3; ++c) {
            const double a = image.rgb[3 * p + c], b = paths.background[p][c];
            largest = std::max(largest, std::abs(a - b) / std::max(1e-3, std::abs(a)));
        }
    return largest;
}

TEST(TileLoop, RecordingWithNoFittedMaterialIsTheRender) {
    const Renderer renderer = cornell();
    const RecordResult recorded = recordUnfitted(renderer, "lafortune");
    const RenderResult image = render(renderer, "lafortune");
    EXPECT_LT(largestDifference(image, recorded.paths), 1e-5);
    EXPECT_EQ(recorded.stats.samples, image.stats.samples);
    EXPECT_EQ(recorded.stats.rays, image.stats.rays);
    EXPECT_FALSE(recorded.stats.interrupted);
}

TEST(TileLoop, RecordingSamplesUnfittedMaterialsWithItsSampler) {
    const Renderer renderer = cornell();
    EXPECT_EQ(RecordOptions().sampler, "mixture");
    EXPECT_EQ(RenderOptions().sampler, "mixture");
    const RecordResult cosine = recordUnfitted(renderer, "cosine");
    EXPECT_LT(largestDifference(render(renderer, "cosine"), cosine.paths), 1e-5);
    EXPECT_GT(largestDifference(render(renderer, "lafortune"), cosine.paths), 0.1)
        << "the cosine sampler gave the lafortune sampler's image";
    EXPECT_ANY_THROW(recordUnfitted(renderer, "no such sampler"));
}

// Sets the interrupt flag for a scope, as a signal would.
struct Interrupt {
    Interrupt() { setInterruptRequested(true); }
    ~Interrupt() { setInterruptRequested(false); }
};

TEST(TileLoop, InterruptedRecordingHoldsTheFirstPassAndSaysSo) {
    const Renderer renderer = cornell();
    RecordOptions options;
    options.spp = 8;
    options.seed = 4;
    options.fittedBsdfs = {renderer.scene().findBsdf("sphere")};
    options.theta0 = {renderer.scene().bsdfs[options.fittedBsdfs[0]].params};
    RecordResult interrupted;
    {
        const Interrupt interrupt;
        interrupted = renderer.record(options);
    }
    EXPECT_TRUE(interrupted.stats.interrupted);
    EXPECT_EQ(interrupted.stats.samples, std::uint64_t(kSize * kSize))
        << "the first pass, one path per pixel, always completes; no later one starts";
    EXPECT_EQ(interrupted.stats.spp, 8);

    // Each pixel is the mean of the one path it got: a recording of one path per pixel.
    options.spp = 1;
    const RecordResult one = renderer.record(options);
    EXPECT_FALSE(one.stats.interrupted);
    const PathSet &a = interrupted.paths, &b = one.paths;
    ASSERT_EQ(a.pixelStart, b.pixelStart);
    ASSERT_EQ(a.vertices.size(), b.vertices.size());
    for (std::size_t p = 0; p < a.background.size(); ++p)
        for (int c = 0; c < 3; ++c) EXPECT_FLOAT_EQ(a.background[p][c], b.background[p][c]);
    for (std::size_t t = 0; t < a.terms.size(); ++t) {
        EXPECT_EQ(a.terms[t].firstVertex, b.terms[t].firstVertex);
        for (int c = 0; c < 3; ++c) EXPECT_FLOAT_EQ(a.terms[t].constant[c], b.terms[t].constant[c]);
    }
}

}  // namespace
}  // namespace phongfit
