#include "mapped_allocator.h"

#include <sys/mman.h>
#include <unistd.h>

#include <atomic>
#include <cstdint>
#include <cstdlib>

namespace phongfit::detail {

namespace {
constexpr std::size_t kMappedBytes = std::size_t(16) << 10;
constexpr int kMostMappings = 16384;
std::atomic<int> mappings{0};
constexpr std::size_t kHeader = sizeof(MappedBlockHeader);
}  // namespace

void* allocateMaybeMapped(std::size_t bytes) {
    const std::size_t total = bytes + kHeader;
    void* block = nullptr;
    bool mapped = false;
    if (bytes >= kMappedBytes) {
        if (mappings.fetch_add(1) < kMostMappings) {
            block =
                mmap(nullptr, total, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
            mapped = block != MAP_FAILED;
        }
        if (!mapped) mappings.fetch_sub(1);
    }
    if (!mapped) {
        block = std::malloc(total);  // aligned for any fundamental type, as the header needs
        if (block == nullptr) throw std::bad_alloc();
    }
    ::new (block) MappedBlockHeader{mapped};
    return static_cast<char*>(block) + kHeader;
}

void deallocateMaybeMapped(void* elements, std::size_t bytes) noexcept {
    void* block = static_cast<char*>(elements) - kHeader;
    if (static_cast<MappedBlockHeader*>(block)->mapped) {
        munmap(block, bytes + kHeader);
        mappings.fetch_sub(1);
    } else {
        std::free(block);
    }
}

int liveMappings() { return mappings.load(); }

std::size_t pageBytes() {
    static const std::size_t page = std::size_t(sysconf(_SC_PAGESIZE));
    return page;
}

void discardPages(const void* from, const void* to) noexcept {
    const std::uintptr_t page = pageBytes();
    const std::uintptr_t begin = (reinterpret_cast<std::uintptr_t>(from) + page - 1) / page * page;
    const std::uintptr_t end = reinterpret_cast<std::uintptr_t>(to) / page * page;
    if (begin < end) madvise(reinterpret_cast<void*>(begin), end - begin, MADV_DONTNEED);
}

}  // namespace phongfit::detail
