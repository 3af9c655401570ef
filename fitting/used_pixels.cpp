#include "used_pixels.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "error.h"

namespace phongfit {

namespace {
bool finite(const Color<float>& c) { return c.allFinite(); }
}  // namespace

UsedPixels selectUsedPixels(const std::vector<Observation>& observations, const SetLists& sets,
                            int slots, int radius, const ExposureBlock& exposure) {
    if (slots > kMaxSlots)
        throw Error(
            fmt::format("{} fitted materials; at most {} can be fitted at once", slots, kMaxSlots));
    const int exposureSlot = exposure.slot();
    UsedPixels prep;
    prep.slotSeen.assign(slots, false);
    std::size_t masked = 0, nonFinite = 0, noMaterial = 0;
    double sum = 0, sumSquares = 0;
    std::vector<std::uint32_t> used;
    for (std::size_t view = 0; view < observations.size(); ++view) {
        const Observation& obs = observations[view];
        const int width = obs.width, height = obs.height;
        const std::size_t pixels = std::size_t(width) * std::size_t(height);
        prep.widths.push_back(width);
        prep.heights.push_back(height);
        prep.index.emplace_back(pixels, -1);
        // Per pixel, the slots its own vertices use (in either set), and whether it is usable.
        std::vector<std::uint32_t> ownStart(pixels + 1, 0), own;
        std::vector<std::uint8_t> usable(pixels, 0);
        for (std::size_t p = 0; p < pixels; ++p) {
            ownStart[p] = std::uint32_t(own.size());
            const double weight = obs.weight.empty() ? 1.0 : obs.weight[p];
            if ((!obs.valid.empty() && obs.valid[p] == 0) || weight == 0) {
                ++masked;
                continue;
            }
            bool ok = finite(Color<float>(obs.rgb[3 * p], obs.rgb[3 * p + 1], obs.rgb[3 * p + 2]));
            bool lit = false;
            used.clear();
            for (const std::vector<PathSet>* set : sets) {
                const PathSet& ps = (*set)[view];
                ok = ok && finite(ps.background[p]);
                lit = lit || (ps.background[p] != 0.0f).any() ||
                      ps.pixelStart[p + 1] > ps.pixelStart[p];
                for (std::uint32_t t = ps.pixelStart[p]; ok && t < ps.pixelStart[p + 1]; ++t) {
                    const PathTerm& term = ps.terms[t];
                    ok = finite(term.constant);
                    for (std::uint32_t k = 0; k < term.vertexCount; ++k)
                        used.push_back(ps.vertices[term.firstVertex + k].slot);
                }
            }
            if (!ok) {
                ++nonFinite;
                continue;
            }
            usable[p] = 1;
            if (exposureSlot >= 0 && lit) used.push_back(std::uint32_t(exposureSlot));
            std::sort(used.begin(), used.end());
            used.erase(std::unique(used.begin(), used.end()), used.end());
            own.insert(own.end(), used.begin(), used.end());
        }
        ownStart[pixels] = std::uint32_t(own.size());
        for (std::size_t p = 0; p < pixels; ++p) {
            if (!usable[p]) continue;
            const int x = int(p % std::size_t(width)), y = int(p / std::size_t(width));
            used.clear();
            for (int yy = std::max(y - radius, 0); yy <= std::min(y + radius, height - 1); ++yy)
                for (int xx = std::max(x - radius, 0); xx <= std::min(x + radius, width - 1);
                     ++xx) {
                    const std::size_t q = std::size_t(yy) * std::size_t(width) + std::size_t(xx);
                    used.insert(used.end(), own.begin() + ownStart[q],
                                own.begin() + ownStart[q + 1]);
                }
            if (used.empty()) {
                ++noMaterial;
                continue;
            }
            std::sort(used.begin(), used.end());
            used.erase(std::unique(used.begin(), used.end()), used.end());
            UsedPixel u;
            u.view = std::uint32_t(view);
            u.pixel = std::uint32_t(p);
            u.slotBegin = std::uint32_t(prep.slots.size());
            u.slotCount = std::uint16_t(used.size());
            u.seesMaterial = ownStart[p + 1] > ownStart[p];
            for (std::uint32_t s : used) prep.slotSeen[s] = true;
            prep.index.back()[p] = std::int32_t(prep.pixels.size());
            prep.slots.insert(prep.slots.end(), used.begin(), used.end());
            prep.pixels.push_back(u);
            if (!u.seesMaterial) continue;
            ++prep.seeingMaterial;
            const Color3 observed = pixelObserved(obs, u.pixel);
            sum += observed.sum();
            const double weight = pixelWeight(obs, u.pixel);
            sumSquares += weight * weight * observed.square().sum();
        }
    }
    prep.pixels.shrink_to_fit();
    prep.slots.shrink_to_fit();
    std::stable_partition(prep.pixels.begin(), prep.pixels.end(),
                          [](const UsedPixel& u) { return u.seesMaterial; });
    for (std::size_t i = 0; i < prep.pixels.size(); ++i)
        prep.index[prep.pixels[i].view][prep.pixels[i].pixel] = std::int32_t(i);
    if (prep.pixels.empty())
        throw Error(
            fmt::format("no pixel of any view can be fitted: {} masked, {} not finite, {} "
                        "not seen through a fitted material",
                        masked, nonFinite, noMaterial));
    prep.leftOut = {
        {"masked", masked}, {"non_finite", nonFinite}, {"no_fitted_material", noMaterial}};
    const double values = 3.0 * double(prep.seeingMaterial);
    prep.meanObserved = sum / values;
    prep.rmsObserved = std::sqrt(sumSquares / values);
    return prep;
}

}  // namespace phongfit
