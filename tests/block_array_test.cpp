// BlockArray (block_array.h): elements read back across block boundaries, truncation hands back
// the blocks beyond it, a consumed prefix goes back block by block, a consumed range by whole
// blocks and whole pages, and a move hands over the blocks without copying them.
#include "block_array.h"

#include <gtest/gtest.h>
#include <sys/mman.h>
#include <unistd.h>

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

// Whether each page of [from, to) is resident (mincore), rounded out to whole pages.
std::vector<bool> residentPages(const void* from, const void* to) {
    const std::uintptr_t page = std::uintptr_t(sysconf(_SC_PAGESIZE));
    const std::uintptr_t begin = reinterpret_cast<std::uintptr_t>(from) / page * page;
    const std::uintptr_t end = (reinterpret_cast<std::uintptr_t>(to) + page - 1) / page * page;
    std::vector<unsigned char> flags((end - begin) / page);
    EXPECT_EQ(mincore(reinterpret_cast<void*>(begin), end - begin, flags.data()), 0);
    std::vector<bool> resident;
    for (unsigned char f : flags) resident.push_back(f & 1);
    return resident;
}

TEST(BlockArray, AConsumedRangeGoesBackByWholeBlocksAndWholePages) {
    const std::size_t page = std::size_t(sysconf(_SC_PAGESIZE)) / sizeof(std::uint64_t);
    const int before = detail::liveMappings();
    BlockArray<std::uint64_t> a;
    for (std::size_t i = 0; i < 3 * kBlock; ++i) a.push_back(i);
    const std::uint64_t* second = &a[kBlock];
    ASSERT_EQ(residentPages(second, second + kBlock), std::vector<bool>(64, true));

    // Within the second block, from mid-page to mid-page: only the whole pages between go back.
    const std::size_t from = kBlock + page / 2, to = kBlock + 10 * page + 3;
    EXPECT_EQ(a.releaseWithin(from, to), 0u);
    EXPECT_EQ(detail::liveMappings() - before, 3);
    const std::uintptr_t bytes = std::uintptr_t(sysconf(_SC_PAGESIZE));
    const std::uintptr_t base = reinterpret_cast<std::uintptr_t>(second) / bytes * bytes;
    const std::uintptr_t lo = reinterpret_cast<std::uintptr_t>(&a[from]),
                         hi = reinterpret_cast<std::uintptr_t>(&a[to - 1] + 1);
    const std::vector<bool> resident = residentPages(second, second + kBlock);
    int dropped = 0;
    for (std::size_t k = 0; k < resident.size(); ++k) {
        const std::uintptr_t at = base + k * bytes;
        EXPECT_EQ(resident[k], !(at >= lo && at + bytes <= hi)) << "page " << k;
        dropped += !resident[k];
    }
    EXPECT_EQ(dropped, 9);
    EXPECT_EQ(a[from - 1], from - 1);  // the elements around the range are still there
    EXPECT_EQ(a[to], to);

    // A range covering the first block whole hands it back; the third keeps what is unread.
    EXPECT_EQ(a.releaseWithin(0, kBlock), 0u);
    EXPECT_EQ(detail::liveMappings() - before, 2);
    EXPECT_EQ(a.releaseWithin(2 * kBlock + 1, 3 * kBlock), 0u);
    EXPECT_EQ(detail::liveMappings() - before, 2);
    EXPECT_EQ(a[2 * kBlock], 2 * kBlock);
    EXPECT_EQ(a.releaseBefore(3 * kBlock), 0u);  // skips the block already handed back
    EXPECT_EQ(detail::liveMappings(), before);
}

}  // namespace
}  // namespace phongfit
