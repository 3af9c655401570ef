// An allocator whose construct() without arguments default-initialises: resize() of a vector of
// trivially constructible elements then leaves the new memory unwritten, so its pages become
// resident only as they are filled (PathSetFilm::assemble fills a recording's path set in tile
// order while it frees the tiles' records, keeping the peak near one copy of the paths).
#pragma once

#include <memory>
#include <new>
#include <type_traits>
#include <utility>
#include <vector>

namespace phongfit {

template <typename T, typename Base = std::allocator<T>>
class DefaultInitAllocator : public Base {
    using Traits = std::allocator_traits<Base>;

public:
    template <typename U>
    struct rebind {
        using other = DefaultInitAllocator<U, typename Traits::template rebind_alloc<U>>;
    };

    using Base::Base;

    template <typename U>
    void construct(U* p) noexcept(std::is_nothrow_default_constructible_v<U>) {
        ::new (static_cast<void*>(p)) U;
    }
    template <typename U, typename... Args>
    void construct(U* p, Args&&... args) {
        Traits::construct(static_cast<Base&>(*this), p, std::forward<Args>(args)...);
    }
};

// A vector whose resize() does not write the new elements.
template <typename T>
using UninitializedVector = std::vector<T, DefaultInitAllocator<T>>;

}  // namespace phongfit
