#include "pixel_sampler.h"

#include <boost/random/sobol.hpp>
#include <vector>

namespace phongfit::sobol {

namespace {

// Built as the program loads (1 MB), so that it belongs to the program, as its code does, rather
// than to the memory of the first recording that draws from it (docs/design/fitter.md, "Memory").
const std::vector<std::uint32_t> tables = [] {
    // Boost's engine runs in Gray-code order: seeded with n it stands at the natural order's
    // point gray(n + 1), so seeded with 2^(k+1) - 2 at point 2^k, whose coordinates are the
    // k-th direction numbers.
    std::vector<std::uint32_t> direction(32 * std::size_t(kDimensions));
    boost::random::sobol_engine<std::uint32_t, 32> engine(kDimensions);
    for (int k = 0; k < 32; ++k) {
        engine.seed(std::uint32_t((std::uint64_t(2) << k) - 2));
        for (std::uint32_t d = 0; d < kDimensions; ++d)
            direction[32 * std::size_t(d) + k] = reverseBits(engine());
    }
    std::vector<std::uint32_t> t(1024 * std::size_t(kDimensions), 0);
    for (std::size_t d = 0; d < kDimensions; ++d)
        for (int b = 0; b < 4; ++b)
            for (std::uint32_t i = 0; i < 256; ++i)
                for (int k = 0; k < 8; ++k)
                    if (i & (1u << k)) t[(4 * d + b) * 256 + i] ^= direction[32 * d + 8 * b + k];
    return t;
}();

}  // namespace

const std::uint32_t* reversedByteTables() { return tables.data(); }

}  // namespace phongfit::sobol
