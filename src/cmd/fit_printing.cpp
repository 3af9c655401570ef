#include "fit_printing.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <filesystem>

#include "comparison_image.h"
#include "edge_agreement.h"
#include "path_growth.h"

namespace phongfit {

namespace {

std::string notConvergedBecause(const FitResult& result) {
    if (result.stopReason == "time budget") return "the time budget was spent";
    if (result.stopReason == "memory")
        return "the next round's paths would not fit in the memory left (--max-memory)";
    if (result.stopReason == "interrupted") return "interrupted";
    if (result.stopReason == "images disagree")
        return "the estimate settled, but the images disagree with their scenes where the "
               "scenes' edges cross pixels (see the warning above)";
    if (result.stopReason == "pixel filter unresolved")
        return "the film names no pixel filter, and the fits with the two its image's edges fit "
               "alike (above) differ by more than their standard errors, which are raised to hold "
               "both; name the image's filter in the film's <rfilter>";
    if (result.stopReason == "precision not met")
        return fmt::format(
            "the estimate stopped moving, but not every parameter is as precise as --precision "
            "asks after {} rounds (--rounds)",
            result.rounds.size());
    if (result.stopReason == "rounds disagree")
        return "the last round was as precise as --precision asks, but the last rounds' "
               "estimates scatter by more, and the standard errors are raised to that scatter";
    if (result.stopReason == "path cap")
        return fmt::format(
            "the estimate stopped moving, but not every parameter is as precise as --precision "
            "asks, and the pixels that inform it already hold the most paths a recording gives a "
            "pixel ({} more than the first round's): more paths would not halve the variance",
            kMostExtraPaths);
    if (result.stopReason == "unresolved") {
        // An n no lobe holds is listed unconstrained, with its standard error at least n.
        std::vector<std::string> names;
        for (const MaterialFit& m : result.materials) {
            std::vector<std::string> unresolved = unresolvedParameters(m);
            if (exponentListedForNoLobe(m)) unresolved.push_back("n");
            for (const std::string& name : unresolved)
                if (std::find(names.begin(), names.end(), name) == names.end())
                    names.push_back(name);
        }
        return fmt::format(
            "the estimate stopped moving, but {} {} standard errors as large as {} values (more "
            "paths, --spp or --adaptive-spp, may resolve them)",
            fmt::join(names, ", "), names.size() == 1 ? "has" : "have",
            names.size() == 1 ? "its" : "their");
    }
    const std::size_t rounds = result.rounds.size();
    if (result.stopReason == "sharper lobe" && result.rounds.back().probe)
        return fmt::format(
            "{} rounds spent (--rounds): the last, recorded at a sharper lobe, did not come "
            "back to this estimate",
            rounds);
    if (result.stopReason == "sharper lobe")
        return fmt::format(
            "{} rounds spent (--rounds) just as a round recorded at a sharper lobe than the "
            "converged one moved the estimate there",
            rounds);
    return fmt::format("{} round{} spent and the last still moved", rounds, rounds == 1 ? "" : "s");
}

// How a converged fit ended, after "converged".
std::string convergedHow(const FitResult& result) {
    if (result.stopReason == "precision") return ": precision reached";
    if (result.stopReason == "noise floor")
        return " at the images' noise floor: more paths cannot meet --precision";
    return "";
}

}  // namespace

void printRound(const FitRound& r, const SceneFitProblem& problem, bool fitExposure) {
    std::string params;
    for (std::size_t s = 0; s < r.materials.size(); ++s)
        params += fmt::format(
            "  {}: kd {:.4g} ± {:.2g} ks {:.4g} ± {:.2g} n {:.4g} ± {:.2g}", problem.materials[s],
            r.materials[s].kd.mean(), r.materials[s].kdStd.maxCoeff(), r.materials[s].ks.mean(),
            r.materials[s].ksStd.maxCoeff(), r.materials[s].n, r.materials[s].nStd);
    if (fitExposure) params += fmt::format("  exposure {:.4g}", r.exposure.value);
    fmt::print(stderr,
               "round {}{}: rmse {:.5g}, {} iterations of {:.3f} s, {:.2f} s, {:.3g} paths "
               "({:.1f} MB), peak {:.0f} MB{}\n",
               r.round + 1, r.probe ? " (sharper probe)" : "", r.rmse, r.iterations,
               r.secondsPerIteration, r.timeSeconds, double(r.paths), r.recordedBytes / 1e6,
               r.peakMemoryBytes / 1e6, params);
}

std::string unconstrainedNote(const MaterialFit& m) {
    const bool noLobe = exponentListedForNoLobe(m);
    std::vector<std::string> held;
    for (const std::string& name : m.unconstrained)
        if (!(noLobe && name == "n")) held.push_back(name);
    if (held.empty() && !noLobe) return "";
    std::string note = held.empty() ? "" : fmt::format("held: {}", fmt::join(held, ", "));
    if (noLobe) note += fmt::format("{}n: no lobe holds it", note.empty() ? "" : "; ");
    return fmt::format("  (unconstrained, {})", note);
}

void printSceneWarnings(const SceneFitProblem& problem) {
    for (const SceneView& v : problem.views)
        if (filterAssumed(v.renderer->scene().sensor, v.renderedAs))
            fmt::print(
                "warning: {}: the film names no <rfilter>, so {} is fitted as rendered with a box "
                "pixel filter, phongfit's default; Mitsuba 0.6's is a Gaussian (stddev 0.5 "
                "pixels), and an image filtered so but fitted as a box gives a confidently wrong "
                "lobe: name the image's filter\n",
                v.scenePath, v.imagePath);
}

void printEdgeFilters(const SceneFitProblem& problem, const FitResult& result,
                      const std::vector<std::optional<PixelFilter>>& filters) {
    for (std::size_t k = 0; k < filters.size() && k < result.edgeChecks.size(); ++k)
        if (filters[k])
            fmt::print(
                "{}: its edges, rendered anew at the estimate, fit a {} pixel filter far better "
                "than phongfit's box (squared deviations {:.4g} against {:.4g}), and neither the "
                "film nor a sidecar names one: fitted again with it\n",
                problem.views[k].imagePath, pixelFilterLabel(*filters[k]),
                result.edgeChecks[k].betterMisfit, result.edgeChecks[k].misfit);
}

void printAlikeFilters(const SceneFitProblem& problem, const std::vector<EdgeCheck>& checks,
                       const std::vector<std::optional<PixelFilter>>& named,
                       const std::vector<std::optional<PixelFilter>>& alike) {
    for (std::size_t k = 0; k < alike.size() && k < checks.size(); ++k)
        if (checks[k].alikeFilter && alike[k] && named[k])
            fmt::print(
                "{}: its edges fit a {} pixel filter as well as the {} (squared deviations {:.4g} "
                "against {:.4g}): fitted with it too, the fit that holds the image better kept\n",
                problem.views[k].imagePath, pixelFilterLabel(*alike[k]),
                pixelFilterLabel(*named[k]), checks[k].alikeMisfit, checks[k].betterMisfit);
}

void printUntoldFilters(const SceneFitProblem& problem,
                        const std::vector<std::optional<PixelFilter>>& untold) {
    for (std::size_t k = 0; k < untold.size() && k < problem.views.size(); ++k)
        if (untold[k])
            fmt::print(
                "{}: its edges do not tell phongfit's box from a {} pixel filter, and neither the "
                "film nor a sidecar names one: fitted with it too, the fit that holds the image "
                "better kept\n",
                problem.views[k].imagePath, pixelFilterLabel(*untold[k]));
}

void printFilterChoice(const SceneFitProblem& problem,
                       const std::vector<std::optional<PixelFilter>>& named,
                       const std::vector<std::optional<PixelFilter>>& alike,
                       const ImageResiduals& residuals) {
    const bool alikeKept = residuals.secondBetter;
    std::vector<std::string> labels;
    for (std::size_t k = 0; k < named.size() && k < problem.views.size(); ++k)
        if (const auto& kept = alikeKept ? alike[k] : named[k]; kept)
            labels.push_back(
                fmt::format("{} for {}", pixelFilterLabel(*kept), problem.views[k].imagePath));
    const double kept = alikeKept ? residuals.second : residuals.first;
    const double other = alikeKept ? residuals.first : residuals.second;
    fmt::print(
        "kept the fit with the {}: its estimate, rendered anew, differs from the images by {:.4g} "
        "rms, the other's by {:.4g}{}\n",
        fmt::join(labels, ", "), kept, other,
        residuals.firstBetter || residuals.secondBetter
            ? ""
            : " (within the renders' noise: the edges' choice kept)");
}

namespace {

// An image that disagrees with its scene where the scene's edges cross pixels (edge_agreement.h).
void printEdgeWarning(const SceneView& v, const EdgeCheck& e) {
    if (!e.disagrees) return;
    const SensorDesc& film = v.renderer->scene().sensor;
    const std::string stated = pixelFilterJson(pixelFilterOf(film)).dump();
    if (e.betterFilter)
        fmt::print(
            "warning: {} disagrees with {} where its edges cross pixels: rendered anew at this "
            "estimate with a {} pixel filter, {} edge pixels fit the image far better than with "
            "the scene's {} (squared deviations {:.4g} against {:.4g}): the estimate is likely "
            "wrong; name the image's filter in the film's <rfilter>\n",
            v.imagePath, v.scenePath, pixelFilterLabel(*e.betterFilter), e.pixels, stated,
            e.betterMisfit, e.misfit);
    else
        fmt::print(
            "warning: {} disagrees with {} where its edges cross pixels: rendered anew at this "
            "estimate, {} edge pixels differ from the image by a median {:.1f} times their "
            "noise: the estimate is likely wrong; check the camera, the shapes and the film's "
            "pixel filter\n",
            v.imagePath, v.scenePath, e.pixels, e.medianDeviation);
}

}  // namespace

void printSceneFit(const SceneFitProblem& problem, const FitResult& result, bool grey,
                   const std::string& dir) {
    for (std::size_t s = 0; s < result.materials.size(); ++s) {
        const MaterialFit& m = result.materials[s];
        fmt::print("{}: kd = {}, ks = {}, n = {:.5g} ± {:.2g}{}\n", problem.materials[s],
                   formatColor(m.kd, m.kdStd, grey), formatColor(m.ks, m.ksStd, grey), m.n, m.nStd,
                   unconstrainedNote(m));
    }
    if (result.exposure)
        fmt::print("exposure = {:.5g} ± {:.2g}{}\n", result.exposure->value, result.exposure->std,
                   result.exposure->unconstrained
                       ? "  (unconstrained: the images cannot tell it from the scale of kd and "
                         "ks; held where the start materials match their brightness, or as far "
                         "above as kd + ks <= 1 needs)"
                       : "");
    // The pixels left out, by why, where any were (fit.json has each view's).
    std::size_t noData = 0, masked = 0, clipped = 0, nonFinite = 0, indirect = 0;
    for (const SceneView& v : problem.views) {
        noData += v.noData, masked += v.masked, clipped += v.clipped;
        nonFinite += v.nonFinite, indirect += v.offMaterials;
    }
    for (std::size_t k = 0; k < result.edgeChecks.size() && k < problem.views.size(); ++k)
        printEdgeWarning(problem.views[k], result.edgeChecks[k]);
    std::string leftOut = problem.views[0].depthNote;
    for (const auto& [count, why] : {
             std::pair{noData, "outside the image's data window"},
             std::pair{masked, "masked"},
             std::pair{clipped, "clipped (at the format's maximum or --saturation)"},
             std::pair{nonFinite, "not finite (--ignore-nonfinite)"},
             std::pair{indirect,
                       "off the fitted materials (seeing them only through other "
                       "surfaces, if at all)"},
         })
        if (count > 0) leftOut += fmt::format("; {} pixels {}", count, why);
    fmt::print("rmse {:.5g} after {} round{}{} in {:.2f} s; left out: {} -> {}\n", result.rmse,
               result.rounds.size(), result.rounds.size() == 1 ? "" : "s",
               result.converged ? fmt::format(" (converged{})", convergedHow(result))
                                : fmt::format(" (not converged: {})", notConvergedBecause(result)),
               result.timeSeconds, leftOut, (std::filesystem::path(dir) / "fit.json").string());
}

}  // namespace phongfit
