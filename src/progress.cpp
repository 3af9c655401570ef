#include "progress.h"

#include <fmt/format.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <iostream>

namespace phongfit {
namespace {

constexpr auto kRedrawInterval = std::chrono::milliseconds(100);
constexpr int kBarWidth = 30;

bool stderrIsTerminal() { return ::isatty(STDERR_FILENO) == 1 && std::getenv("CI") == nullptr; }

// "12.3", "4.56 k", "7.8 M": rates span many orders of magnitude.
std::string siNumber(double value) {
    static constexpr const char* kPrefixes[] = {"", " k", " M", " G", " T"};
    int i = 0;
    while (std::abs(value) >= 999.5 && i < 4) {
        value /= 1000;
        ++i;
    }
    return fmt::format("{:.3g}{}", value, kPrefixes[i]);
}

// "4.20 s" below a minute, then "m:ss" and "h:mm:ss".
std::string duration(double seconds) {
    if (seconds < 60) return fmt::format("{:.2f} s", seconds);
    const auto total = static_cast<long long>(std::llround(seconds));
    if (total < 3600) return fmt::format("{}:{:02}", total / 60, total % 60);
    return fmt::format("{}:{:02}:{:02}", total / 3600, total / 60 % 60, total % 60);
}

double secondsBetween(std::chrono::steady_clock::time_point a,
                      std::chrono::steady_clock::time_point b) {
    return std::chrono::duration<double>(b - a).count();
}

}  // namespace

Progress::Progress(std::string label, std::uint64_t total, std::string unit, bool quiet)
    : Progress(std::move(label), total, std::move(unit), quiet, std::cerr, stderrIsTerminal()) {}

Progress::Progress(std::string label, std::uint64_t total, std::string unit, bool quiet,
                   std::ostream& out, bool terminal)
    : label_(std::move(label)),
      unit_(std::move(unit)),
      total_(total),
      quiet_(quiet),
      terminal_(terminal && !quiet),
      out_(out),
      start_(Clock::now()),
      nextDraw_(0) {}

Progress::~Progress() {
    std::lock_guard lock(drawMutex_);
    if (!finished_ && drawnWidth_ > 0) out_ << '\n' << std::flush;
}

void Progress::advance(std::uint64_t n) {
    const std::uint64_t done = done_.fetch_add(n, std::memory_order_relaxed) + n;
    if (!terminal_) return;
    const Clock::time_point now = Clock::now();
    Clock::rep due = nextDraw_.load(std::memory_order_relaxed);
    if ((now - start_).count() < due) return;
    // One thread wins the right to draw this frame; the others carry on.
    const Clock::rep next = (now - start_ + kRedrawInterval).count();
    if (!nextDraw_.compare_exchange_strong(due, next, std::memory_order_relaxed)) return;
    std::unique_lock lock(drawMutex_, std::try_to_lock);
    if (lock.owns_lock() && !finished_) draw(done, now);
}

void Progress::draw(std::uint64_t done, Clock::time_point now) {
    done = std::min(done, total_);
    const double fraction = total_ > 0 ? double(done) / double(total_) : 1.0;
    const int filled = static_cast<int>(fraction * kBarWidth);
    const double elapsed = secondsBetween(start_, now);
    const double rate = elapsed > 0 ? double(done) / elapsed : 0.0;
    const std::string eta = rate > 0 ? duration(double(total_ - done) / rate) : "?";
    std::string line = fmt::format("{} [{}{}] {:3.0f}%  {} {}/s  ETA {}", label_,
                                   std::string(filled, '#'), std::string(kBarWidth - filled, '.'),
                                   100 * fraction, siNumber(rate), unit_, eta);
    const std::size_t width = line.size();
    if (width < drawnWidth_) line.append(drawnWidth_ - width, ' ');  // erase a longer old bar
    drawnWidth_ = width;
    out_ << '\r' << line << std::flush;
}

void Progress::finish() {
    std::lock_guard lock(drawMutex_);
    if (finished_) return;
    finished_ = true;
    if (quiet_) return;
    const double elapsed = secondsBetween(start_, Clock::now());
    const std::uint64_t done = done_.load(std::memory_order_relaxed);
    const std::string rate = elapsed > 0 ? siNumber(double(done) / elapsed) : "inf";
    std::string line = fmt::format("{}: {} {} in {} ({} {}/s)", label_, done, unit_,
                                   duration(elapsed), rate, unit_);
    if (drawnWidth_ > 0) {
        if (line.size() < drawnWidth_) line.append(drawnWidth_ - line.size(), ' ');
        out_ << '\r';
    }
    out_ << line << '\n' << std::flush;
}

}  // namespace phongfit
