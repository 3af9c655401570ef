// kappa, the image's noise in units of one path's variance (image_noise.h), read from simulated
// pixels whose image and recordings' noise are known: normal draws with variance kappa v for the
// image and v / N for each recording of N paths.
#include "image_noise.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

namespace phongfit {
namespace {

// `count` pixels, one channel each, of path variances spread over two decades; each recording's
// noise `recordingFactor` times what N paths of that variance give.
std::vector<PixelNoise> simulatedPixels(double kappa, int paths, double recordingFactor, int count,
                                        unsigned seed) {
    std::mt19937_64 rng(seed);
    std::normal_distribution<double> normal;
    std::uniform_real_distribution<double> decades(0, 2);
    std::vector<PixelNoise> pixels;
    for (int i = 0; i < count; ++i) {
        const double v = std::pow(10.0, decades(rng));
        const double image = std::sqrt(kappa * v) * normal(rng);
        const double recording = std::sqrt(recordingFactor * v / paths);
        const double a = image + recording * normal(rng), b = image + recording * normal(rng);
        pixels.push_back({a * b, 0.25 * (a - b) * (a - b), v});
    }
    return pixels;
}

// The median of r_A . r_B / v alone (the reading kappa had before the split): `pixels` with
// recordings said 10^4 times noisier in variance, so that the split is not used.
double productReading(std::vector<PixelNoise> pixels) {
    for (PixelNoise& p : pixels) p.halfDifference *= 1e4;
    return noiseScale(pixels);
}

TEST(ImageNoise, ReadsTheImagesNoiseWhereTheRecordingsAreAsNoisy) {
    // An image of 256 independent samples a pixel, recordings of 64 and 256 paths: the product's
    // median reads low (about half), the split of the residuals about right (its lower
    // 2-standard-error end, about 6% below the truth over 100000 pixels at 64 paths).
    for (const int paths : {64, 256}) {
        const std::vector<PixelNoise> pixels = simulatedPixels(1.0 / 256, paths, 1, 100000, 7);
        const double kappa = noiseScale(pixels);
        EXPECT_NEAR(kappa, 1.0 / 256, 0.15 / 256) << paths << " paths";
        EXPECT_LT(productReading(pixels), 0.8 / 256) << paths << " paths";
    }
}

TEST(ImageNoise, ANoiseFreeImageReadsNoNoise) {
    const double kappa = noiseScale(simulatedPixels(0, 64, 1, 20000, 11));
    EXPECT_GE(kappa, 0);
    EXPECT_LT(kappa, 0.05 / 256);
}

TEST(ImageNoise, RecordingsNoisierThanTheirPathsKeepTheProductsReading) {
    // Recordings 20x noisier than their paths' variance says (light no recorded term carries, as
    // in the Cornell box): the split is not trusted, and kappa is the product's median.
    const std::vector<PixelNoise> pixels = simulatedPixels(1.0 / 256, 4, 20, 20000, 13);
    EXPECT_DOUBLE_EQ(noiseScale(pixels), productReading(pixels));
}

TEST(ImageNoise, NoPixelsNoNoise) { EXPECT_EQ(noiseScale({}), 0); }

// The image's noise and the recordings' are independent, and their variances add. The round's
// sandwich read part of the image's off its residuals (the counted part): only the rest is added.
TEST(ImageNoise, TheImagesNoiseBeyondWhatTheRoundCountedAddsInQuadrature) {
    MaterialFit fit;
    fit.kd = fit.ks = Color3::Constant(0.4);
    fit.kdStd = fit.ksStd = Color3::Constant(0.003);
    fit.kdImageStd = Color3(0.004, 0.001, 0.004);
    fit.kdCountedImageStd = Color3(0, 0, 0.002);
    fit.ksImageStd = Color3::Constant(0.002);
    fit.ksCountedImageStd = Color3::Constant(0.005);
    fit.n = 100;
    fit.logNStd = 0.1;
    fit.nStd = 10;
    fit.logNImageStd = 0.2;
    fit.logNCountedImageStd = 0.1;
    applyImageNoise(fit);
    EXPECT_DOUBLE_EQ(fit.kdStd[0], std::sqrt(9e-6 + 16e-6));
    EXPECT_DOUBLE_EQ(fit.kdStd[1], std::sqrt(9e-6 + 1e-6));
    EXPECT_DOUBLE_EQ(fit.kdStd[2], std::sqrt(9e-6 + 16e-6 - 4e-6));
    // All of the image's noise counted already: nothing added.
    for (int c = 0; c < 3; ++c) EXPECT_EQ(fit.ksStd[c], 0.003) << c;
    EXPECT_DOUBLE_EQ(fit.logNStd, std::sqrt(0.01 + 0.04 - 0.01));
    EXPECT_DOUBLE_EQ(fit.nStd, 100 * fit.logNStd);
}

}  // namespace
}  // namespace phongfit
