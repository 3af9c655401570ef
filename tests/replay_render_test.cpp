// Replay is unbiased: paths recorded at theta0 and replayed at theta1 give, within statistical
// error, the image rendered directly at theta1, on the path-traced Cornell box (interreflections,
// an area light, MIS), also when the pixels that see the fitted sphere get more paths
// (RecordOptions::directSpp).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "renderer.h"
#include "replay.h"
#include "scene_parser.h"

namespace phongfit {
namespace {

constexpr int kSize = 32, kRecordings = 16;

const PhongMaterial kTheta1 = [] {
    PhongMaterial m;
    m.kd = Color3(0.3, 0.25, 0.2);
    m.ks = Color3(0.35, 0.4, 0.45);
    m.n = 60;
    return m;
}();

Scene cornell(const PhongMaterial* sphere = nullptr) {
    Scene scene = loadScene(PHONGFIT_SCENES_DIR "/cornell_phong.xml",
                            {{"width", std::to_string(kSize)}, {"height", std::to_string(kSize)}});
    if (sphere) scene.bsdfs[scene.findBsdf("sphere")].params = *sphere;
    return scene;
}

// Per-pixel statistics are heavy-tailed here (caustics through the glossy sphere), so the images
// are compared over aggregates of many pixels, where the central limit holds: the four quadrants
// and the pixels whose centre sees the sphere, per channel.
constexpr int kAggregates = 5;

std::vector<int> aggregatesOf(int pixel, const std::vector<bool>& sphere) {
    const int x = pixel % kSize, y = pixel / kSize;
    std::vector<int> a = {2 * (y >= kSize / 2) + (x >= kSize / 2)};
    if (sphere[std::size_t(pixel)]) a.push_back(4);
    return a;
}

struct Aggregates {
    std::vector<double> mean = std::vector<double>(3 * kAggregates, 0.0);
    std::vector<double> variance = std::vector<double>(3 * kAggregates, 0.0);  // of the mean
    std::vector<double> count = std::vector<double>(kAggregates, 0.0);
};

// The pixels whose centre sees the sphere, from a recording with 1 path per pixel elsewhere and
// 64 there: one path of the others leaves far fewer than 16 terms.
std::vector<bool> spherePixels(const PathSet& probe) {
    std::vector<bool> sphere(std::size_t(kSize) * kSize);
    for (std::size_t p = 0; p < sphere.size(); ++p)
        sphere[p] = probe.pixelStart[p + 1] - probe.pixelStart[p] > 16;
    return sphere;
}

Aggregates rendered(const Scene& scene, int spp, const std::vector<bool>& sphere) {
    RenderOptions options;
    options.spp = spp;
    options.seed = 99;
    options.quiet = true;
    const RenderResult r = Renderer(scene).render(options);
    Aggregates s;
    for (int p = 0; p < kSize * kSize; ++p)
        for (int a : aggregatesOf(p, sphere)) {
            s.count[a] += 1;
            for (int c = 0; c < 3; ++c) {
                s.mean[3 * a + c] += r.rgb[3 * p + c];
                s.variance[3 * a + c] += r.variance[3 * p + c];
            }
        }
    for (int k = 0; k < 3 * kAggregates; ++k) {
        s.mean[k] /= s.count[k / 3];
        s.variance[k] /= s.count[k / 3] * s.count[k / 3];
    }
    return s;
}

// kRecordings independent recordings at the scene's sphere, replayed at theta1: the aggregates'
// mean over the recordings, with its variance from their spread.
Aggregates replayed(const Scene& scene, const PhongMaterial& theta1, int spp, int directSpp,
                    const std::vector<bool>& sphere, std::size_t& terms, bool lightRings = true,
                    int extraPaths = 0, std::size_t* weightedPixels = nullptr) {
    const Renderer renderer(scene);
    const int bsdf = scene.findBsdf("sphere");
    const PhongParams<double> theta{theta1.kd, theta1.ks, theta1.n};
    std::vector<std::vector<double>> values;  // per recording, per aggregate and channel
    terms = 0;
    for (int k = 0; k < kRecordings; ++k) {
        RecordOptions options;
        options.spp = spp;
        options.directSpp = directSpp;
        options.lightRings = lightRings;
        if (extraPaths > 0) options.extraPaths.assign(std::size_t(kSize) * kSize, extraPaths);
        options.seed = 1000 + std::uint64_t(k);
        options.fittedBsdfs = {bsdf};
        options.theta0 = {scene.bsdfs[bsdf].params};
        const PathSet paths = renderer.record(options).paths;
        terms += paths.terms.size();
        if (weightedPixels != nullptr)
            *weightedPixels += std::size_t(std::count_if(
                paths.groups.begin(), paths.groups.end(),
                [](const PathGroups& g) { return g.ringedScale != 1 || g.sampledScale != 1; }));
        std::vector<double> v(3 * kAggregates, 0.0), count(kAggregates, 0.0);
        for (int p = 0; p < kSize * kSize; ++p) {
            const Color3 value = replayPixel(paths, std::size_t(p), &theta);
            for (int a : aggregatesOf(p, sphere)) {
                count[a] += 1;
                for (int c = 0; c < 3; ++c) v[3 * a + c] += value[c];
            }
        }
        for (int i = 0; i < 3 * kAggregates; ++i) v[i] /= count[i / 3];
        values.push_back(v);
    }
    Aggregates s;
    for (int i = 0; i < 3 * kAggregates; ++i) {
        for (const auto& v : values) s.mean[i] += v[i] / kRecordings;
        for (const auto& v : values)
            s.variance[i] += (v[i] - s.mean[i]) * (v[i] - s.mean[i]) / (kRecordings - 1);
        s.variance[i] /= kRecordings;
    }
    return s;
}

// The largest |difference| / sigma over aggregates and channels.
double largestDeviation(const Aggregates& a, const Aggregates& b) {
    double largest = 0;
    for (std::size_t k = 0; k < a.mean.size(); ++k) {
        const double sigma = std::sqrt(a.variance[k] + b.variance[k]);
        EXPECT_GT(sigma, 0) << "aggregate " << k / 3;
        largest = std::max(largest, std::abs(a.mean[k] - b.mean[k]) / sigma);
    }
    return largest;
}

// The replayed variances come from 16 recordings (Student's t, 15 degrees of freedom): 1% false
// alarms over the 15 comparisons, Sidak-corrected, is |t| < 4.27 (t_15 two-sided at 6.7e-4).
constexpr double kThreshold = 4.27;

TEST(ReplayAgainstRender, RecordedAtTheta0ReplayedAtTheta1MatchesTheRenderAtTheta1) {
    const Scene scene0 = cornell();  // the sphere at kd 0.5, ks 0.2, n 30
    std::size_t uniform = 0, focused = 0;
    RecordOptions probe;
    probe.spp = 1;
    probe.directSpp = 64;
    probe.lightRings = false;  // rings would give every pixel that sees the sphere far more terms
    probe.fittedBsdfs = {scene0.findBsdf("sphere")};
    probe.theta0 = {scene0.bsdfs[probe.fittedBsdfs[0]].params};
    const std::vector<bool> sphere = spherePixels(Renderer(scene0).record(probe).paths);
    ASSERT_GT(std::count(sphere.begin(), sphere.end(), true), 20);

    const Aggregates truth = rendered(cornell(&kTheta1), 1024, sphere);
    const Aggregates even = replayed(scene0, kTheta1, 64, 0, sphere, uniform);
    EXPECT_LT(largestDeviation(even, truth), kThreshold);
    // More paths where the sphere is seen directly: still the same expected image.
    const Aggregates more = replayed(scene0, kTheta1, 16, 256, sphere, focused);
    EXPECT_LT(largestDeviation(more, truth), kThreshold);
    // Without directSpp the second recording would hold a quarter of the first's terms.
    EXPECT_GT(focused, uniform / 4 + uniform / 8) << "the sphere's pixels got 16x the paths";
    // The test can tell: replaying at theta0 instead of theta1 is refused.
    const Aggregates stale =
        replayed(scene0, scene0.bsdfs[probe.fittedBsdfs[0]].params, 64, 0, sphere, uniform);
    EXPECT_GT(largestDeviation(stale, truth), 2 * kThreshold);
}

// Direct light integrated by rings about the mirror direction (light_rings.h) where a card hides
// part of the light across the highlight: the rings' visibility rays keep the replay unbiased.
TEST(ReplayAgainstRender, RingsUnderAPartlyHiddenLightMatchTheRender) {
    const auto blocked = [](const PhongMaterial* m) {
        Scene s = loadScene(PHONGFIT_TEST_SCENES_DIR "/sphere_quad_blocked.xml", {});
        if (m) s.bsdfs[s.findBsdf("sphere")].params = *m;
        return s;
    };
    const Scene scene0 = blocked(nullptr);  // n 300; the image is all sphere
    const std::vector<bool> sphere(std::size_t(kSize) * kSize, true);
    PhongMaterial theta1 = kTheta1;
    theta1.n = 1000;
    const Aggregates truth = rendered(blocked(&theta1), 4096, sphere);
    std::size_t rings = 0, sampled = 0;
    EXPECT_LT(largestDeviation(replayed(scene0, theta1, 16, 0, sphere, rings), truth), kThreshold);
    EXPECT_LT(largestDeviation(replayed(scene0, theta1, 16, 0, sphere, sampled, false), truth),
              kThreshold);
    EXPECT_GT(rings, 3 * sampled) << "the pixels near the highlight were integrated by rings";
    // 4 ringed paths a pixel and 28 sampled ones (a round that grows the paths), each kind's mean
    // weighted by the inverse of its variance (PathGroups): still the render's expected image.
    std::size_t mixed = 0, weighted = 0;
    EXPECT_LT(
        largestDeviation(replayed(scene0, theta1, 4, 0, sphere, mixed, true, 28, &weighted), truth),
        kThreshold);
    EXPECT_GT(weighted, std::size_t(kRecordings) * kSize * kSize / 2)
        << "most pixels weight their ringed and sampled paths";
    // The card matters: without it the image is brighter than the test can miss.
    Scene open = blocked(&theta1);
    open.shapes.erase(open.shapes.begin() + 1);
    EXPECT_GT(largestDeviation(rendered(open, 4096, sphere), truth), 4 * kThreshold);
}

}  // namespace
}  // namespace phongfit
