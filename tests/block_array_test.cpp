// BlockArray (block_array.h): elements read back across block boundaries, truncation hands back
// the blocks beyond it, a consumed prefix goes back block by block, and a move hands over the
// blocks without copying them.
#include "block_array.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <numeric>
#include <vector>

namespace phongfit {
namespace {

constexpr std::size_t kBlock = BlockArray<std::uint64_t>::kBlock;

TEST(BlockArray, HoldsWhatIsAppendedAcrossBlocks) {
    static_assert(kBlock == 32766);  // 256 kB with the allocator's 16-byte header
    const int before = detail::liveMappings();
    BlockArray<std::uint64_t> a;
    std::vector<std::uint64_t> values(3 * kBlock + 5);
    std::iota(values.begin(), values.end(), 1u);
    a.append(std::span(values).first(kBlock - 1));
    for (std::size_t i = kBlock - 1; i < values.size(); ++i) a.push_back(values[i]);
    ASSERT_EQ(a.size(), values.size());
    EXPECT_EQ(detail::liveMappings() - before, 4);
    for (std::size_t i = 0; i < values.size(); ++i) ASSERT_EQ(a[i], values[i]) << i;

    a.truncate(kBlock + 1);  // two blocks still hold elements
    EXPECT_EQ(a.size(), kBlock + 1);
    EXPECT_EQ(detail::liveMappings() - before, 2);
    a.push_back(7);
    EXPECT_EQ(a[kBlock + 1], 7u);
    EXPECT_EQ(a[kBlock], values[kBlock]);
}

TEST(BlockArray, AConsumedPrefixGoesBackBlockByBlock) {
    const int before = detail::liveMappings();
    BlockArray<std::uint64_t> a;
    for (std::size_t i = 0; i < 3 * kBlock; ++i) a.push_back(i);
    EXPECT_EQ(a.releaseBefore(kBlock - 1), 0u);  // the first block still holds one unread
    EXPECT_EQ(detail::liveMappings() - before, 3);
    EXPECT_EQ(a.releaseBefore(2 * kBlock + 3), 0u);  // mapped: none went to the heap
    EXPECT_EQ(detail::liveMappings() - before, 1);
    EXPECT_EQ(a[2 * kBlock + 3], 2 * kBlock + 3);
    BlockArray<std::uint64_t> moved = std::move(a);
    EXPECT_EQ(moved.size(), 3 * kBlock);
    EXPECT_EQ(a.size(), 0u);
    EXPECT_EQ(moved[3 * kBlock - 1], 3 * kBlock - 1);
    EXPECT_EQ(detail::liveMappings() - before, 1);
    moved = BlockArray<std::uint64_t>();
    EXPECT_EQ(detail::liveMappings(), before);
}

}  // namespace
}  // namespace phongfit
