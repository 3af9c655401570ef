#include "pixel_sums.h"

#include <gtest/gtest.h>
#include <tbb/task_arena.h>

#include <Eigen/Core>
#include <cmath>
#include <cstring>
#include <mutex>
#include <random>
#include <vector>

namespace phongfit {
namespace {

// Terms of very different magnitudes, so that another order of additions changes the rounding.
std::vector<double> terms(std::size_t count) {
    std::mt19937 rng(5);
    std::uniform_real_distribution<double> mantissa(-1, 1);
    std::uniform_int_distribution<int> exponent(-30, 30);
    std::vector<double> t(count);
    for (double& v : t) v = std::ldexp(mantissa(rng), exponent(rng));
    return t;
}

struct Sums {
    double sum = 0;
    Eigen::Vector2d moments = Eigen::Vector2d::Zero();
    Sums& operator+=(const Sums& other) {
        sum += other.sum;
        moments += other.moments;
        return *this;
    }
};

Sums sumWith(int threads, const std::vector<double>& t) {
    tbb::task_arena arena(threads);
    return sumOverPixels(
        arena, t.size(), Sums{}, [] { return 0; },
        [&](std::size_t i, Sums& sum, int&) {
            sum.sum += t[i];
            sum.moments += Eigen::Vector2d(t[i] * t[i], std::sin(t[i]));
        });
}

bool sameBits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

TEST(PixelSums, BitIdenticalWhateverTheThreadCount) {
    const std::vector<double> t = terms(100003);
    const Sums one = sumWith(1, t);
    for (int threads : {2, 3, 8}) {
        for (int repeat = 0; repeat < 3; ++repeat) {
            const Sums many = sumWith(threads, t);
            EXPECT_TRUE(sameBits(one.sum, many.sum)) << threads << " threads";
            EXPECT_TRUE(sameBits(one.moments[0], many.moments[0])) << threads << " threads";
            EXPECT_TRUE(sameBits(one.moments[1], many.moments[1])) << threads << " threads";
        }
    }
    // And it is the sum, up to rounding.
    long double exact = 0;
    for (double v : t) exact += v;
    EXPECT_NEAR(one.sum, double(exact), 1e-6 * std::abs(double(exact)) + 1e-3);
}

TEST(PixelSums, ScratchIsMadePerBlockAndNoPixelIsSkippedOrRepeated) {
    const std::size_t count = 10 * kPixelBlock + 17;
    tbb::task_arena arena(4);
    std::vector<int> visits(count, 0);
    int scratches = 0;
    const int total = sumOverPixels(
        arena, count, 0,
        [&] {
            static std::mutex mutex;
            std::lock_guard<std::mutex> lock(mutex);
            ++scratches;
            return 0;
        },
        [&](std::size_t i, int& sum, int&) {
            ++visits[i];
            ++sum;
        });
    EXPECT_EQ(total, int(count));
    for (std::size_t i = 0; i < count; ++i) EXPECT_EQ(visits[i], 1) << i;
    // Blocks hold at most kPixelBlock pixels, and are not split further than halving does.
    EXPECT_GE(scratches, int((count + kPixelBlock - 1) / kPixelBlock));
    EXPECT_LE(scratches, int(2 * count / kPixelBlock));
}

TEST(PixelSums, NoPixelsGiveZero) {
    tbb::task_arena arena(2);
    EXPECT_EQ(sumOverPixels(
                  arena, 0, 7, [] { return 0; }, [](std::size_t, int&, int&) {}),
              7);
}

}  // namespace
}  // namespace phongfit
