// MappedAllocator (mapped_allocator.h): blocks of every size hold what is written to them, and
// more live blocks than it maps fall back to the heap rather than failing, and each block knows
// which it came from (blockIsMapped).
#include "mapped_allocator.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <numeric>
#include <vector>

namespace phongfit {
namespace {

template <typename T>
using MappedVector = std::vector<T, MappedAllocator<T>>;

TEST(MappedAllocator, VectorsGrowingThroughHeapAndMappedBlocksKeepTheirElements) {
    MappedVector<std::uint32_t> v;
    for (std::uint32_t i = 0; i < (1u << 20); ++i) v.push_back(i);  // 16 B ... 4 MB blocks
    std::vector<std::uint32_t> expected(v.size());
    std::iota(expected.begin(), expected.end(), 0u);
    EXPECT_TRUE(std::equal(v.begin(), v.end(), expected.begin(), expected.end()));
    v.resize(3);
    v.shrink_to_fit();
    EXPECT_EQ(v, (MappedVector<std::uint32_t>{0, 1, 2}));
}

TEST(MappedAllocator, MoreLiveBlocksThanItMapsComeFromTheHeap) {
    // 20000 blocks of 16 kB: beyond the 16384 mappings it keeps, the rest from the heap.
    std::vector<MappedVector<std::uint64_t>> blocks(20000);
    for (std::size_t b = 0; b < blocks.size(); ++b) {
        blocks[b].reserve(2048);
        blocks[b].push_back(b);
    }
    EXPECT_EQ(detail::liveMappings(), 16384);
    for (std::size_t b = 0; b < blocks.size(); ++b) ASSERT_EQ(blocks[b].front(), b);
    // Each block knows where it came from: only those beyond the mappings, from the heap.
    std::size_t heap = 0;
    for (const MappedVector<std::uint64_t>& b : blocks) heap += !detail::blockIsMapped(b.data());
    EXPECT_EQ(heap, 20000u - 16384u);
    EXPECT_FALSE(detail::blockIsMapped(MappedVector<std::uint64_t>(4).data()));
    blocks.clear();
    EXPECT_EQ(detail::liveMappings(), 0);
    // Mappings freed: mapped again.
    MappedVector<std::uint64_t> again(1 << 16, 7);
    EXPECT_EQ(detail::liveMappings(), 1);
    EXPECT_EQ(again.back(), 7u);
}

}  // namespace
}  // namespace phongfit
