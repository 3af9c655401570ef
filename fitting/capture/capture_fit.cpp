#include "capture_fit.h"

#include <fmt/format.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <utility>

#include "error.h"
#include "grid_search.h"
#include "phong_brdf.h"
#include "replay.h"

namespace phongfit {
namespace {

// The start scan fits kd and ks on about this many pairs.
constexpr std::size_t kScanPairs = 100000;
constexpr int kScanMaxLog2N = 16;
// The golden-section search stops when log2 n is bracketed this closely.
constexpr double kScanTolerance = 0.01;
// With relative intensities the fit's energy bound lies this many times beyond the scan's kd + ks.
constexpr double kRelativeHeadroom = 4;
// kd + ks this close to 1 is on the energy bound.
constexpr double kAtEnergyBound = 1e-3;
// Below this ks the start would hide the lobe from the fitter (see startScan).
constexpr double kMinStartKs = 1e-3;

// Squared errors summed until the RMSE is taken.
struct ErrorSums {
    double squares = 0, observedSquares = 0;
    std::size_t pairs = 0;

    void add(const ErrorSums& o) {
        squares += o.squares;
        observedSquares += o.observedSquares;
        pairs += o.pairs;
    }
    PredictionError result() const {
        const double values = 3.0 * double(std::max<std::size_t>(pairs, 1));
        const double rmse = std::sqrt(squares / values);
        const double observedRms = std::sqrt(observedSquares / values);
        return {pairs, rmse, observedRms > 0 ? rmse / observedRms : 0};
    }
};

struct ScanSample {
    double cosine, logCos;
    Color3 observed;
};

// About kScanPairs pairs, evenly spread over the model's views.
std::vector<ScanSample> scanSamples(const CaptureModel& model) {
    const std::size_t stride = std::max<std::size_t>(1, model.used / kScanPairs);
    std::vector<ScanSample> samples;
    std::size_t k = 0;
    for (std::size_t v = 0; v < model.paths.size(); ++v) {
        const PathSet& ps = model.paths[v];
        for (std::size_t p = 0; p < ps.terms.size(); ++p, ++k) {
            if (k % stride != 0) continue;
            const float* rgb = &model.observations[v].rgb[3 * p];
            samples.push_back(
                {ps.terms[p].constant[0], ps.vertices[p].logCos, Color3(rgb[0], rgb[1], rgb[2])});
        }
    }
    return samples;
}

// The non-negative kd and ks per channel that fit the samples best in least squares at the
// exponent n (without n: kd alone), and the residual sum of squares.
std::pair<PhongMaterial, double> bestReflectances(const std::vector<ScanSample>& samples,
                                                  std::optional<double> n) {
    // Per channel c: observed = kd_c a + ks_c b; the normal equations over the samples.
    Eigen::Matrix2d gram = Eigen::Matrix2d::Zero();
    Eigen::Matrix<double, 2, 3> moments = Eigen::Matrix<double, 2, 3>::Zero();
    Color3 observedSquares = Color3::Zero();
    for (const ScanSample& s : samples) {
        const Eigen::Vector2d basis(
            s.cosine * kInvPi,
            n ? s.cosine * (*n + 2) * (0.5 * kInvPi) * phongPower(*n, s.logCos) : 0.0);
        gram += basis * basis.transpose();
        moments += basis * s.observed.matrix().transpose();
        observedSquares += s.observed.square();
    }
    PhongMaterial m;
    m.n = n.value_or(0);
    double error = 0;
    for (int c = 0; c < 3; ++c) {
        const auto sse = [&](const Eigen::Vector2d& x) {
            return observedSquares[c] + x.dot(gram * x) - 2 * x.dot(moments.col(c));
        };
        // The interior solution if it is non-negative, else the better one-lobe solution.
        const Eigen::Vector2d onlyKd(std::max(moments(0, c) / gram(0, 0), 0.0), 0);
        Eigen::Vector2d x = onlyKd;
        if (n && gram(1, 1) > 0) {
            const Eigen::Vector2d onlyKs(0, std::max(moments(1, c) / gram(1, 1), 0.0));
            x = sse(onlyKd) < sse(onlyKs) ? onlyKd : onlyKs;
            const Eigen::Vector2d interior = gram.ldlt().solve(moments.col(c));
            if (interior.allFinite() && interior.minCoeff() >= 0 && sse(interior) < sse(x))
                x = interior;
        }
        error += sse(x);
        m.kd[c] = x[0];
        m.ks[c] = x[1];
    }
    return {m, error};
}

std::string describeLeftOut(const CaptureModel& m) {
    return fmt::format("{} normal facing away, {} below --min-cos, {} clipped, {} not finite",
                       m.leftOut.at("facing_away"), m.leftOut.at("below_min_cos"),
                       m.leftOut.at("clipped"), m.leftOut.at("non_finite"));
}

}  // namespace

PathSet oneTermPerPixel(const std::vector<float>& cosines, const std::vector<float>& logCos) {
    const std::size_t count = cosines.size();
    PathSet ps;
    ps.width = int(count);
    ps.height = 1;
    ps.spp = 1;
    ps.slots = 1;
    ps.background.assign(count, Color<float>::Zero());
    ps.terms.resize(count);
    ps.vertices.resize(count);
    ps.pixelStart.resize(count + 1);
    for (std::size_t k = 0; k < count; ++k) {
        ps.terms[k] = {std::uint32_t(k), std::uint32_t(k), 1, Color<float>::Constant(cosines[k])};
        ps.vertices[k] = {logCos[k], 0};
        ps.pixelStart[k] = std::uint32_t(k);
    }
    ps.pixelStart[count] = std::uint32_t(count);
    return ps;
}

CaptureModel buildCaptureModel(const Capture& capture, const std::vector<CaptureImage>& images,
                               double minCos) {
    if (!(minCos >= 0 && minCos < 1))
        throw Error(fmt::format("--min-cos {}: must be in [0, 1)", minCos));
    CaptureModel m;
    m.leftOut = {{"facing_away", 0}, {"below_min_cos", 0}, {"clipped", 0}, {"non_finite", 0}};
    const std::size_t pixels = capture.pixels.size();
    std::vector<Frame<double>> frames(pixels);
    std::vector<Vec3d> views(pixels);
    for (std::size_t i = 0; i < pixels; ++i) {
        frames[i] = Frame<double>(capture.normals[i]);
        views[i] = frames[i].toLocal(Vec3d(0, 0, 1));
    }
    std::vector<float> cosines, logCos;
    for (const CaptureImage& image : images) {
        const Vec3d& light = capture.lights[image.light].direction;
        Observation obs;
        std::vector<std::uint32_t> entries;
        cosines.clear();
        logCos.clear();
        for (std::size_t i = 0; i < pixels; ++i) {
            ++m.pairs;
            const Vec3d wo = views[i];
            const Vec3d wi = frames[i].toLocal(light);
            const char* reason = nullptr;
            if (!(cosTheta(wo) > 0))
                reason = "facing_away";
            else if (!(cosTheta(wi) >= minCos && cosTheta(wi) > 0))
                reason = "below_min_cos";
            else if (image.state[i] == PixelState::NonFinite)
                reason = "non_finite";
            else if (image.state[i] == PixelState::Clipped)
                reason = "clipped";
            if (reason) {
                ++m.leftOut[reason];
                continue;
            }
            entries.push_back(std::uint32_t(i));
            cosines.push_back(float(cosTheta(wi)));
            logCos.push_back(float(logCosAlpha(wi, wo)));
            obs.rgb.insert(obs.rgb.end(), image.rgb[i].begin(), image.rgb[i].end());
        }
        if (entries.empty()) continue;
        obs.width = int(entries.size());
        obs.height = 1;
        m.used += entries.size();
        m.lights.push_back(image.light);
        m.observations.push_back(std::move(obs));
        m.paths.push_back(oneTermPerPixel(cosines, logCos));
        m.entries.push_back(std::move(entries));
    }
    return m;
}

std::vector<PathSet> withoutLobe(const std::vector<PathSet>& paths) {
    std::vector<PathSet> out = paths;
    for (PathSet& ps : out)
        for (PathVertex& v : ps.vertices) v.logCos = -std::numeric_limits<float>::infinity();
    return out;
}

HoldoutPrediction predictCapture(const CaptureModel& model, const PairPredictor& phong,
                                 const PairPredictor& lambertian) {
    HoldoutPrediction out;
    ErrorSums phongTotal, lambertianTotal;
    for (std::size_t v = 0; v < model.paths.size(); ++v) {
        const Observation& obs = model.observations[v];
        ErrorSums phongSums, lambertianSums;
        for (std::size_t p = 0; p < model.entries[v].size(); ++p) {
            const std::optional<Color3> byPhong = phong(v, p), byLambertian = lambertian(v, p);
            if (!byPhong || !byLambertian) continue;
            const Color3 observed(obs.rgb[3 * p], obs.rgb[3 * p + 1], obs.rgb[3 * p + 2]);
            phongSums.squares += (*byPhong - observed).square().sum();
            lambertianSums.squares += (*byLambertian - observed).square().sum();
            phongSums.observedSquares += observed.square().sum();
            ++phongSums.pairs;
        }
        lambertianSums.observedSquares = phongSums.observedSquares;
        lambertianSums.pairs = phongSums.pairs;
        out.perLight.push_back({model.lights[v], phongSums.result(), lambertianSums.result()});
        phongTotal.add(phongSums);
        lambertianTotal.add(lambertianSums);
    }
    out.phong = phongTotal.result();
    out.lambertian = lambertianTotal.result();
    return out;
}

HoldoutPrediction predictCapture(const CaptureModel& model, const PhongMaterial& phong,
                                 const PhongMaterial& lambertian) {
    const auto by = [&](const PhongMaterial& m) -> PairPredictor {
        return [&model, &m](std::size_t v, std::size_t p) -> std::optional<Color3> {
            return replayPixel(model.paths[v], p, &m);
        };
    };
    return predictCapture(model, by(phong), by(lambertian));
}

PhongMaterial scanReflectances(const CaptureModel& model, bool lobe) {
    const std::vector<ScanSample> samples = scanSamples(model);
    if (samples.empty()) throw Error("the start scan needs at least one (pixel, light) pair");
    if (!lobe) return bestReflectances(samples, std::nullopt).first;
    // The residual is unimodal in n wherever the images show one lobe.
    const double log2n = gridThenGoldenMinimum(
        [&](double e) { return bestReflectances(samples, std::exp2(e)).second; }, 0, kScanMaxLog2N,
        1, kScanTolerance);
    return bestReflectances(samples, std::exp2(log2n)).first;
}

PhongMaterial startScan(const CaptureModel& model, bool lobe, double scale) {
    PhongMaterial start = scanReflectances(model, lobe);
    start.kd /= scale;
    start.ks /= scale;
    for (int ch = 0; ch < 3; ++ch) {
        if (lobe) start.ks[ch] = std::clamp(start.ks[ch], kMinStartKs, 1.0);
        start.kd[ch] = std::clamp(start.kd[ch], 0.0, 1.0 - start.ks[ch]);
    }
    return start;
}

CaptureModel buildUsableModel(const Capture& capture, const std::vector<CaptureImage>& images,
                              double minCos, const std::string& which) {
    CaptureModel model = buildCaptureModel(capture, images, minCos);
    if (model.paths.empty())
        throw Error(
            fmt::format("capture '{}': no (pixel, light) pair of the {} {} lights can be used ({})",
                        capture.dir, images.size(), which, describeLeftOut(model)));
    const std::size_t nonFinite = model.leftOut.at("non_finite");
    if (double(nonFinite) > kMaxNonFiniteFraction * double(model.pairs))
        throw Error(fmt::format(
            "capture '{}': {} of the {} (pixel, light) pairs of the {} {} lights are NaN or "
            "infinite, more than the {:g}% a capture may have left out",
            capture.dir, nonFinite, model.pairs, images.size(), which,
            100 * kMaxNonFiniteFraction));
    return model;
}

namespace {

// A fit made on images divided by `scale`, in the images' units.
void rescale(FitResult& result, double scale) {
    const auto material = [scale](MaterialFit& m) {
        m.kd *= scale, m.ks *= scale, m.kdStd *= scale, m.ksStd *= scale;
    };
    for (MaterialFit& m : result.materials) material(m);
    result.rmse *= scale;
    for (FitRound& round : result.rounds) {
        for (MaterialFit& m : round.materials) material(m);
        round.rmse *= scale;
    }
}

}  // namespace

CaptureFit fitCapture(const Capture& capture, const std::vector<CaptureImage>& images,
                      const std::vector<CaptureImage>& heldOutImages,
                      const CaptureFitOptions& options) {
    CaptureFit out;
    out.model = buildUsableModel(capture, images, options.minCos, "fitted");
    // The paths are exact: least squares is unbiased on them, one set serves as both of the
    // fitter's independent recordings, and re-recording changes nothing: one round.
    FitOptions fit = options.fit;
    fit.estimator = Estimator::LeastSquares;
    fit.scanStart = false;  // startScan below, on a subsample
    if (!heldOutImages.empty())
        out.heldOut = buildUsableModel(capture, heldOutImages, options.minCos, "held-out");

    // Relative intensities: kd and ks are in the images' units, where kd + ks <= 1 means nothing.
    // The fit runs on images divided by a scale that puts the energy bound far beyond the scan's
    // estimate, and its results are scaled back.
    if (options.relativeIntensities) {
        const PhongMaterial scanned = scanReflectances(out.model, true);
        out.scale = kRelativeHeadroom * std::max((scanned.kd + scanned.ks).maxCoeff(), 1e-12);
    }
    std::vector<Observation> obs = out.model.observations;
    for (Observation& o : obs)
        for (float& v : o.rgb) v = float(v / out.scale);

    out.start = startScan(out.model, true, out.scale);
    out.phong = fitPathSets(obs, out.model.paths, out.model.paths, {out.start}, fit);
    rescale(out.phong, out.scale);
    out.start.kd *= out.scale, out.start.ks *= out.scale;
    const MaterialFit& phong = out.phong.materials[0];
    out.energyBoundReached =
        !options.relativeIntensities && (phong.kd + phong.ks).maxCoeff() >= 1 - kAtEnergyBound;
    if (out.heldOut) {
        const std::vector<PathSet> flat = withoutLobe(out.model.paths);
        out.lambertian =
            fitPathSets(obs, flat, flat, {startScan(out.model, false, out.scale)}, fit);
        rescale(*out.lambertian, out.scale);
        out.holdout = predictCapture(*out.heldOut, out.phong.materials[0].material(),
                                     out.lambertian->materials[0].material());
    }
    return out;
}

}  // namespace phongfit
