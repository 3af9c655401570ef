#include "progress.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <regex>
#include <sstream>
#include <thread>
#include <vector>

namespace phongfit {
namespace {

// "render: 100 px in 0.01 s (9.5 k px/s)"
const std::regex kSummary(R"(render: (\d+) px in [0-9.:]+( s)? \([0-9.e+-]+( [kMGT])? px/s\)\n)");

TEST(Progress, OffTerminalPrintsNothingUntilOneSummaryLine) {
    std::ostringstream out;
    Progress progress("render", 100, "px", false, out, false);
    progress.advance(40);
    progress.advance(60);
    EXPECT_EQ(out.str(), "");
    progress.finish();
    const std::string summary = out.str();
    std::smatch m;
    ASSERT_TRUE(std::regex_match(summary, m, kSummary)) << summary;
    EXPECT_EQ(m[1], "100");
    progress.finish();  // a second call adds nothing
    EXPECT_EQ(out.str(), summary);
}

TEST(Progress, QuietPrintsNothing) {
    std::ostringstream out;
    {
        Progress progress("render", 100, "px", true, out, true);
        progress.advance(50);
        progress.finish();
    }
    EXPECT_EQ(out.str(), "");
}

TEST(Progress, OnTerminalDrawsABarInPlaceThenTheSummary) {
    std::ostringstream out;
    Progress progress("render", 100, "px", false, out, true);
    progress.advance(50);  // the first advance draws at once
    const std::string bar = out.str();
    EXPECT_TRUE(std::regex_match(
        bar, std::regex(R"(\rrender \[#{15}\.{15}\]  50%  [0-9.e+-]+( [kMGT])? px/s  ETA \S+.*)")))
        << bar;
    progress.advance(50);
    progress.finish();
    const std::string all = out.str();
    const std::size_t last = all.rfind('\r');
    ASSERT_NE(last, std::string::npos);
    std::string summary = all.substr(last + 1);
    // The summary is padded with spaces to overwrite the whole bar.
    summary.erase(std::remove(summary.begin(), summary.end(), ' '), summary.end());
    EXPECT_TRUE(std::regex_match(summary, std::regex(R"(render:100pxin[0-9.:]+s?\(.*px/s\)\n)")))
        << all;
    EXPECT_GE(all.size() - last - 1, bar.size());
}

TEST(Progress, RedrawsAreRateLimited) {
    std::ostringstream out;
    Progress progress("render", 100000, "px", false, out, true);
    for (int i = 0; i < 100000; ++i) progress.advance(1);
    const std::string all = out.str();
    const auto redraws = std::count(all.begin(), all.end(), '\r');
    EXPECT_GE(redraws, 1);
    EXPECT_LT(redraws, 100);  // ~10 per second; the loop takes far less than 10 s
}

TEST(Progress, UnfinishedBarEndsItsLineWhenDestroyed) {
    std::ostringstream out;
    { Progress("render", 100, "px", false, out, true).advance(10); }
    ASSERT_FALSE(out.str().empty());
    EXPECT_EQ(out.str().back(), '\n');
}

TEST(Progress, CountsEveryAdvanceFromManyThreads) {
    std::ostringstream out;
    Progress progress("render", 40000, "px", false, out, true);
    std::vector<std::thread> threads;
    for (int t = 0; t < 4; ++t)
        threads.emplace_back([&] {
            for (int i = 0; i < 10000; ++i) progress.advance(1);
        });
    for (auto& t : threads) t.join();
    progress.finish();
    const std::string all = out.str();
    EXPECT_NE(all.find("render: 40000 px in"), std::string::npos) << all;
}

}  // namespace
}  // namespace phongfit
