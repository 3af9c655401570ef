// An append-only array kept in fixed blocks of 256 kB (mapped_allocator.h: straight from the
// system). For a recording's tile records, which grow to tens of megabytes a tile where a lobe
// draws the paths: a vector doubles by copying, and for a moment holds both copies; blocks are
// never copied. A reader hands back what it has consumed (releaseBefore a prefix, releaseWithin
// any range), so copying the records into the path set does not hold a tile twice either.
#pragma once

#include <algorithm>
#include <cstddef>
#include <memory>
#include <span>
#include <type_traits>
#include <utility>
#include <vector>

#include "mapped_allocator.h"

namespace phongfit {

template <typename T>
class BlockArray {
    static_assert(std::is_trivially_destructible_v<T>);  // blocks go back without destructors

public:
    // Elements a block holds: with MappedAllocator's header, 256 kB, 64 pages exactly. (A power of
    // two spilled the header's 16 bytes onto a 65th page: 1.6% of the paths resident for nothing.)
    static constexpr std::size_t kBlock =
        ((std::size_t(256) << 10) - sizeof(detail::MappedBlockHeader)) / sizeof(T);

    BlockArray() = default;
    BlockArray(const BlockArray&) = delete;
    BlockArray& operator=(const BlockArray&) = delete;
    BlockArray(BlockArray&& other) noexcept
        : blocks_(std::move(other.blocks_)),
          size_(std::exchange(other.size_, 0)),
          released_(std::exchange(other.released_, 0)) {
        other.blocks_.clear();
    }
    BlockArray& operator=(BlockArray&& other) noexcept {
        releaseBefore(blocks_.size() * kBlock);
        blocks_ = std::move(other.blocks_);
        size_ = std::exchange(other.size_, 0);
        released_ = std::exchange(other.released_, 0);
        other.blocks_.clear();
        return *this;
    }
    ~BlockArray() { releaseBefore(blocks_.size() * kBlock); }

    std::size_t size() const { return size_; }
    const T& operator[](std::size_t i) const { return blocks_[i / kBlock][i % kBlock]; }
    T& operator[](std::size_t i) { return blocks_[i / kBlock][i % kBlock]; }

    void push_back(const T& x) {
        if (size_ == blocks_.size() * kBlock)
            blocks_.push_back(MappedAllocator<T>().allocate(kBlock));
        std::construct_at(&blocks_[size_ / kBlock][size_ % kBlock], x);
        ++size_;
    }
    void append(std::span<const T> xs) {
        for (const T& x : xs) push_back(x);
    }
    // Keeps the first n elements (size() >= n, none of them released), handing back the blocks
    // beyond them.
    void truncate(std::size_t n) {
        size_ = n;
        while (blocks_.size() > (n + kBlock - 1) / kBlock) {
            release(blocks_.back());
            blocks_.pop_back();
        }
    }
    // Hands back the blocks that hold only elements before i; those are not read again. Returns
    // the bytes that went back to the heap rather than to the system (MappedAllocator's fallback).
    std::size_t releaseBefore(std::size_t i) {
        std::size_t heap = 0;
        for (; released_ < std::min(i / kBlock, blocks_.size()); ++released_)
            heap += release(blocks_[released_]);
        return heap;
    }
    // Once appending is over, elements [begin, end) are not read again: the blocks that hold only
    // them go back, and the whole pages they fill in the others leave the resident set (mapped
    // blocks). Returns the bytes that went back to the heap.
    std::size_t releaseWithin(std::size_t begin, std::size_t end) {
        std::size_t heap = 0;
        end = std::min(end, size_);
        for (std::size_t b = begin / kBlock; begin < end; ++b) {
            const std::size_t first = b * kBlock, last = std::min(first + kBlock, size_);
            const std::size_t to = std::min(end, last);
            T*& block = blocks_[b];
            if (begin == first && to == last)
                heap += release(block);
            else if (block != nullptr && detail::blockIsMapped(block))
                detail::discardPages(block + (begin - first), block + (to - first));
            begin = to;
        }
        return heap;
    }

private:
    static std::size_t release(T*& block) {
        if (block == nullptr) return 0;
        const std::size_t heap = detail::blockIsMapped(block) ? 0 : kBlock * sizeof(T);
        MappedAllocator<T>().deallocate(block, kBlock);
        block = nullptr;
        return heap;
    }

    std::vector<T*> blocks_;  // the first released_, and any released within, are nullptr
    std::size_t size_ = 0, released_ = 0;
};

}  // namespace phongfit
