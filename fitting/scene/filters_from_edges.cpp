#include "filters_from_edges.h"

#include <cmath>
#include <opencv2/imgproc.hpp>

#include "film_window.h"
#include "render_sidecar.h"

namespace phongfit {

namespace {

// Per view whose film names no filter, whose image no sidecar describes (filterAssumed) and whose
// filter was not taken from its edges already: `pick` of its edge check. Empty where none picks
// one.
template <typename Pick>
std::vector<std::optional<PixelFilter>> perAssumedView(const SceneFitProblem& problem,
                                                       const FitResult& result, Pick pick) {
    std::vector<std::optional<PixelFilter>> filters(problem.views.size());
    bool any = false;
    for (std::size_t k = 0; k < problem.views.size() && k < result.edgeChecks.size(); ++k) {
        const SceneView& v = problem.views[k];
        if (v.filterFromEdges || !filterAssumed(v.renderer->scene().sensor, v.renderedAs)) continue;
        filters[k] = pick(result.edgeChecks[k]);
        any = any || filters[k].has_value();
    }
    return any ? filters : std::vector<std::optional<PixelFilter>>{};
}

}  // namespace

std::vector<std::optional<PixelFilter>> edgeFilters(const SceneFitProblem& problem,
                                                    const FitResult& result) {
    return perAssumedView(problem, result, [](const EdgeCheck& e) { return e.betterFilter; });
}

std::vector<std::optional<PixelFilter>> untoldFilters(const SceneFitProblem& problem,
                                                      const FitResult& result) {
    return perAssumedView(problem, result, [](const EdgeCheck& e) -> std::optional<PixelFilter> {
        if (e.betterFilter) return std::nullopt;
        return PixelFilter{SensorDesc::Filter::Gaussian,
                           pixelFilterName(SensorDesc::Filter::Gaussian).defaultWidth};
    });
}

std::vector<std::optional<PixelFilter>> alikeFilters(const SceneFitProblem& problem,
                                                     const FitResult& result) {
    std::vector<std::optional<PixelFilter>> filters = edgeFilters(problem, result);
    bool any = false;
    for (std::size_t k = 0; k < filters.size(); ++k)
        if (const auto& alike = result.edgeChecks[k].alikeFilter; filters[k] && alike) {
            filters[k] = alike;
            any = true;
        }
    return any ? filters : std::vector<std::optional<PixelFilter>>{};
}

ImageResiduals imageResiduals(const SceneFitProblem& first, const FitResult& firstFit,
                              const SceneFitProblem& second, const FitResult& secondFit,
                              const SceneRecording& recording) {
    // Per value, each fit's residual against two independent renders multiplied (the renders' noise
    // out of its expectation, as the cross products of a round), and their difference.
    double products[2] = {0, 0}, differences = 0, differenceSquares = 0;
    std::size_t values = 0;
    for (std::size_t k = 0; k < first.views.size() && k < second.views.size(); ++k) {
        const Observation& o = first.views[k].observation;
        // Inside the silhouettes, by the widest reach of the two filters: at a silhouette a
        // pixel's value is the share of its footprint each side covers, which the edge check
        // has weighed; inside, a highlight that varies over a pixel shows the filter's shape.
        cv::Mat inside(o.height, o.width, CV_8U);
        for (std::size_t p = 0; p < o.valid.size(); ++p) inside.data[p] = first.views[k].direct[p];
        const int reach = std::max(filterReach(first.views[k].renderer->scene().sensor),
                                   filterReach(second.views[k].renderer->scene().sensor));
        cv::erode(inside, inside, cv::Mat::ones(2 * reach + 1, 2 * reach + 1, CV_8U));
        std::vector<std::uint8_t> both(o.valid.size());
        for (std::size_t p = 0; p < both.size(); ++p)
            both[p] = o.valid[p] && second.views[k].observation.valid[p] && inside.data[p];
        // Each fit's estimate, rendered as its view's image was.
        const SceneView* views[2] = {&first.views[k], &second.views[k]};
        const FitResult* fits[2] = {&firstFit, &secondFit};
        RenderOptions options[2];
        for (int f = 0; f < 2; ++f) {
            options[f] = renderOptionsAt(*views[f], fits[f]->fittedMaterials(), recording.threads);
            options[f].spp = kResidualSpp;
        }
        // Band by band of rows, each pixel's samples its own whatever the window: what is held
        // stays small beside a large film's fit.
        const FilmWindow all = boundingWindow(both, o.width, o.height);
        for (int y0 = all.y0; y0 < all.y0 + all.height; y0 += kResidualRows) {
            const FilmWindow band{all.x0, y0, all.width,
                                  std::min(kResidualRows, all.y0 + all.height - y0)};
            const std::vector<std::uint8_t> rendered = cropped(both, o.width, band);
            const auto renderAt = [&](int f, std::uint64_t r) {
                RenderOptions at = options[f];
                at.seed = recording.seed * 7919 + 1299709 + r;  // apart from the recordings
                at.window = band;
                at.rendered = rendered;
                RenderResult out = views[f]->renderer->render(at);
                const double exposure = fits[f]->exposureValue();
                for (float& x : out.rgb) x = float(exposure * x);
                return out.rgb;
            };
            const std::vector<float> renders[2][2] = {{renderAt(0, 0), renderAt(0, 1)},
                                                      {renderAt(1, 0), renderAt(1, 1)}};
            for (std::size_t q = 0; q < band.pixels(); ++q) {
                if (!rendered[q]) continue;
                const std::size_t p =
                    std::size_t(band.y0 + int(q) / band.width) * std::size_t(o.width) +
                    std::size_t(band.x0 + int(q) % band.width);
                for (std::size_t c = 0; c < 3; ++c) {
                    double product[2];
                    for (int f = 0; f < 2; ++f) {
                        product[f] = (o.rgb[3 * p + c] - renders[f][0][3 * q + c]) *
                                     (o.rgb[3 * p + c] - renders[f][1][3 * q + c]);
                        products[f] += product[f];
                    }
                    differences += product[0] - product[1];
                    differenceSquares += std::pow(product[0] - product[1], 2);
                    ++values;
                }
            }
        }
    }
    ImageResiduals out;
    if (values < 2) return out;
    const double n = double(values), mean = differences / n;
    out.first = std::sqrt(std::max(products[0] / n, 0.0));
    out.second = std::sqrt(std::max(products[1] / n, 0.0));
    const double standardError =
        std::sqrt(std::max(differenceSquares / n - mean * mean, 0.0) / (n - 1));
    out.secondBetter = mean > kResidualEvidence * standardError;
    out.firstBetter = -mean > kResidualEvidence * standardError;
    return out;
}

void holdBothFilters(FitResult& kept, const FitResult& other) {
    bool moved = false;
    const auto hold = [&moved](double& std, double difference) {
        moved = moved || std::abs(difference) > std;
        std = std::hypot(std, difference);
    };
    for (std::size_t s = 0; s < kept.materials.size() && s < other.materials.size(); ++s) {
        MaterialFit& m = kept.materials[s];
        const MaterialFit& o = other.materials[s];
        for (int c = 0; c < 3; ++c) {
            hold(m.kdStd[c], m.kd[c] - o.kd[c]);
            hold(m.ksStd[c], m.ks[c] - o.ks[c]);
        }
        if (m.n > 0 && o.n > 0 && !m.isUnconstrained("n")) {
            hold(m.nStd, m.n - o.n);
            hold(m.logNStd, std::log(m.n / o.n));
        }
    }
    if (kept.converged && moved) {
        kept.converged = false;
        kept.stopReason = "pixel filter unresolved";
    }
}

}  // namespace phongfit
