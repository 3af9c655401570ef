#include "edge_agreement.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <tuple>
#include <utility>

#include "film_window.h"
#include "grid_search.h"
#include "percentile.h"

namespace phongfit {

namespace {

// Paths a pixel of the render: as many as the image's (the difference's noise then twice the
// image's variance, which the deviations allow for), within what keeps the check a small part of
// the fit.
int renderSpp(int imageSpp) { return imageSpp > 0 ? std::clamp(imageSpp, 512, 4096) : 4096; }

// The image's largest difference from a 4-neighbour in the film, over the channels: how much a
// pixel filter's spread moves the pixel's value.
double contrast(const Observation& o, std::uint32_t p) {
    const int x = int(p % std::uint32_t(o.width)), y = int(p / std::uint32_t(o.width));
    double most = 0;
    const auto against = [&](int qx, int qy) {
        if (qx < 0 || qy < 0 || qx >= o.width || qy >= o.height) return;
        const std::size_t q = std::size_t(qy) * std::size_t(o.width) + std::size_t(qx);
        for (std::size_t c = 0; c < 3; ++c)
            most =
                std::max(most, std::abs(double(o.rgb[3 * std::size_t(p) + c]) - o.rgb[3 * q + c]));
    };
    against(x - 1, y), against(x + 1, y), against(x, y - 1), against(x, y + 1);
    return most;
}

// Up to `most` of `pixels`: the higher-contrast half of them, evenly spread, in the order of
// `pixels`.
std::vector<std::uint32_t> highContrast(const Observation& o, std::vector<std::uint32_t> pixels,
                                        std::size_t most) {
    if (pixels.size() <= most) return pixels;
    std::vector<std::pair<double, std::uint32_t>> ranked;
    for (std::uint32_t p : pixels) ranked.emplace_back(-contrast(o, p), p);
    const std::size_t half = std::max(most, ranked.size() / 2);
    std::nth_element(ranked.begin(), ranked.begin() + std::ptrdiff_t(half), ranked.end());
    std::vector<std::uint32_t> high;
    for (std::size_t k = 0; k < half; ++k) high.push_back(ranked[k].second);
    std::sort(high.begin(), high.end());
    pixels.clear();
    for (std::size_t k = 0; k < most; ++k) pixels.push_back(high[k * high.size() / most]);
    return pixels;
}

// A chosen pixel, over the sum of its channels: the render, one sample's standard deviation there
// (the channels' added, as if they moved as one) and the samples taken.
struct Rendered {
    double value, sampleStd;
    std::uint32_t samples;
};

// Paths a pixel whose first render's samples all took one value is rendered with again: that
// render saw no noise there, whether it missed a lit sliver of a silhouette that one of the
// image's samples hit (the point-lit sphere at 128x128: 0.0054 in the image, none of 512 paths
// lit) or the filter leaves the pixel dark. At this many, a sliver lit above the darkness that
// deviations() leaves out is hit about 16 times.
constexpr int kSliverSpp = 16384;

// `pixels` of view `v`, rendered with `options` (its window and flags set here).
std::vector<Rendered> renderAt(const SceneView& v, const std::vector<std::uint32_t>& pixels,
                               double exposure, RenderOptions options) {
    const Observation& o = v.observation;
    options.window = boundingWindow(pixels, o.width);
    std::vector<std::uint8_t> flags(options.window.pixels(), 0);
    const auto at = [&](std::uint32_t p) {
        const int x = int(p % std::uint32_t(o.width)) - options.window.x0;
        const int y = int(p / std::uint32_t(o.width)) - options.window.y0;
        return std::size_t(y) * std::size_t(options.window.width) + std::size_t(x);
    };
    for (std::uint32_t p : pixels) flags[at(p)] = 1;
    options.rendered = flags;
    const RenderResult r = v.renderer->render(options);
    std::vector<Rendered> out;
    for (std::uint32_t p : pixels) {
        const std::size_t q = at(p);
        Rendered c{0, 0, r.sampleCount[q]};
        for (std::size_t ch = 0; ch < 3; ++ch) {
            c.value += exposure * r.rgb[3 * q + ch];
            c.sampleStd += exposure * std::sqrt(r.variance[3 * q + ch] * double(r.sampleCount[q]));
        }
        out.push_back(c);
    }
    return out;
}

// The chosen pixels of view `v` rendered with `options`, and those whose samples all took one
// value again with kSliverSpp paths (the same first ones).
std::vector<Rendered> renderPixels(const SceneView& v, const std::vector<std::uint32_t>& chosen,
                                   double exposure, RenderOptions options) {
    std::vector<Rendered> out = renderAt(v, chosen, exposure, options);
    std::vector<std::uint32_t> flat;
    std::vector<std::size_t> where;
    for (std::size_t k = 0; k < chosen.size(); ++k)
        if (out[k].sampleStd == 0) {
            flat.push_back(chosen[k]);
            where.push_back(k);
        }
    if (flat.empty()) return out;
    options.spp = std::max(options.spp, kSliverSpp);
    const std::vector<Rendered> again = renderAt(v, flat, exposure, options);
    for (std::size_t i = 0; i < flat.size(); ++i) out[where[i]] = again[i];
    return out;
}

// Per chosen pixel: |image - render| over the noise of their difference and kEdgeTolerance; -1
// where the pixel is dark in both (the unlit side of a silhouette), which agrees whatever the
// filter.
std::vector<double> deviations(const std::vector<double>& image,
                               const std::vector<Rendered>& rendered, int imageSpp) {
    double brightest = 0;
    for (std::size_t k = 0; k < image.size(); ++k)
        brightest = std::max({brightest, std::abs(image[k]), std::abs(rendered[k].value)});
    std::vector<double> out;
    for (std::size_t k = 0; k < image.size(); ++k) {
        const Rendered& c = rendered[k];
        const double level = std::max(std::abs(image[k]), std::abs(c.value));
        const double noise =
            c.sampleStd * c.sampleStd *
            ((imageSpp > 0 ? 1.0 / imageSpp : 0.0) + 1.0 / std::max<std::uint32_t>(c.samples, 1));
        const double tolerance = kEdgeTolerance * level;
        out.push_back(level <= 1e-3 * brightest ? -1.0
                                                : std::abs(image[k] - c.value) /
                                                      std::sqrt(noise + tolerance * tolerance));
    }
    return out;
}

// The pixels with light, and their squared deviations' sum.
std::pair<std::size_t, double> litMisfit(const std::vector<double>& deviations) {
    std::pair<std::size_t, double> out{0, 0.0};
    for (double d : deviations)
        if (d >= 0) out = {out.first + 1, out.second + d * d};
    return out;
}

// The width of a filter's kind, within kWidthRange of `defaultWidth`, where `misfit` is least:
// golden-section search over log width (the misfit falls, then rises, as the filter widens), to
// 2%, rounded to 3 digits as the label prints it.
template <class Misfit>
double bestWidth(double defaultWidth, const Misfit& misfit) {
    const double logWidth = goldenSectionMinimum([&](double t) { return misfit(std::exp(t)); },
                                                 std::log(defaultWidth / kWidthRange),
                                                 std::log(defaultWidth * kWidthRange), 0.02);
    return std::stod(fmt::format("{:.3g}", std::exp(logWidth)));
}

// Of the filters `tried` (the first `defaults` at their default widths), the one of another kind
// than `best` that fits within kFilterEvidence of it, defaults first, then the least misfit. Where
// `best` is at its default width, only a default: renderers filter at theirs.
std::optional<std::pair<PixelFilter, double>> alikeFilter(
    const std::vector<std::pair<PixelFilter, double>>& tried,
    const std::pair<PixelFilter, double>& best, std::size_t defaults) {
    const bool bestDefault = std::any_of(tried.begin(), tried.begin() + std::ptrdiff_t(defaults),
                                         [&](const auto& t) { return t.first == best.first; });
    std::optional<std::pair<PixelFilter, double>> alike;
    for (std::size_t k = 0; k < tried.size(); ++k) {
        if (k == defaults && (alike || bestDefault)) break;
        const auto& [filter, misfit] = tried[k];
        if (filter.filter != best.first.filter && misfit < best.second + kFilterEvidence &&
            (!alike || misfit < alike->second))
            alike = tried[k];
    }
    return alike;
}

}  // namespace

std::string pixelFilterLabel(const PixelFilter& f) {
    const PixelFilterName& name = pixelFilterName(f.filter);
    return name.width == nullptr ? name.type
                                 : fmt::format("{} {} {:g}", name.type, name.width, f.width);
}

std::vector<std::uint32_t> edgePixels(const std::vector<int>& seen, int width, int height,
                                      const std::vector<int>& fitted) {
    const auto isFitted = [&](int bsdf) {
        return std::find(fitted.begin(), fitted.end(), bsdf) != fitted.end();
    };
    const auto differs = [&](std::size_t p, std::size_t q) {
        return seen[p] != seen[q] && (isFitted(seen[p]) || isFitted(seen[q]));
    };
    std::vector<std::uint32_t> edges;
    for (int y = 0; y < height; ++y)
        for (int x = 0; x < width; ++x) {
            const std::size_t p = std::size_t(y) * std::size_t(width) + std::size_t(x);
            if ((x > 0 && differs(p, p - 1)) || (x + 1 < width && differs(p, p + 1)) ||
                (y > 0 && differs(p, p - std::size_t(width))) ||
                (y + 1 < height && differs(p, p + std::size_t(width))))
                edges.push_back(std::uint32_t(p));
        }
    return edges;
}

EdgeCheck edgeAgreement(const SceneView& v, const std::vector<PhongMaterial>& fitted,
                        double exposure, int imageSpp, std::uint64_t seed, int threads) {
    const Observation& o = v.observation;
    std::vector<std::uint32_t> used;
    for (std::uint32_t p : v.edges)
        if (o.valid[p]) used.push_back(p);
    std::vector<std::uint32_t> chosen = highContrast(o, used, kMostEdgePixels);
    EdgeCheck check;
    if (chosen.size() < kLeastEdgePixels) return check;
    std::vector<double> image;
    for (std::uint32_t p : chosen)
        image.push_back(double(o.rgb[3 * std::size_t(p)]) + o.rgb[3 * std::size_t(p) + 1] +
                        o.rgb[3 * std::size_t(p) + 2]);

    RenderOptions options = renderOptionsAt(v, fitted, threads);
    options.spp = renderSpp(imageSpp);
    options.seed = seed * 7919 + 15485863;  // independent of the recordings and the noise renders
    options.pixelSampler = PixelSamplerType::Independent;
    // Every filter's render takes the same samples: their misfits differ by the filter alone.
    const auto deviationsWith = [&](const std::optional<PixelFilter>& filter) {
        options.pixelFilter = filter;
        return deviations(image, renderPixels(v, chosen, exposure, options), imageSpp);
    };
    const std::vector<double> stated = deviationsWith(std::nullopt);
    std::tie(check.pixels, check.misfit) = litMisfit(stated);
    if (check.pixels < kLeastEdgePixels) return check;
    // The median over the pixels whose centre sees a fitted material: outside, the background's
    // own pixels (an environment another renderer interpolates otherwise) are no part of the fit.
    const auto insideMedian = [&](const std::vector<double>& deviations) {
        std::vector<double> inside;
        for (std::size_t k = 0; k < chosen.size(); ++k)
            if (deviations[k] >= 0 && v.direct[chosen[k]]) inside.push_back(deviations[k]);
        return std::pair{inside.size(), percentile(inside, 50)};
    };
    const auto [inside, statedMedian] = insideMedian(stated);
    check.medianDeviation = statedMedian;
    check.disagrees = inside * 2 >= kLeastEdgePixels && check.medianDeviation > kEdgeDisagreement;

    // The other filters at their default widths; where one fits better, or the scene's own leaves
    // edge pixels too far off, each kind at its best width too. A filter whose edges leave too few
    // pixels lit has no misfit.
    const PixelFilter own = pixelFilterOf(v.renderer->scene().sensor);
    const auto misfitWith = [&](const PixelFilter& f) {
        if (f == own) return check.misfit;
        const auto [lit, misfit] = litMisfit(deviationsWith(f));
        return lit < kLeastEdgePixels ? std::numeric_limits<double>::infinity() : misfit;
    };
    const auto better = [&](double misfit) {
        return misfit < kFilterPreference * check.misfit && misfit < check.misfit - kFilterEvidence;
    };
    std::vector<std::pair<PixelFilter, double>> defaults;
    for (const PixelFilterName& f : kPixelFilters) {
        const PixelFilter filter{f.filter, f.width == nullptr ? 0 : f.defaultWidth};
        defaults.emplace_back(filter, misfitWith(filter));
    }
    auto best = *std::min_element(defaults.begin(), defaults.end(),
                                  [](const auto& x, const auto& y) { return x.second < y.second; });
    if (!better(best.second) && !(check.medianDeviation > kWidthSearch)) return check;
    // Renderers filter at their defaults: another width is named where it fits better than every
    // default by kFilterEvidence.
    const double bestDefault = best.second;
    std::vector<std::pair<PixelFilter, double>> tried = defaults;
    for (const auto& candidate : defaults) {
        const PixelFilter& filter = candidate.first;
        if (pixelFilterName(filter.filter).width == nullptr) continue;
        const PixelFilter widened{filter.filter, bestWidth(filter.width, [&](double w) {
                                      return misfitWith({filter.filter, w});
                                  })};
        const double misfit = misfitWith(widened);
        tried.emplace_back(widened, misfit);
        if (misfit < bestDefault - kFilterEvidence && misfit < best.second)
            best = {widened, misfit};
    }
    // A filter is the image's only where its edges agree as an image's own do: none fits edges
    // that a camera or shapes other than the image's moved (the widest Gaussian searched would
    // fit them "better").
    if (!better(best.second) || insideMedian(deviationsWith(best.first)).second > kWidthSearch)
        return check;
    check.betterFilter = best.first;
    check.betterMisfit = best.second;
    check.disagrees = true;
    // Another kind the edges fit as well: a default width first, as for the best.
    const auto alike = alikeFilter(tried, best, defaults.size());
    if (alike && insideMedian(deviationsWith(alike->first)).second <= kWidthSearch)
        std::tie(check.alikeFilter, check.alikeMisfit) = *alike;
    return check;
}

}  // namespace phongfit
