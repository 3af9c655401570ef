#include "memory_plan.h"

#include <fmt/format.h>

#include "error.h"
#include "memory_info.h"

namespace phongfit {

std::optional<std::size_t> fitMemoryAvailable(std::size_t limit) {
    if (limit > 0) {
        const std::size_t held = residentBytes();
        return limit > held ? limit - held : 0;
    }
    const std::size_t available = availableBytes();
    if (available == 0) return std::nullopt;
    return available;
}

namespace {

std::size_t pixelCount(const std::vector<Observation>& observations) {
    std::size_t pixels = 0;
    for (const Observation& o : observations)
        pixels += std::size_t(o.width) * std::size_t(o.height);
    return pixels;
}

}  // namespace

std::size_t stateBytes(const std::vector<Observation>& observations) {
    return pixelCount(observations) * kStateBytesPerPixel;
}

std::size_t leastFirstRoundBytes(const std::vector<Observation>& observations) {
    return stateBytes(observations) + pixelCount(observations) * 2 * kLeastRecordedBytesPerPixel;
}

double nextRoundBytes(std::size_t recordedBytes, double growth, std::size_t pixelsUsed) {
    return double(recordedBytes) * growth + double(kStateBytesPerPixel) * double(pixelsUsed);
}

void requireMemory(std::size_t need, std::size_t limit, const std::string& what) {
    const std::optional<std::size_t> available = fitMemoryAvailable(limit);
    if (!available || need <= *available) return;
    // A limit counts the whole process, which already holds the scene, the images and the
    // renderer: say so, or a limit below that reads as "0 MB available" with no reason.
    const std::string whence =
        limit > 0 ? fmt::format(
                        "--max-memory {:.3g} GB less the {:.1f} MB the process already "
                        "holds: scene, images, renderer",
                        double(limit) / 1e9, double(residentBytes()) / 1e6)
                  : std::string("what the machine has available");
    throw Error(
        fmt::format("{} needs at least {:.1f} MB, but only {:.1f} MB are available ({}); "
                    "use a smaller image, fewer paths, or a larger --max-memory",
                    what, double(need) / 1e6, double(*available) / 1e6, whence));
}

}  // namespace phongfit
