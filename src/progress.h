// Progress of a long job (render, record, fit) on stderr. On a terminal: a bar redrawn in place
// with percent, rate and ETA. Elsewhere (logs, CI, pipes): silence until finish(), then one summary
// line, so logs are not flooded with carriage returns.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <mutex>
#include <ostream>
#include <string>

namespace phongfit {

class Progress {
public:
    // Writes to stderr; draws the bar only if stderr is a terminal and the environment variable CI
    // is unset. `quiet` silences everything.
    Progress(std::string label, std::uint64_t total, std::string unit, bool quiet);
    // For tests: explicit stream, and whether to treat it as a terminal.
    Progress(std::string label, std::uint64_t total, std::string unit, bool quiet,
             std::ostream& out, bool terminal);
    // Ends an unfinished bar with a newline, so an error message that follows starts on its own
    // line.
    ~Progress();

    Progress(const Progress&) = delete;
    Progress& operator=(const Progress&) = delete;

    // Thread-safe and cheap (an atomic add; on a terminal also a clock read): call it from workers.
    void advance(std::uint64_t n = 1);
    // Prints the summary line: label, total, elapsed time, rate. Call once, when the job is done.
    void finish();

private:
    using Clock = std::chrono::steady_clock;

    void draw(std::uint64_t done, Clock::time_point now);

    std::string label_, unit_;
    std::uint64_t total_;
    bool quiet_, terminal_;
    std::ostream& out_;
    Clock::time_point start_;
    std::atomic<std::uint64_t> done_{0};
    std::atomic<Clock::rep> nextDraw_;  // ticks since start_; redraws are rate-limited to ~10/s
    std::mutex drawMutex_;
    std::size_t drawnWidth_ = 0;  // of the last bar, so finish() can overwrite all of it
    bool finished_ = false;
};

}  // namespace phongfit
