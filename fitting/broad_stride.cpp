#include "broad_stride.h"

#include <algorithm>

namespace phongfit {

bool stridesBroader(const MaterialFit& m, double recordedN) {
    return !m.isUnconstrained("n") && m.nStd >= 2 * m.n && m.n < recordedN &&
           m.ks.mean() >= 3 * m.ksStd.mean();
}

std::optional<std::vector<PhongMaterial>> broadStride(const std::vector<MaterialFit>& solved,
                                                      const std::vector<PhongMaterial>& recorded,
                                                      std::vector<PhongMaterial> next) {
    bool strides = false;
    for (std::size_t i = 0; i < solved.size(); ++i) {
        if (!stridesBroader(solved[i], recorded[i].n)) continue;
        next[i].n = std::min(solved[i].n, recorded[i].n / kBroadStride);
        strides = true;
    }
    if (!strides) return std::nullopt;
    return next;
}

}  // namespace phongfit
