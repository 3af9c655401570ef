// Per-pixel albedo with a shared lobe (albedo_map_fit.h): recovery of a known albedo map and lobe
// from a synthetic textured capture (noise, clipping, attached shadows, zero normals), captures
// whose light intensities are relative, no lobe, and the real DiLiGenT captures predicting
// held-out lights better than the per-pixel Lambertian baseline.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "albedo_map_fit.h"
#include "capture.h"
#include "capture_fit.h"
#include "error.h"
#include "image.h"
#include "synthetic_capture.h"
#include "temp_dir.h"

namespace phongfit {
namespace {

using test::range;
using test::Synthetic;

// A two-tone pattern (a leaf on a glaze) with a smooth shading of each tone.
Color3 texture(int x, int y) {
    const double shade = 0.85 + 0.15 * std::sin(x / 5.0) * std::cos(y / 7.0);
    const bool leaf = (x / 6 + y / 6) % 2 == 0;
    return shade * (leaf ? Color3(0.55, 0.3, 0.2) : Color3(0.2, 0.35, 0.5));
}

// As many lights as a DiLiGenT capture.
constexpr int kLights = 96;

struct TexturedCapture {
    test::TempDir dir{"albedo_map"};
    Synthetic synthetic;
    Capture capture;
    std::vector<CaptureImage> images;

    // `intensityScale` multiplies the intensities written to light_intensities.txt (relative
    // intensities: the images then read as 1 / intensityScale times brighter).
    explicit TexturedCapture(double intensityScale = 1, Color3 ks = Color3(0.2, 0.25, 0.3)) {
        synthetic.albedo = texture;
        synthetic.truth.ks = ks;
        synthetic.lights = kLights;
        synthetic.write(dir.path());
        zeroNormals();
        if (intensityScale != 1) scaleIntensities(intensityScale);
        capture = readCapture(dir.path().string());
        images = readCaptureImages(capture, range(0, kLights - 1), {}, 2);
    }

    // Three normals in the middle of the sphere become zero, as in real data: left out, counted.
    void zeroNormals() const {
        const std::string path = (dir.path() / "normals.exr").string();
        Image normals = readImage(path);
        for (int x = 20; x < 23; ++x) normals.set(x, 20, Color<float>::Zero());
        writeExr(normals, path);
    }

    void scaleIntensities(double scale) const {
        const auto path = dir.path() / "light_intensities.txt";
        std::ifstream in(path);
        std::ostringstream scaled;
        for (double r, g, b; in >> r >> g >> b;)
            scaled << r * scale << " " << g * scale << " " << b * scale << "\n";
        in.close();
        std::ofstream(path) << scaled.str();
    }

    AlbedoMapFit fit() const {
        AlbedoMapOptions options;
        options.threads = 2;
        return fitAlbedoMap(capture, buildCaptureModel(capture, images, 0.05), options);
    }

    // RMSE of the fitted albedo map against `scale` times the texture, relative to the mean of
    // the scaled texture, over the fitted pixels and channels.
    double albedoError(const AlbedoMapFit& fit, double scale) const {
        double squares = 0, sum = 0, zSquares = 0;
        std::size_t values = 0;
        for (std::size_t i = 0; i < capture.pixels.size(); ++i) {
            if (!fit.fitted[i]) continue;
            const int x = int(capture.pixels[i] % std::uint32_t(capture.width));
            const int y = int(capture.pixels[i] / std::uint32_t(capture.width));
            const Color3 truth = scale * texture(x, y);
            squares += (fit.kd[i] - truth).square().sum();
            zSquares += ((fit.kd[i] - truth) / fit.kdStd[i]).square().sum();
            sum += truth.sum();
            values += 3;
        }
        // The errors are the images' noise, as large as the standard errors say.
        EXPECT_NEAR(std::sqrt(zSquares / double(values)), 1, 0.1);
        return std::sqrt(squares / double(values)) / (sum / double(values));
    }
};

void expectLobeRecovered(const LobeFit& fit, const PhongMaterial& truth, double scale) {
    for (int c = 0; c < 3; ++c) {
        const double ks = scale * truth.ks[c];
        EXPECT_NEAR(fit.ks[c], ks, 0.02 * ks) << "channel " << c;
        EXPECT_LT(std::abs(fit.ks[c] - ks), 3 * fit.ksStd[c])
            << "channel " << c << ": ks " << fit.ks[c] << " ± " << fit.ksStd[c] << ", truth " << ks;
    }
    EXPECT_NEAR(fit.n, truth.n, 0.05 * truth.n);
    EXPECT_LT(std::abs(fit.n - truth.n), 3 * fit.nStd) << fit.n << " ± " << fit.nStd;
    EXPECT_TRUE(fit.unconstrained.empty());
    EXPECT_FALSE(fit.nAtBound);
}

TEST(AlbedoMap, RecoversTexturedAlbedoAndSharedLobe) {
    const TexturedCapture t;
    const AlbedoMapFit fit = t.fit();
    EXPECT_EQ(t.capture.badNormals, 3u);
    EXPECT_GT(fit.pixelsFitted, 0.9 * double(t.capture.pixels.size()));
    EXPECT_LT(t.albedoError(fit, 1), 0.02);
    ASSERT_EQ(fit.lobes.size(), 1u);
    expectLobeRecovered(fit.lobes[0], t.synthetic.truth, 1);
    EXPECT_LT(fit.rmse, 0.5 * fit.lambertianRmse) << "the lobe must explain the highlights";
    EXPECT_EQ(fit.kdAboveOne, 0u);
    EXPECT_FALSE(fit.energyBoundExceeded);
    for (std::size_t i = 0; i < fit.kd.size(); ++i)
        if (fit.fitted[i]) {
            EXPECT_TRUE((fit.kdStd[i] > 0).all() && fit.kdStd[i].allFinite());
        }
}

// Intensities known only up to a common factor: kd and ks come out in the images' units (ten
// times the truth here, beyond any energy bound), n unchanged.
TEST(AlbedoMap, RelativeIntensitiesGiveScaledReflectancesAndTheSameExponent) {
    const TexturedCapture t(0.1);
    const AlbedoMapFit fit = t.fit();
    EXPECT_LT(t.albedoError(fit, 10), 0.02);
    expectLobeRecovered(fit.lobes[0], t.synthetic.truth, 10);
    EXPECT_GT(fit.kdAboveOne, 0u) << "kd + ks > 1 is counted, not refused";
    EXPECT_TRUE(fit.energyBoundExceeded);
}

// Pixels near the rim see fewer lights above --min-cos than those facing the camera: with the
// median count as the least, about half are left out, each counted.
TEST(AlbedoMap, PixelsWithTooFewPairsAreLeftOutAndCounted) {
    const TexturedCapture t;
    const CaptureModel model = buildCaptureModel(t.capture, t.images, 0.05);
    std::vector<int> pairs(t.capture.pixels.size(), 0);
    for (const auto& entries : model.entries)
        for (std::uint32_t p : entries) ++pairs[p];
    std::vector<int> sorted = pairs;
    std::nth_element(sorted.begin(), sorted.begin() + std::ptrdiff_t(sorted.size() / 2),
                     sorted.end());
    AlbedoMapOptions options;
    options.threads = 2;
    options.minPairs = sorted[sorted.size() / 2];
    const AlbedoMapFit fit = fitAlbedoMap(t.capture, model, options);
    const auto tooFew = std::size_t(std::count_if(
        pairs.begin(), pairs.end(), [&](int count) { return count < options.minPairs; }));
    EXPECT_GT(tooFew, 0u);
    EXPECT_EQ(fit.pixelsTooFewPairs, tooFew);
    EXPECT_EQ(fit.pixelsFitted + fit.pixelsTooFewPairs, t.capture.pixels.size());
    for (std::size_t i = 0; i < fit.fitted.size(); ++i) {
        EXPECT_EQ(fit.fitted[i] != 0, pairs[i] >= options.minPairs);
        if (!fit.fitted[i]) {
            EXPECT_TRUE((fit.kd[i] == 0).all());
        }
    }
    options.minPairs = kLights + 1;
    EXPECT_THROW(fitAlbedoMap(t.capture, model, options), Error);
}

TEST(AlbedoMap, NoLobeLeavesTheExponentUnconstrained) {
    const TexturedCapture t(1, Color3::Zero());
    const AlbedoMapFit fit = t.fit();
    EXPECT_LT(t.albedoError(fit, 1), 0.02);
    const LobeFit& lobe = fit.lobes[0];
    EXPECT_EQ(lobe.unconstrained, std::vector<std::string>{"n"});
    EXPECT_FALSE(fit.converged());
    for (int c = 0; c < 3; ++c) EXPECT_LT(lobe.ks[c], 3 * lobe.ksStd[c] + 1e-12);
}

// Two materials, each with its own lobe (a bright matte-ish leaf, a dark sharp-lobed glaze): with
// --materials 2 the clustering finds them (numbered by brightness) and each lobe is recovered as
// one material alone would be; one shared lobe explains the images worse.
TEST(AlbedoMap, TwoMaterialsAreFoundAndEachLobeRecovered) {
    const auto leafAt = [](int x, int y) { return (x / 8 + y / 8) % 2 == 0; };
    PhongMaterial leaf, glaze;
    leaf.ks = Color3::Constant(0.15), leaf.n = 200;
    glaze.ks = Color3::Constant(0.3), glaze.n = 30;
    const auto materialAt = [&](int x, int y) {
        const double shade = 0.9 + 0.1 * std::sin(x / 5.0) * std::cos(y / 7.0);
        PhongMaterial m = leafAt(x, y) ? leaf : glaze;
        m.kd = shade * (leafAt(x, y) ? Color3(0.6, 0.35, 0.25) : Color3(0.15, 0.3, 0.45));
        return m;
    };
    const test::TempDir dir("albedo_materials");
    Synthetic synthetic;
    synthetic.lights = kLights;
    synthetic.materialAt = materialAt;
    synthetic.write(dir.path());
    const Capture capture = readCapture(dir.path().string());
    const CaptureModel model =
        buildCaptureModel(capture, readCaptureImages(capture, range(0, kLights - 1), {}, 2), 0.05);
    AlbedoMapOptions options;
    options.threads = 2;
    options.materials = 2;
    const AlbedoMapFit fit = fitAlbedoMap(capture, model, options);
    ASSERT_EQ(fit.lobes.size(), 2u);
    std::size_t right = 0;
    for (std::size_t i = 0; i < capture.pixels.size(); ++i) {
        const int x = int(capture.pixels[i] % std::uint32_t(capture.width));
        const int y = int(capture.pixels[i] / std::uint32_t(capture.width));
        right += fit.material[i] == (leafAt(x, y) ? 1 : 0);  // the glaze is darker: material 1
    }
    EXPECT_GT(double(right), 0.98 * double(capture.pixels.size()));
    expectLobeRecovered(fit.lobes[0], glaze, 1);
    expectLobeRecovered(fit.lobes[1], leaf, 1);

    options.materials = 1;
    EXPECT_GT(fitAlbedoMap(capture, model, options).rmse, 1.5 * fit.rmse);
    options.materials = kMaxMaterials + 1;
    EXPECT_THROW(fitAlbedoMap(capture, model, options), Error);
}

// Odd lights fitted, even lights predicted: the shared lobe must beat the per-pixel Lambertian
// baseline on both real captures, overall and on most lights. The exponent fitted from the even
// lights agrees with the odd lights' within the standard errors (which must include how each
// light misfits: the model-only ones put the two 60 standard errors apart on pot2).
void expectPhongPredictsBetter(const std::string& dir, const ReadOptions& decoding) {
    CaptureReadOptions read;
    read.decoding = decoding;
    const Capture capture = readCapture(dir, read);
    AlbedoMapOptions options;
    options.threads = 2;
    const std::vector<CaptureImage> odd = readCaptureImages(capture, range(0, 94, 2), read, 2);
    const std::vector<CaptureImage> even = readCaptureImages(capture, range(1, 95, 2), read, 2);
    const AlbedoMapCaptureFit fit = fitCaptureAlbedoMap(capture, odd, even, 0.05, options);
    ASSERT_TRUE(fit.holdout);
    const HoldoutPrediction& h = *fit.holdout;
    EXPECT_EQ(h.perLight.size(), 48u);
    EXPECT_LT(h.phong.relRmse, 0.8 * h.lambertian.relRmse);
    std::size_t better = 0;
    for (const LightPrediction& l : h.perLight) better += l.phong.rmse < l.lambertian.rmse;
    EXPECT_GE(better, 40u);
    const LobeFit& a = fit.fit.lobes[0];
    EXPECT_TRUE(a.unconstrained.empty());
    ASSERT_TRUE(std::isfinite(a.nStd));

    const LobeFit b = fitCaptureAlbedoMap(capture, even, {}, 0.05, options).fit.lobes[0];
    EXPECT_LT(std::abs(a.n - b.n), 2 * std::hypot(a.nStd, b.nStd))
        << "n = " << a.n << " ± " << a.nStd << " (odd lights) vs " << b.n << " ± " << b.nStd
        << " (even lights)";
}

TEST(AlbedoMap, DiligentBallPredictsHeldOutLightsBetterThanPerPixelLambertian) {
    expectPhongPredictsBetter(PHONGFIT_BALL_DIR, {});
}

TEST(AlbedoMap, DiligentPot2PredictsHeldOutLightsBetterThanPerPixelLambertian) {
    ReadOptions linear;
    linear.encoding = Encoding::Linear;
    expectPhongPredictsBetter(PHONGFIT_POT2_DIR, linear);
}

}  // namespace
}  // namespace phongfit
