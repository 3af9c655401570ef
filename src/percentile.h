// The p-th percentile of a sample, as the value at rank p% of its size (no interpolation): what a
// comparison image's white level and an edge check's median deviation read.
#pragma once

#include <algorithm>
#include <cstddef>
#include <vector>

namespace phongfit {

// The value of rank min(size - 1, p / 100 * size) in `values`, sorted (p = 50: the upper median);
// 0 for no values.
inline double percentile(std::vector<double> values, double p) {
    if (values.empty()) return 0;
    const auto at =
        values.begin() + std::ptrdiff_t(std::min<double>(double(values.size() - 1),
                                                         p / 100 * double(values.size())));
    std::nth_element(values.begin(), at, values.end());
    return *at;
}

}  // namespace phongfit
