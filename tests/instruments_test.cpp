#include "instruments.h"

#include <gtest/gtest.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <random>
#include <vector>

namespace phongfit {
namespace {

// Two views of different sizes; about half their pixels used, 3 in 4 of those seeing a material,
// each with a sorted subset of 3 slots (the ones seeing none still have slots: their
// neighbours'). Pixels listed in a shuffled order, as the index allows.
UsedPixels randomPixels(std::mt19937& rng) {
    UsedPixels prep;
    prep.widths = {9, 4};
    prep.heights = {6, 11};
    std::bernoulli_distribution used(0.5), sees(0.75), hasSlot(0.6);
    for (std::uint32_t view = 0; view < 2; ++view) {
        const int pixels = prep.widths[view] * prep.heights[view];
        prep.index.emplace_back(std::size_t(pixels), -1);
        for (int p = 0; p < pixels; ++p) {
            if (!used(rng)) continue;
            UsedPixel u;
            u.view = view;
            u.pixel = std::uint32_t(p);
            u.slotBegin = std::uint32_t(prep.slots.size());
            for (std::uint32_t s = 0; s < 3; ++s)
                if (hasSlot(rng)) prep.slots.push_back(s);
            if (prep.slots.size() == u.slotBegin) prep.slots.push_back(1);
            u.slotCount = std::uint16_t(prep.slots.size() - u.slotBegin);
            u.seesMaterial = sees(rng);
            prep.pixels.push_back(u);
        }
    }
    std::shuffle(prep.pixels.begin(), prep.pixels.end(), rng);
    for (std::size_t i = 0; i < prep.pixels.size(); ++i)
        prep.index[prep.pixels[i].view][prep.pixels[i].pixel] = std::int32_t(i);
    return prep;
}

// The average as smoothJacobians states it, out of place: over the pixels of the window around,
// clipped to the view, those used and seeing a material that list the slot (the rest count 0).
std::vector<StoredJacobian> averaged(const UsedPixels& prep,
                                     const std::vector<StoredJacobian>& jacobians) {
    std::vector<StoredJacobian> out(jacobians.size());
    for (const UsedPixel& u : prep.pixels) {
        const int width = prep.widths[u.view], height = prep.heights[u.view];
        const int x = int(u.pixel) % width, y = int(u.pixel) / width;
        for (std::uint32_t a = 0; a < u.slotCount; ++a) {
            Eigen::Matrix3d sum = Eigen::Matrix3d::Zero();
            int count = 0;
            for (int yy = y - kInstrumentRadius; yy <= y + kInstrumentRadius; ++yy)
                for (int xx = x - kInstrumentRadius; xx <= x + kInstrumentRadius; ++xx) {
                    if (xx < 0 || yy < 0 || xx >= width || yy >= height) continue;
                    ++count;
                    const std::int32_t q = prep.index[u.view][std::size_t(yy * width + xx)];
                    if (q < 0 || !prep.pixels[std::size_t(q)].seesMaterial) continue;
                    const UsedPixel& v = prep.pixels[std::size_t(q)];
                    for (std::uint32_t b = 0; b < v.slotCount; ++b)
                        if (prep.slots[v.slotBegin + b] == prep.slots[u.slotBegin + a])
                            sum += jacobians[v.slotBegin + b].cast<double>();
                }
            out[u.slotBegin + a] = (sum / count).cast<float>();
        }
    }
    return out;
}

TEST(Instruments, SmoothingInPlaceGivesEachEntryTheAverageAroundIt) {
    std::mt19937 rng(7);
    std::uniform_real_distribution<float> value(-2, 2);
    tbb::task_arena arena(2);
    for (int trial = 0; trial < 20; ++trial) {
        const UsedPixels prep = randomPixels(rng);
        std::vector<StoredJacobian> jacobians(prep.slots.size());
        for (StoredJacobian& j : jacobians)
            j = StoredJacobian::NullaryExpr([&] { return value(rng); });
        const std::vector<StoredJacobian> expected = averaged(prep, jacobians);
        smoothJacobians(prep, jacobians, arena);
        // The same sums in the same order: equal to the last bit.
        for (std::size_t i = 0; i < jacobians.size(); ++i)
            ASSERT_EQ(jacobians[i], expected[i]) << "trial " << trial << ", entry " << i;
    }
}

TEST(Instruments, SmoothingAViewWithOnePixelUsedDividesByTheWholeWindow) {
    // A 5 x 5 view with its centre alone used: the window holds 25 pixels, 24 of them unused.
    UsedPixels prep;
    prep.widths = {5};
    prep.heights = {5};
    prep.index.emplace_back(25, -1);
    prep.index[0][12] = 0;
    prep.pixels.push_back(UsedPixel{0, 12, 0, 1, true});
    prep.slots = {0};
    std::vector<StoredJacobian> jacobians = {StoredJacobian::Constant(25.0f)};
    tbb::task_arena arena(2);
    smoothJacobians(prep, jacobians, arena);
    EXPECT_EQ(jacobians[0], StoredJacobian::Constant(1.0f));
}

}  // namespace
}  // namespace phongfit
