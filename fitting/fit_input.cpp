#include "fit_input.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "error.h"

namespace phongfit {

void checkPathSet(const PathSet& paths, const Observation& obs, int view, int slots) {
    const auto where = [&] { return fmt::format("path set of view {}", view); };
    if (paths.width != obs.width || paths.height != obs.height)
        throw Error(fmt::format("{} is {}x{} but its image is {}x{} (they must match)", where(),
                                paths.width, paths.height, obs.width, obs.height));
    if (paths.slots != slots)
        throw Error(fmt::format("{} has {} material slots but {} materials are fitted", where(),
                                paths.slots, slots));
    const std::size_t pixels = std::size_t(obs.width) * std::size_t(obs.height);
    if (paths.background.size() != pixels || paths.pixelStart.size() != pixels + 1 ||
        paths.pixelStart.front() != 0 || paths.pixelStart.back() != paths.terms.size())
        throw Error(
            fmt::format("{}: background ({}) and pixelStart ({}) must hold {} and {} "
                        "entries, pixelStart from 0 to the term count {}",
                        where(), paths.background.size(), paths.pixelStart.size(), pixels,
                        pixels + 1, paths.terms.size()));
    for (std::size_t p = 0; p < pixels; ++p) {
        if (paths.pixelStart[p] > paths.pixelStart[p + 1])
            throw Error(fmt::format("{}: pixelStart decreases at pixel {}", where(), p));
        for (std::uint32_t t = paths.pixelStart[p]; t < paths.pixelStart[p + 1]; ++t) {
            const PathTerm& term = paths.terms[t];
            if (term.pixel != p || term.vertexCount == 0 ||
                std::size_t(term.firstVertex) + term.vertexCount > paths.vertices.size())
                throw Error(
                    fmt::format("{}: term {} (pixel {}, vertices {}+{}) is not pixel {}'s "
                                "or has no valid vertex range (there are {} vertices)",
                                where(), t, term.pixel, term.firstVertex, term.vertexCount, p,
                                paths.vertices.size()));
        }
    }
    for (std::size_t i = 0; i < paths.vertices.size(); ++i) {
        const PathVertex& v = paths.vertices[i];
        if (v.slot >= std::uint32_t(slots) || std::isnan(v.logCos) || v.logCos > 0)
            throw Error(
                fmt::format("{}: vertex {} has slot {} and log cos alpha {} (allowed: slot "
                            "< {}, log cos alpha <= 0 or -inf)",
                            where(), i, v.slot, v.logCos, slots));
    }
}

void checkObservation(const Observation& obs, int view) {
    const std::size_t pixels =
        std::size_t(std::max(obs.width, 0)) * std::size_t(std::max(obs.height, 0));
    if (obs.width <= 0 || obs.height <= 0 || obs.rgb.size() != 3 * pixels ||
        (!obs.valid.empty() && obs.valid.size() != pixels) ||
        (!obs.weight.empty() && obs.weight.size() != pixels))
        throw Error(fmt::format(
            "observation of view {}: {}x{} needs 3 values per pixel ({} given), "
            "and a mask and weights with one per pixel or none ({} and {} "
            "given)",
            view, obs.width, obs.height, obs.rgb.size(), obs.valid.size(), obs.weight.size()));
    for (std::size_t p = 0; p < obs.weight.size(); ++p)
        if (!(obs.weight[p] >= 0) || !std::isfinite(obs.weight[p]))
            throw Error(
                fmt::format("observation of view {}: weight {} at pixel ({}, {}) is invalid "
                            "(allowed: finite, >= 0)",
                            view, obs.weight[p], p % obs.width, p / obs.width));
}

}  // namespace phongfit
