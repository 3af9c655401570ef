#include "round_scatter.h"

#include <algorithm>
#include <cmath>

namespace phongfit {

std::vector<MaterialScatter> roundScatter(const std::vector<FitRound>& rounds,
                                          const std::vector<MaterialFit>* latest) {
    constexpr std::size_t kFirst = 2;
    std::vector<const std::vector<MaterialFit>*> estimates;
    for (std::size_t r = kFirst; r < rounds.size(); ++r)
        if (!rounds[r].probe) estimates.push_back(&rounds[r].materials);
    if (latest && rounds.size() >= kFirst) estimates.push_back(latest);
    if (estimates.size() > std::size_t(kScatterRounds))
        estimates.erase(estimates.begin(), estimates.end() - kScatterRounds);
    if (estimates.size() < 2) return {};
    std::vector<MaterialScatter> out(estimates.back()->size());
    const double pairs = 2.0 * double(estimates.size() - 1);
    for (std::size_t k = 1; k < estimates.size(); ++k)
        for (std::size_t s = 0; s < out.size(); ++s) {
            const MaterialFit &a = (*estimates[k - 1])[s], &b = (*estimates[k])[s];
            out[s].kd += (b.kd - a.kd).square() / pairs;
            out[s].ks += (b.ks - a.ks).square() / pairs;
            out[s].logN += std::pow(std::log(b.n) - std::log(a.n), 2) / pairs;
        }
    for (MaterialScatter& m : out) {
        m.kd = m.kd.sqrt();
        m.ks = m.ks.sqrt();
        m.logN = std::sqrt(m.logN);
    }
    return out;
}

void widenToRoundScatter(FitResult& result) {
    const std::vector<MaterialScatter> scatter = roundScatter(result.rounds);
    for (std::size_t s = 0; s < scatter.size() && s < result.materials.size(); ++s) {
        MaterialFit& m = result.materials[s];
        for (int c = 0; c < 3; ++c) {
            if (m.kdStd[c] > 0) m.kdStd[c] = std::max(m.kdStd[c], scatter[s].kd[c]);
            if (m.ksStd[c] > 0) m.ksStd[c] = std::max(m.ksStd[c], scatter[s].ks[c]);
        }
        if (m.nStd > 0) m.nStd = std::max(m.nStd, m.n * scatter[s].logN);
    }
}

}  // namespace phongfit
