// `phongfit hdr-merge` end to end: a bracketed set of 8-bit exposures made from a known linear
// image through a known response (gamma 2.2, clipped) merges back to that image up to one scale
// factor; bad input is refused with one line naming the problem.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <opencv2/imgcodecs.hpp>
#include <string>
#include <vector>

#include "image.h"
#include "subprocess.h"
#include "temp_dir.h"

namespace phongfit {
namespace {

constexpr int kWidth = 96, kHeight = 64;
const std::vector<double> kTimes = {1.0 / 64, 1.0 / 16, 1.0 / 4, 1.0, 4.0};

// Radiance spanning four decades: log-spaced across x, a different slope per channel, and a
// vertical ripple so each row differs.
Color3 radiance(int x, int y) {
    const double base = std::pow(10.0, -2.5 + 4.0 * x / (kWidth - 1));
    const double ripple = 1 + 0.3 * std::sin(0.4 * y);
    return Color3(base * ripple, 0.7 * base * ripple, 0.4 * base / ripple);
}

// The camera: value = (radiance * time)^(1 / 2.2), clipped to [0, 1], quantised to 8 bits.
void writeExposure(const std::string& path, double time) {
    cv::Mat image(kHeight, kWidth, CV_8UC3);
    for (int y = 0; y < kHeight; ++y)
        for (int x = 0; x < kWidth; ++x) {
            const Color3 e = radiance(x, y) * time;
            for (int c = 0; c < 3; ++c)
                image.at<cv::Vec3b>(y, x)[2 - c] = cv::saturate_cast<uchar>(
                    std::lround(255 * std::pow(std::clamp(e[c], 0.0, 1.0), 1 / 2.2)));
        }
    cv::imwrite(path, image);
}

class HdrMerge : public ::testing::Test {
protected:
    void SetUp() override {
        for (std::size_t i = 0; i < kTimes.size(); ++i) {
            images_.push_back(dir_.at("exposure" + std::to_string(i) + ".png"));
            writeExposure(images_.back(), kTimes[i]);
        }
    }
    static std::string times(const std::vector<double>& t) {
        std::string s;
        for (double v : t) {
            if (!s.empty()) s += ',';
            s += std::to_string(v);
        }
        return s;
    }
    test::ProcessResult run(std::vector<std::string> args) const {
        args.insert(args.begin(), "hdr-merge");
        return test::runPhongfit(args);
    }

    test::TempDir dir_{"hdr_merge"};
    std::vector<std::string> images_;
};

TEST_F(HdrMerge, MergedImageIsProportionalToTheRadiance) {
    std::vector<std::string> args = images_;
    args.insert(args.end(), {"--times", times(kTimes), "-o", dir_.at("merged.exr")});
    const auto r = run(args);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    const Image merged = readImage(dir_.at("merged.exr"));
    ASSERT_EQ(merged.width, kWidth);
    ASSERT_EQ(merged.height, kHeight);

    // Pixels some exposure sees unclipped and above the 8-bit noise floor.
    std::vector<double> ratios;
    for (int y = 0; y < kHeight; ++y)
        for (int x = 0; x < kWidth; ++x) {
            const Color3 l = radiance(x, y);
            for (int c = 0; c < 3; ++c) {
                const bool seen = std::any_of(kTimes.begin(), kTimes.end(), [&](double t) {
                    return l[c] * t > 0.02 && l[c] * t < 0.9;
                });
                if (seen) ratios.push_back(merged.at(x, y)[c] / l[c]);
            }
        }
    ASSERT_GT(ratios.size(), std::size_t(kWidth * kHeight * 2));
    // Debevec's response is recovered up to a scale (the median ratio) and is least certain near
    // the ends of the 8-bit range, so a few pixels stray further than most.
    std::vector<double> sorted = ratios;
    std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
    const double scale = sorted[sorted.size() / 2];
    ASSERT_TRUE(std::isfinite(scale) && scale > 0);
    std::vector<double> errors;
    for (double q : ratios) errors.push_back(std::abs(q / scale - 1));
    std::sort(errors.begin(), errors.end());
    EXPECT_LT(errors[errors.size() / 2], 0.02);
    EXPECT_LT(errors[errors.size() * 9 / 10], 0.12);
}

TEST_F(HdrMerge, BadInputIsRefusedWithOneLineAndNothingWritten) {
    cv::imwrite(dir_.at("small.png"), cv::Mat(kHeight / 2, kWidth, CV_8UC3, cv::Scalar(9, 9, 9)));
    cv::imwrite(dir_.at("deep.png"), cv::Mat(kHeight, kWidth, CV_16UC3, cv::Scalar(9, 9, 9)));
    dir_.write("garbage.png", "not an image");
    const std::string out = dir_.at("refused.exr");
    struct Case {
        std::vector<std::string> args;
        std::string fragment;
    };
    const std::vector<Case> cases = {
        {{images_[0], images_[1], images_[2], "--times", "1,2"},
         "--times has 2 values for 3 images"},
        {{images_[0], images_[1], "--times", "1,0"}, "--times: 0"},
        {{images_[0], images_[1], "--times", "-1,2"}, "--times: -1"},
        {{images_[0], dir_.at("garbage.png"), "--times", "1,2"}, "garbage.png"},
        {{images_[0], dir_.at("missing.png"), "--times", "1,2"}, "missing.png': no such file"},
        {{images_[0], dir_.at("small.png"), "--times", "1,2"}, "small.png' is 96x32"},
        {{images_[0], dir_.at("deep.png"), "--times", "1,2"}, "deep.png' is not 8-bit"},
        {{images_[0], "--times", "1"}, "at least two exposures"},
    };
    for (const Case& c : cases) {
        std::vector<std::string> args = c.args;
        args.insert(args.end(), {"-o", out});
        const auto r = run(args);
        EXPECT_NE(r.exitCode, 0) << c.fragment;
        EXPECT_NE(r.err.find(c.fragment), std::string::npos)
            << "expected '" << c.fragment << "' in: " << r.err;
        EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
        EXPECT_FALSE(std::filesystem::exists(out)) << c.fragment;
    }
    const auto r = run({images_[0], images_[1], "--times", "1,2", "-o", dir_.at("merged.png")});
    EXPECT_NE(r.err.find("written as EXR"), std::string::npos) << r.err;
}

}  // namespace
}  // namespace phongfit
