#include "albedo_map_fit.h"

#include <fmt/format.h>
#include <tbb/blocked_range.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <limits>
#include <memory>

#include "error.h"
#include "grid_search.h"
#include "material_clusters.h"
#include "phong_brdf.h"

namespace phongfit {
namespace {

// The exponent is searched over log2 n in [kMinLog2N, kMaxLog2N]: a grid, then golden section
// around its best point until log2 n is bracketed within kLog2NTolerance.
constexpr double kMinLog2N = 0, kMaxLog2N = 20;
constexpr double kGridStep = 0.5;
constexpr double kLog2NTolerance = 1e-4;
// The active set of kd_p = 0 settles in a few passes; this bounds a pathological case.
constexpr int kMaxActiveSetPasses = 100;
// More pixels than this fraction 3 standard errors beyond kd + ks = 1 is not chance.
constexpr double kChanceFraction = 0.01;
// A channel's lobe is seen when its ks is this many standard errors above zero.
constexpr double kLobeSigmas = 3;

struct Pair {
    float cosine, logCos;
    Color<float> observed;
    std::uint32_t view;  // the light's view in the model
};

// The pairs grouped by fitted pixel.
struct PixelPairs {
    std::vector<std::uint32_t> pixel;  // mask pixel index of each fitted pixel
    std::vector<std::size_t> start;    // pairs of fitted pixel i: [start[i], start[i + 1])
    std::vector<Pair> pairs;
};

// The pairs of the pixels of material `which` that have at least minPairs pairs (marked in
// `fitted`).
PixelPairs groupByPixel(const CaptureModel& model, const std::vector<std::uint8_t>& material,
                        std::uint8_t which, int minPairs, std::vector<std::uint8_t>& fitted) {
    const std::size_t maskPixels = material.size();
    std::vector<std::size_t> count(maskPixels, 0);
    for (const auto& entries : model.entries)
        for (std::uint32_t p : entries) ++count[p];
    PixelPairs out;
    std::vector<std::size_t> at(maskPixels, 0);
    out.start.push_back(0);
    for (std::size_t p = 0; p < maskPixels; ++p) {
        if (material[p] != which || count[p] < std::size_t(minPairs)) continue;
        fitted[p] = 1;
        at[p] = out.start.back();
        out.pixel.push_back(std::uint32_t(p));
        out.start.push_back(out.start.back() + count[p]);
    }
    out.pairs.resize(out.start.back());
    for (std::size_t v = 0; v < model.entries.size(); ++v) {
        const PathSet& ps = model.paths[v];
        const std::vector<float>& rgb = model.observations[v].rgb;
        for (std::size_t k = 0; k < model.entries[v].size(); ++k) {
            const std::uint32_t p = model.entries[v][k];
            if (!fitted[p] || material[p] != which) continue;
            out.pairs[at[p]++] = {ps.terms[k].constant[0], ps.vertices[k].logCos,
                                  Color<float>(rgb[3 * k], rgb[3 * k + 1], rgb[3 * k + 2]),
                                  std::uint32_t(v)};
        }
    }
    return out;
}

// The model's two basis functions of a pair at exponent n: I = kd a + ks b.
double diffuseBasis(double cosine) { return cosine * kInvPi; }
double lobeBasis(double cosine, double logCos, double n) {
    return cosine * (n + 2) * (0.5 * kInvPi) * phongPower(n, logCos);
}
// d b / d n.
double lobeSlope(double cosine, double logCos, double n) {
    if (logCos == -std::numeric_limits<float>::infinity()) return 0;
    return cosine * (0.5 * kInvPi) * phongPower(n, logCos) * (1 + (n + 2) * double(logCos));
}

// Sums over one pixel's pairs that do not depend on n.
struct FixedSums {
    double aa = 0;
    Color3 aI = Color3::Zero(), II = Color3::Zero();
};
// Sums over one pixel's pairs at one n.
struct LobeSums {
    double ab = 0, bb = 0;
    Color3 bI = Color3::Zero();
};

struct Solution {
    Color3 ks = Color3::Zero();
    std::vector<Color3> kd;  // per fitted pixel
    double sse = 0;
};

class Solver {
public:
    Solver(const PixelPairs& pixels, bool grey) : pixels_(pixels), grey_(grey) {
        fixed_.resize(pixels.pixel.size());
        tbb::parallel_for(std::size_t(0), fixed_.size(), [&](std::size_t i) {
            FixedSums& s = fixed_[i];
            for (std::size_t k = pixels.start[i]; k < pixels.start[i + 1]; ++k) {
                const Pair& pair = pixels.pairs[k];
                const double a = diffuseBasis(pair.cosine);
                const Color3 observed = pair.observed.cast<double>();
                s.aa += a * a;
                s.aI += a * observed;
                s.II += observed.square();
            }
        });
    }

    // The best kd_p >= 0 and ks >= 0 at exponent n (without the lobe: kd_p alone).
    Solution solve(double n, bool lobe) {
        const std::size_t count = fixed_.size();
        std::vector<LobeSums> lobeSums(count);
        if (lobe)
            tbb::parallel_for(std::size_t(0), count, [&](std::size_t i) {
                LobeSums& s = lobeSums[i];
                for (std::size_t k = pixels_.start[i]; k < pixels_.start[i + 1]; ++k) {
                    const Pair& pair = pixels_.pairs[k];
                    const double a = diffuseBasis(pair.cosine);
                    const double b = lobeBasis(pair.cosine, pair.logCos, n);
                    s.ab += a * b;
                    s.bb += b * b;
                    s.bI += b * pair.observed.cast<double>();
                }
            });
        Solution out;
        out.ks = lobe ? sharedKs(lobeSums) : Color3::Zero();
        out.kd.resize(count);
        for (std::size_t i = 0; i < count; ++i) {
            const FixedSums& f = fixed_[i];
            const LobeSums& l = lobeSums[i];
            const Color3 kd = ((f.aI - out.ks * l.ab) / f.aa).max(0.0);
            out.kd[i] = kd;
            out.sse += (f.II - 2 * kd * f.aI - 2 * out.ks * l.bI + kd.square() * f.aa +
                        2 * kd * out.ks * l.ab + out.ks.square() * l.bb)
                           .sum();
        }
        return out;
    }

    const FixedSums& fixed(std::size_t i) const { return fixed_[i]; }

private:
    // ks given that each free kd_p takes its best value; pixels whose kd_p would be negative are
    // held at kd_p = 0 (the active set), until the set no longer changes.
    Color3 sharedKs(const std::vector<LobeSums>& sums) const {
        const std::size_t count = sums.size();
        std::vector<std::array<bool, 3>> held(count, {false, false, false});
        Color3 ks = Color3::Zero();
        for (int pass = 0; pass < kMaxActiveSetPasses; ++pass) {
            Color3 num = Color3::Zero(), den = Color3::Zero();
            for (std::size_t i = 0; i < count; ++i)
                for (int c = 0; c < 3; ++c) {
                    const FixedSums& f = fixed_[i];
                    const LobeSums& l = sums[i];
                    num[c] += held[i][c] ? l.bI[c] : l.bI[c] - l.ab * f.aI[c] / f.aa;
                    den[c] += held[i][c] ? l.bb : l.bb - l.ab * l.ab / f.aa;
                }
            if (grey_) num.setConstant(num.sum()), den.setConstant(den.sum());
            for (int c = 0; c < 3; ++c) ks[c] = den[c] > 0 ? std::max(num[c] / den[c], 0.0) : 0;
            bool changed = false;
            for (std::size_t i = 0; i < count; ++i)
                for (int c = 0; c < 3; ++c) {
                    const bool negative = fixed_[i].aI[c] - ks[c] * sums[i].ab < 0;
                    changed |= negative != held[i][c];
                    held[i][c] = negative;
                }
            if (!changed) break;
        }
        return ks;
    }

    const PixelPairs& pixels_;
    bool grey_;
    std::vector<FixedSums> fixed_;
};

// The exponent in [2^kMinLog2N, 2^kMaxLog2N] with the smallest residual.
double bestExponent(Solver& solver, int& evaluations) {
    const auto sse = [&](double log2n) {
        ++evaluations;
        return solver.solve(std::exp2(log2n), true).sse;
    };
    return std::exp2(gridThenGoldenMinimum(sse, kMinLog2N, kMaxLog2N, kGridStep, kLog2NTolerance));
}

// Standard errors of ks and n, the larger of two: the Gauss-Newton information with the free kd_p
// eliminated (Schur complement), sigma^2 from the residual, which holds when the model is exact and
// the noise independent; and the sandwich clustered by light, which also holds when each light
// misfits in its own way (a direction or intensity a little off, interreflection): real captures,
// where the exponents fitted from two halves of the lights differ by far more than the first says.
// Parameters at a bound (ks = 0, kd_p = 0) are held.
void standardErrors(const PixelPairs& pixels, const Solver& solver, const Solution& s, double n,
                    bool grey, std::size_t views, LobeFit& out, std::vector<Color3>& kdStd) {
    const std::size_t values = 3 * pixels.pairs.size();
    // Parameters: ks per channel (or one), then n.
    const int ksCount = grey ? 1 : 3, nIndex = ksCount;
    const auto ksIndex = [&](int c) { return grey ? 0 : c; };
    Eigen::Matrix4d info = Eigen::Matrix4d::Zero();
    // Per light, the score (projected Jacobian times residual) of each parameter.
    std::vector<Eigen::Vector4d> scores(views, Eigen::Vector4d::Zero());
    std::size_t freeKd = 0;
    for (std::size_t i = 0; i < pixels.pixel.size(); ++i) {
        double ab = 0, ad = 0, bb = 0, bd = 0, dd = 0;
        for (std::size_t k = pixels.start[i]; k < pixels.start[i + 1]; ++k) {
            const Pair& pair = pixels.pairs[k];
            const double a = diffuseBasis(pair.cosine);
            const double b = lobeBasis(pair.cosine, pair.logCos, n);
            const double d = lobeSlope(pair.cosine, pair.logCos, n);
            ab += a * b, ad += a * d, bb += b * b, bd += b * d, dd += d * d;
        }
        const double aa = solver.fixed(i).aa;
        for (int c = 0; c < 3; ++c) {
            const double ks = s.ks[c];
            const int j = ksIndex(c);
            info(j, j) += bb;
            info(j, nIndex) += ks * bd;
            info(nIndex, j) += ks * bd;
            info(nIndex, nIndex) += ks * ks * dd;
            const bool free = s.kd[i][c] > 0;
            if (free) {  // eliminate it
                ++freeKd;
                const Eigen::Vector2d v(ab, ks * ad);
                info(j, j) -= v[0] * v[0] / aa;
                info(j, nIndex) -= v[0] * v[1] / aa;
                info(nIndex, j) -= v[0] * v[1] / aa;
                info(nIndex, nIndex) -= v[1] * v[1] / aa;
            }
            for (std::size_t k = pixels.start[i]; k < pixels.start[i + 1]; ++k) {
                const Pair& pair = pixels.pairs[k];
                const double a = diffuseBasis(pair.cosine);
                const double b = lobeBasis(pair.cosine, pair.logCos, n);
                const double d = lobeSlope(pair.cosine, pair.logCos, n);
                const double r = pair.observed[c] - s.kd[i][c] * a - ks * b;
                // The Jacobian row with kd_p projected out, as the Schur complement does.
                const double jKs = free ? b - a * ab / aa : b;
                const double jN = ks * (free ? d - a * ad / aa : d);
                scores[pair.view][j] += jKs * r;
                scores[pair.view][nIndex] += jN * r;
            }
        }
    }
    // Held parameters (ks at 0; n without any lobe) leave the system.
    std::vector<int> free;
    for (int c = 0; c < ksCount; ++c)
        if (s.ks[grey ? 0 : c] > 0) free.push_back(c);
    const bool lobe = !free.empty();
    if (lobe) free.push_back(nIndex);
    const double dof = double(values) - double(freeKd) - double(free.size());
    const double sigma2 = dof > 0 ? s.sse / dof : std::numeric_limits<double>::infinity();
    const auto size = Eigen::Index(free.size());
    Eigen::MatrixXd reduced(size, size), meat = Eigen::MatrixXd::Zero(size, size);
    for (Eigen::Index r = 0; r < size; ++r)
        for (Eigen::Index c = 0; c < size; ++c) reduced(r, c) = info(free[r], free[c]);
    for (const Eigen::Vector4d& score : scores) {
        Eigen::VectorXd g(size);
        for (Eigen::Index r = 0; r < size; ++r) g[r] = score[free[std::size_t(r)]];
        meat += g * g.transpose();
    }
    const double clusters = double(views);
    if (clusters > 1) meat *= clusters / (clusters - 1);
    const Eigen::MatrixXd bread = reduced.inverse();
    const Eigen::MatrixXd model = sigma2 * bread, clustered = bread * meat * bread;
    const auto stdOf = [&](int param) {
        const auto at = std::find(free.begin(), free.end(), param);
        if (at == free.end()) return std::numeric_limits<double>::infinity();
        const Eigen::Index i = at - free.begin();
        const double var = std::max(model(i, i), clustered(i, i));
        return var >= 0 && std::isfinite(var) ? std::sqrt(var)
                                              : std::numeric_limits<double>::infinity();
    };
    for (int c = 0; c < 3; ++c) out.ksStd[c] = s.ks[c] > 0 ? stdOf(ksIndex(c)) : 0.0;
    out.nStd = lobe ? stdOf(nIndex) : std::numeric_limits<double>::infinity();
    for (std::size_t i = 0; i < pixels.pixel.size(); ++i)
        for (int c = 0; c < 3; ++c)
            kdStd[pixels.pixel[i]][c] = std::sqrt(sigma2 / solver.fixed(i).aa);
}

}  // namespace

AlbedoMapFit fitAlbedoMap(const Capture& capture, const CaptureModel& model,
                          const AlbedoMapOptions& options) {
    const auto started = std::chrono::steady_clock::now();
    if (options.materials < 1 || options.materials > kMaxMaterials)
        throw Error(
            fmt::format("--materials {}: must be 1 to {}", options.materials, kMaxMaterials));
    std::unique_ptr<tbb::global_control> threads;
    if (options.threads > 0)
        threads = std::make_unique<tbb::global_control>(
            tbb::global_control::max_allowed_parallelism, std::size_t(options.threads));
    AlbedoMapFit out;
    const std::size_t maskPixels = capture.pixels.size();
    out.minN = std::exp2(kMinLog2N);
    out.maxN = std::exp2(kMaxLog2N);
    out.kd.assign(maskPixels, Color3::Zero());
    out.kdStd.assign(maskPixels, Color3::Zero());
    out.lambertianKd.assign(maskPixels, Color3::Zero());
    out.fitted.assign(maskPixels, 0);
    if (options.materials == 1) {
        out.material.assign(maskPixels, 0);
    } else {
        AlbedoMapOptions shared = options;
        shared.materials = 1;
        out.material = clusterMaterials(fitAlbedoMap(capture, model, shared), options.materials);
    }
    double sse = 0, lambertianSse = 0;
    for (int m = 0; m < options.materials; ++m) {
        const PixelPairs pixels =
            groupByPixel(model, out.material, std::uint8_t(m), options.minPairs, out.fitted);
        if (pixels.pixel.empty())
            throw Error(fmt::format(
                "capture '{}': no pixel of material {} of {} has {} usable pairs, the least a "
                "per-pixel albedo needs{}",
                capture.dir, m + 1, options.materials, options.minPairs,
                options.materials > 1 ? " (fewer --materials?)" : ""));
        LobeFit lobe;
        lobe.pixels = pixels.pixel.size();
        Solver solver(pixels, options.grey);
        lobe.n = bestExponent(solver, lobe.evaluations);
        lobe.nAtBound = std::log2(lobe.n) < kMinLog2N + 2 * kGridStep ||
                        std::log2(lobe.n) > kMaxLog2N - 2 * kGridStep;
        const Solution phong = solver.solve(lobe.n, true);
        const Solution lambertian = solver.solve(lobe.n, false);
        lobe.ks = phong.ks;
        for (std::size_t i = 0; i < pixels.pixel.size(); ++i) {
            out.kd[pixels.pixel[i]] = phong.kd[i];
            out.lambertianKd[pixels.pixel[i]] = lambertian.kd[i];
        }
        sse += phong.sse, lambertianSse += lambertian.sse;
        out.pairs += pixels.pairs.size();
        out.pixelsFitted += pixels.pixel.size();
        standardErrors(pixels, solver, phong, lobe.n, options.grey, model.entries.size(), lobe,
                       out.kdStd);
        bool seen = false;
        for (int c = 0; c < 3; ++c) seen |= lobe.ks[c] > kLobeSigmas * lobe.ksStd[c];
        if (!seen || !std::isfinite(lobe.nStd)) lobe.unconstrained.push_back("n");
        for (std::uint32_t p : pixels.pixel)
            if ((out.kd[p] - kLobeSigmas * out.kdStd[p] + lobe.ks > 1).any()) ++out.kdAboveOne;
        out.lobes.push_back(std::move(lobe));
    }
    out.pixelsTooFewPairs = maskPixels - out.pixelsFitted;
    out.energyBoundExceeded = double(out.kdAboveOne) > kChanceFraction * double(out.pixelsFitted);
    const double values = 3.0 * double(out.pairs);
    out.rmse = std::sqrt(std::max(sse, 0.0) / values);
    out.lambertianRmse = std::sqrt(std::max(lambertianSse, 0.0) / values);
    out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
    return out;
}

bool AlbedoMapFit::converged() const {
    return std::all_of(lobes.begin(), lobes.end(),
                       [](const LobeFit& l) { return l.unconstrained.empty(); });
}

Color3 predictAlbedoMap(const AlbedoMapFit& fit, std::uint32_t pixel, double cosine,
                        double logCos) {
    const LobeFit& lobe = fit.lobes[fit.material[pixel]];
    return fit.kd[pixel] * diffuseBasis(cosine) + lobe.ks * lobeBasis(cosine, logCos, lobe.n);
}

HoldoutPrediction predictCapture(const CaptureModel& model, const AlbedoMapFit& fit) {
    const auto pixel = [&](std::size_t v, std::size_t k) { return model.entries[v][k]; };
    return predictCapture(
        model,
        [&](std::size_t v, std::size_t k) -> std::optional<Color3> {
            const std::uint32_t p = pixel(v, k);
            if (!fit.fitted[p]) return std::nullopt;
            return predictAlbedoMap(fit, p, model.paths[v].terms[k].constant[0],
                                    model.paths[v].vertices[k].logCos);
        },
        [&](std::size_t v, std::size_t k) -> std::optional<Color3> {
            const std::uint32_t p = pixel(v, k);
            if (!fit.fitted[p]) return std::nullopt;
            return fit.lambertianKd[p] * diffuseBasis(model.paths[v].terms[k].constant[0]);
        });
}

AlbedoMapCaptureFit fitCaptureAlbedoMap(const Capture& capture,
                                        const std::vector<CaptureImage>& images,
                                        const std::vector<CaptureImage>& heldOutImages,
                                        double minCos, const AlbedoMapOptions& options) {
    AlbedoMapCaptureFit out;
    out.model = buildUsableModel(capture, images, minCos, "fitted");
    if (!heldOutImages.empty())
        out.heldOut = buildUsableModel(capture, heldOutImages, minCos, "held-out");
    out.fit = fitAlbedoMap(capture, out.model, options);
    if (out.heldOut) out.holdout = predictCapture(*out.heldOut, out.fit);
    return out;
}

}  // namespace phongfit
