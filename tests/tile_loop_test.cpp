// Rendering and path recording run one tile loop (renderer/tile_loop.h), so they share its
// policies: a recording with no fitted material is the render (same random numbers, same sampler,
// same non-finite samples left out), and a recording polls the interrupt flag as a render does.
#include "tile_loop.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "chi_square.h"
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

// A sample's film position is drawn from the pixel's filter (importance-sampled, weight 1): its
// offset from the pixel's centre, binned over the plane, against the filter's closed-form CDF along
// each axis (the box's uniform one, the Gaussian's erf, the tent's two parabolas), the two axes
// independent. Tungsten's default filter is the tent of radius 1, Mitsuba 0.6's the Gaussian of
// stddev 0.5.
TEST(TileLoop, FilmPositionsFollowThePixelFilter) {
    struct Case {
        const char* name;
        SensorDesc::Filter filter;
        double width;  // stddev or radius
        std::function<double(double)> cdf;
        double reach;  // the bins span [-reach, reach], the outer ones open
    };
    const auto tent = [](double r) {
        return [r](double x) {
            x = std::clamp(x, -r, r);
            return x < 0 ? (x + r) * (x + r) / (2 * r * r) : 1 - (r - x) * (r - x) / (2 * r * r);
        };
    };
    const std::vector<Case> cases = {
        {"box", SensorDesc::Filter::Box, 0, [](double x) { return std::clamp(x + 0.5, 0.0, 1.0); },
         0.5},
        {"gaussian", SensorDesc::Filter::Gaussian, 0.5,
         [](double x) { return 0.5 * std::erfc(-x / (0.5 * std::sqrt(2.0))); }, 1.5},
        {"tent", SensorDesc::Filter::Tent, 1, tent(1), 1},
        {"tent 1.5", SensorDesc::Filter::Tent, 1.5, tent(1.5), 1.5},
    };
    constexpr int kBins = 12, kSamples = 200000;
    for (const Case& c : cases) {
        SensorDesc film;
        film.filter = c.filter;
        film.filterWidth = c.width;
        std::vector<double> edges = {-std::numeric_limits<double>::infinity()};
        for (int k = 1; k < kBins; ++k) edges.push_back(c.reach * (2.0 * k / kBins - 1));
        edges.push_back(std::numeric_limits<double>::infinity());
        const auto bin = [&](double d) {
            return int(std::upper_bound(edges.begin() + 1, edges.end() - 1, d) - edges.begin()) - 1;
        };
        std::vector<double> observed(kBins * kBins, 0), expected(kBins * kBins);
        std::mt19937_64 rng(17);
        std::uniform_real_distribution<double> uniform(0, 1);
        for (int s = 0; s < kSamples; ++s) {
            const Vec2d at = filmPosition(film, 7, 3, uniform(rng), uniform(rng));
            ++observed[bin(at.x() - 7.5) * kBins + bin(at.y() - 3.5)];
        }
        for (int i = 0; i < kBins; ++i)
            for (int j = 0; j < kBins; ++j)
                expected[i * kBins + j] = kSamples * (c.cdf(edges[i + 1]) - c.cdf(edges[i])) *
                                          (c.cdf(edges[j + 1]) - c.cdf(edges[j]));
        const ChiSquareResult r = chiSquareTest(observed, expected);
        EXPECT_GT(r.pValue, sidakSignificance(1e-3, int(cases.size())))
            << c.name << ": chi-square " << r.statistic << " on " << r.dof << " degrees of freedom";
    }
}

}  // namespace
}  // namespace phongfit
