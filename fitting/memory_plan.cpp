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

void requireMemory(std::size_t need, std::optional<std::size_t> available,
                   const std::string& what) {
    if (!available || need <= *available) return;
    throw Error(
        fmt::format("{} needs at least {:.1f} MB, but only {:.1f} MB are available (a "
                    "smaller image, fewer paths, or a larger --max-memory)",
                    what, double(need) / 1e6, double(*available) / 1e6));
}

}  // namespace phongfit
