// Sums over used pixels, in parallel and deterministic: the fit is bit-identical whatever the
// thread count.
#pragma once

#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>
#include <tbb/task_arena.h>

#include <cstddef>

namespace phongfit {

// Pixels per block. Fixed, as is the reduction tree over the blocks
// (tbb::parallel_deterministic_reduce splits by the range alone), so each block's partial sum and
// the order they are added in do not depend on the threads.
inline constexpr std::size_t kPixelBlock = 256;

// Sum over i in [0, count) of body(i, sum, scratch), run in `arena`. `zero` is the sum of no
// pixels; Value needs +=. makeScratch() makes one block's scratch space.
template <typename Value, typename MakeScratch, typename Body>
Value sumOverPixels(tbb::task_arena& arena, std::size_t count, const Value& zero,
                    const MakeScratch& makeScratch, const Body& body) {
    return arena.execute([&] {
        return tbb::parallel_deterministic_reduce(
            tbb::blocked_range<std::size_t>(0, count, kPixelBlock), zero,
            [&](const tbb::blocked_range<std::size_t>& range, Value sum) {
                auto scratch = makeScratch();
                for (std::size_t i = range.begin(); i != range.end(); ++i) body(i, sum, scratch);
                return sum;
            },
            [](Value a, const Value& b) {
                a += b;
                return a;
            });
    });
}

}  // namespace phongfit
