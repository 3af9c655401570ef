// An allocator that takes blocks of 16 kB and more straight from the system (mmap) and gives them
// straight back (munmap). For vectors that grow by doubling while many others grow beside them
// (a recording's tile records): from the heap, each doubling leaves a freed block the others
// cannot reuse whole, and the resident set grew 1.4 times the paths recorded; mapped, a freed
// block leaves the resident set at once and the unused capacity is never touched, so never
// resident. Smaller blocks, and any beyond 16384 live mappings or refused by the system, come from
// the heap: the kernel limits a process's mappings (vm.max_map_count, 65530 by default).
#pragma once

#include <cstddef>
#include <new>

namespace phongfit {

namespace detail {
// Each block starts with a header saying where it came from; the elements follow it.
struct alignas(16) MappedBlockHeader {
    bool mapped;
};
void* allocateMaybeMapped(std::size_t bytes);
void deallocateMaybeMapped(void* elements, std::size_t bytes) noexcept;
int liveMappings();  // how many blocks are mapped now
// Hands the whole pages within [from, to) of a mapped block back to the system: they leave the
// resident set and read as zero if touched again. The block's first page, which holds the header,
// never lies within its elements' whole pages.
void discardPages(const void* from, const void* to) noexcept;
std::size_t pageBytes();  // the system's page size
// Whether a block MappedAllocator gave came from the system (else from the heap).
inline bool blockIsMapped(const void* elements) noexcept {
    return (static_cast<const MappedBlockHeader*>(elements) - 1)->mapped;
}
}  // namespace detail

template <typename T>
class MappedAllocator {
    static_assert(alignof(T) <= alignof(detail::MappedBlockHeader));

public:
    using value_type = T;

    MappedAllocator() = default;
    template <typename U>
    MappedAllocator(const MappedAllocator<U>&) noexcept {}

    T* allocate(std::size_t n) {
        if (n > (std::size_t(-1) - sizeof(detail::MappedBlockHeader)) / sizeof(T))
            throw std::bad_array_new_length();
        return static_cast<T*>(detail::allocateMaybeMapped(n * sizeof(T)));
    }
    void deallocate(T* p, std::size_t n) noexcept {
        detail::deallocateMaybeMapped(p, n * sizeof(T));
    }

    template <typename U>
    bool operator==(const MappedAllocator<U>&) const noexcept {
        return true;
    }
};

}  // namespace phongfit
