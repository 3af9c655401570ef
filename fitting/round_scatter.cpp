#include "round_scatter.h"

#include <algorithm>
#include <cmath>
#include <functional>

namespace phongfit {

void widenToRoundScatter(FitResult& result) {
    constexpr int kFirst = 2;
    const int rounds = int(result.rounds.size());
    const int first = std::max(kFirst, rounds - kScatterRounds);
    if (rounds - first < 2) return;
    // sqrt(mean squared successive difference / 2) of value(round) over rounds first..last.
    const auto scatter = [&](const std::function<double(const FitRound&)>& value) {
        double sum = 0;
        for (int r = first + 1; r < rounds; ++r)
            sum += std::pow(value(result.rounds[r]) - value(result.rounds[r - 1]), 2);
        return std::sqrt(sum / (2.0 * (rounds - 1 - first)));
    };
    for (std::size_t s = 0; s < result.materials.size(); ++s) {
        MaterialFit& m = result.materials[s];
        for (int c = 0; c < 3; ++c) {
            if (m.kdStd[c] > 0)
                m.kdStd[c] = std::max(
                    m.kdStd[c], scatter([&](const FitRound& r) { return r.materials[s].kd[c]; }));
            if (m.ksStd[c] > 0)
                m.ksStd[c] = std::max(
                    m.ksStd[c], scatter([&](const FitRound& r) { return r.materials[s].ks[c]; }));
        }
        if (m.nStd > 0)
            m.nStd = std::max(m.nStd, m.n * scatter([&](const FitRound& r) {
                                          return std::log(r.materials[s].n);
                                      }));
    }
}

}  // namespace phongfit
