// The most the process holds (its resident set) over a stretch of work: read every millisecond by
// a thread of its own, and from Linux's high-water mark (VmHWM), whichever is more.
//
// Linux (6.2 on) keeps a process's page counts per CPU and folds a CPU's part into the total only
// past a batch (32 pages on 2 CPUs, more on more); VmHWM is kept from the folded totals. On this
// 2-core machine it read a fit's peak 100-380 kB low: the whole budget of a small fit
// (docs/design/fitter.md, "Memory"). The resident set (statm) sums the CPUs' parts.
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstddef>
#include <mutex>
#include <thread>

namespace phongfit {

class ResidentPeak {
public:
    ResidentPeak();   // starts reading
    ~ResidentPeak();  // stops
    ResidentPeak(const ResidentPeak&) = delete;
    ResidentPeak& operator=(const ResidentPeak&) = delete;

    // Starts afresh, VmHWM too (resetPeakResident), from what the process holds now.
    void reset();
    // The most the process held since it started or since reset(), 0 where Linux does not say.
    std::size_t bytes();

private:
    void read();  // one reading, into most_

    int statm_ = -1;  // /proc/self/statm, read at offset 0 each time
    std::atomic<std::size_t> most_{0};
    std::mutex mutex_;
    std::condition_variable wake_;
    bool stop_ = false;
    std::thread thread_;
};

}  // namespace phongfit
