#include "resident_peak.h"

#include <gtest/gtest.h>
#include <sys/mman.h>

#include <chrono>
#include <cstring>
#include <thread>

#include "memory_info.h"

namespace phongfit {
namespace {

constexpr std::size_t kHeld = std::size_t(8) << 20;
// What a reading may lack where Linux's resident set itself is kept per CPU (6.2 to 6.16): a
// batch of pages on each of a few CPUs.
constexpr std::size_t kSlack = std::size_t(1) << 20;

// Holds kHeld bytes resident for a while (a few of ResidentPeak's readings), then unmaps them.
void holdAPeak() {
    void* block = mmap(nullptr, kHeld, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    ASSERT_NE(block, MAP_FAILED);
    std::memset(block, 1, kHeld);
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    munmap(block, kHeld);
}

TEST(ResidentPeak, KeepsAPeakThatLinuxsHighWaterMarkForgot) {
    ResidentPeak peak;
    peak.reset();
    const std::size_t start = residentBytes();
    holdAPeak();
    // VmHWM starts afresh below the peak: what is left of it is the readings'.
    resetPeakResident();
    ASSERT_LT(peakResidentBytes(), start + kHeld / 2);
    EXPECT_GE(peak.bytes() + kSlack, start + kHeld);
}

TEST(ResidentPeak, StartsAfreshWhenReset) {
    ResidentPeak peak;
    holdAPeak();
    ASSERT_GE(peak.bytes() + kSlack, residentBytes() + kHeld);
    peak.reset();
    // Read before bytes(), which reads again: the resident set may grow by a few pages between.
    const std::size_t now = residentBytes();
    EXPECT_LT(peak.bytes(), now + kHeld / 2);
    EXPECT_GE(peak.bytes() + kSlack, now);
}

}  // namespace
}  // namespace phongfit
