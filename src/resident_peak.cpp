#include "resident_peak.h"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>

#include "memory_info.h"

namespace phongfit {

namespace {

// Often enough for the phases a fit's peak lies in (a recording's copy takes milliseconds), while
// a reading (a few microseconds) costs under 1% of a core.
constexpr std::chrono::milliseconds kInterval{1};

}  // namespace

ResidentPeak::ResidentPeak() : statm_(::open("/proc/self/statm", O_RDONLY | O_CLOEXEC)) {
    read();
    if (statm_ < 0) return;
    thread_ = std::thread([this] {
        std::unique_lock lock(mutex_);
        while (!wake_.wait_for(lock, kInterval, [this] { return stop_; })) {
            lock.unlock();
            read();
            lock.lock();
        }
    });
}

ResidentPeak::~ResidentPeak() {
    {
        const std::lock_guard lock(mutex_);
        stop_ = true;
    }
    wake_.notify_one();
    if (thread_.joinable()) thread_.join();
    if (statm_ >= 0) ::close(statm_);
}

void ResidentPeak::reset() {
    resetPeakResident();
    most_.store(0);
    read();
}

std::size_t ResidentPeak::bytes() {
    read();
    return std::max(most_.load(), peakResidentBytes());
}

void ResidentPeak::read() {
    const std::size_t bytes = residentBytes(statm_);
    std::size_t seen = most_.load();
    while (bytes > seen && !most_.compare_exchange_weak(seen, bytes)) {
    }
}

}  // namespace phongfit
