#include "decoding_check.h"

#include <cmath>

#include "albedo_map_fit.h"
#include "error.h"

namespace phongfit {
namespace {

// The other reading is likely right when it explains more than this fraction of the pixels better.
constexpr double kClearMajority = 0.7;
// The check fits every this-many-th mask pixel: the verdict does not need them all.
constexpr std::uint32_t kPixelStride = 4;

double reread(double linear, Encoding from, Encoding to) {
    if (from == to) return linear;
    const double code = from == Encoding::Srgb ? linearToSrgb(linear) : linear;
    return to == Encoding::Srgb ? srgbToLinear(code) : code;
}

}  // namespace

std::string curveName(Encoding curve) { return curve == Encoding::Srgb ? "sRGB" : "linear"; }

std::optional<DecodingCheck> checkDecoding(const Capture& capture, const CaptureModel& model,
                                           const std::vector<CaptureImage>& images, int threads) {
    if (images.empty() || !images.front().integerCurve) return std::nullopt;
    DecodingCheck out;
    out.used = *images.front().integerCurve;
    if (out.used != Encoding::Linear && out.used != Encoding::Srgb) return std::nullopt;
    out.other = out.used == Encoding::Srgb ? Encoding::Linear : Encoding::Srgb;

    // Every kPixelStride-th pixel, each pair read both ways.
    CaptureModel used, other;
    for (std::size_t v = 0; v < model.entries.size(); ++v) {
        const Color3 intensity = capture.lights[std::size_t(model.lights[v])].intensity;
        std::vector<std::uint32_t> entries;
        std::vector<float> cosines, logCos, usedRgb, otherRgb;
        for (std::size_t k = 0; k < model.entries[v].size(); ++k) {
            if (model.entries[v][k] % kPixelStride != 0) continue;
            entries.push_back(model.entries[v][k]);
            cosines.push_back(model.paths[v].terms[k].constant[0]);
            logCos.push_back(model.paths[v].vertices[k].logCos);
            for (int c = 0; c < 3; ++c) {
                // The value as read was divided by the light's intensity: undo it to re-read the
                // code, then divide again.
                const double value = model.observations[v].rgb[3 * k + std::size_t(c)];
                usedRgb.push_back(float(value));
                otherRgb.push_back(
                    float(reread(value * intensity[c], out.used, out.other) / intensity[c]));
            }
        }
        if (entries.empty()) continue;
        for (CaptureModel* m : {&used, &other}) {
            m->lights.push_back(model.lights[v]);
            m->entries.push_back(entries);
            m->paths.push_back(oneTermPerPixel(cosines, logCos));
            Observation obs;
            obs.width = int(entries.size());
            obs.height = 1;
            obs.rgb = m == &used ? usedRgb : otherRgb;
            m->observations.push_back(std::move(obs));
        }
    }
    AlbedoMapOptions options;
    options.threads = threads;
    // Per pixel, the residual of each reading relative to its values' sum of squares.
    const auto pixelErrors = [&](const CaptureModel& m) -> std::optional<std::vector<double>> {
        std::optional<AlbedoMapFit> fit;
        try {
            fit = fitAlbedoMap(capture, m, options);
        } catch (const Error&) {
            return std::nullopt;  // too few pairs per pixel: no verdict
        }
        std::vector<double> squares(capture.pixels.size(), 0), residual(capture.pixels.size(), 0);
        for (std::size_t v = 0; v < m.entries.size(); ++v)
            for (std::size_t k = 0; k < m.entries[v].size(); ++k) {
                const std::uint32_t p = m.entries[v][k];
                if (!fit->fitted[p]) continue;
                const float* rgb = &m.observations[v].rgb[3 * k];
                const Color3 observed(rgb[0], rgb[1], rgb[2]);
                const Color3 predicted = predictAlbedoMap(*fit, p, m.paths[v].terms[k].constant[0],
                                                          m.paths[v].vertices[k].logCos);
                squares[p] += observed.square().sum();
                residual[p] += (predicted - observed).square().sum();
            }
        for (std::size_t p = 0; p < squares.size(); ++p)
            residual[p] = squares[p] > 0 ? residual[p] / squares[p] : -1;
        return residual;
    };
    const auto usedErrors = pixelErrors(used), otherErrors = pixelErrors(other);
    if (!usedErrors || !otherErrors) return std::nullopt;
    std::size_t pixels = 0, otherBetter = 0;
    for (std::size_t p = 0; p < usedErrors->size(); ++p) {
        if ((*usedErrors)[p] < 0 || (*otherErrors)[p] < 0) continue;
        ++pixels;
        otherBetter += (*otherErrors)[p] < (*usedErrors)[p];
    }
    if (pixels == 0) return std::nullopt;
    out.otherBetterFraction = double(otherBetter) / double(pixels);
    out.otherFitsBetter = out.otherBetterFraction > kClearMajority;
    return out;
}

}  // namespace phongfit
