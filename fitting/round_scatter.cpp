#include "round_scatter.h"

#include <algorithm>
#include <array>
#include <cmath>

namespace phongfit {

namespace {

// The mean of the middle of three successive differences' sizes of four independent estimates,
// over their standard deviation (simulated, 2e7 draws: 1.0875 +- 0.00015).
constexpr double kMiddleDifferencePerSigma = 1.0875;

}  // namespace

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
    const std::size_t materials = estimates.back()->size();
    std::vector<MaterialScatter> out(materials);
    // A full window's scatter is its middle successive difference: a round that travelled (from a
    // start's state the recordings could not tell apart, to the estimate) is one difference of
    // three, and would otherwise set it (docs/design/fitter.md, "Standard errors no smaller than
    // the rounds' scatter").
    static_assert(kScatterRounds == 4, "kMiddleDifferencePerSigma is for four estimates");
    if (estimates.size() == std::size_t(kScatterRounds)) {
        const auto middle = [&](auto value) {
            std::array<double, kScatterRounds - 1> d;
            for (std::size_t k = 1; k < estimates.size(); ++k)
                d[k - 1] = std::abs(value(*estimates[k]) - value(*estimates[k - 1]));
            std::sort(d.begin(), d.end());
            return d[1] / kMiddleDifferencePerSigma;
        };
        for (std::size_t s = 0; s < materials; ++s) {
            for (int c = 0; c < 3; ++c) {
                out[s].kd[c] = middle([&](const auto& e) { return e[s].kd[c]; });
                out[s].ks[c] = middle([&](const auto& e) { return e[s].ks[c]; });
            }
            out[s].logN = middle([&](const auto& e) { return std::log(e[s].n); });
        }
        return out;
    }
    const double pairs = 2.0 * double(estimates.size() - 1);
    for (std::size_t k = 1; k < estimates.size(); ++k)
        for (std::size_t s = 0; s < materials; ++s) {
            const MaterialFit &a = (*estimates[k - 1])[s], &b = (*estimates[k])[s];
            out[s].kd += (b.kd - a.kd).square() / pairs;
            out[s].ks += (b.ks - a.ks).square() / pairs;
            out[s].logN += std::pow(std::log(b.n) - std::log(a.n), 2) / pairs;
        }
    // The square root of a variance estimated from a few rounds is biased low (Jensen): from two
    // estimates it is sqrt(2 / pi) = 0.80 of the spread on average. Divided by that mean, c4, for
    // the degrees of freedom of the mean squared successive difference of k estimates,
    // 2 (k - 1)^2 / (3 k - 4) (von Neumann).
    const double k = double(estimates.size()), dof = 2 * (k - 1) * (k - 1) / (3 * k - 4);
    const double c4 =
        std::sqrt(2 / dof) * std::exp(std::lgamma((dof + 1) / 2) - std::lgamma(dof / 2));
    for (MaterialScatter& m : out) {
        m.kd = m.kd.sqrt() / c4;
        m.ks = m.ks.sqrt() / c4;
        m.logN = std::sqrt(m.logN) / c4;
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
        if (m.nStd > 0) {
            m.logNStd = std::max(m.logNStd, scatter[s].logN);
            m.nStd = std::max(m.nStd, m.n * scatter[s].logN);
        }
    }
}

namespace {

// How far the estimates may still go: over the last run of moves in the last move's direction,
// whose moves shrink by rho a round (geometric mean), the rest of a geometric series,
// last * rho / (1 - rho), at most the run's travel (all of it where the moves do not shrink), and
// at least the last move.
double drift(const std::vector<double>& estimates) {
    if (estimates.size() < 2) return 0;
    std::size_t k = estimates.size() - 2;
    const double last = estimates.back() - estimates[k];
    while (k > 0 && (estimates[k] - estimates[k - 1]) * last > 0) --k;
    const double travel = std::abs(estimates.back() - estimates[k]);
    const std::size_t moves = estimates.size() - 1 - k;
    if (moves < 2) return std::abs(last);
    const double rho =
        std::pow(std::abs(last / (estimates[k + 1] - estimates[k])), 1.0 / double(moves - 1));
    if (rho >= 1) return travel;
    return std::max(std::abs(last), std::min(std::abs(last) * rho / (1 - rho), travel));
}

}  // namespace

void widenToDrift(FitResult& result) {
    for (std::size_t s = 0; s < result.materials.size(); ++s) {
        const auto along = [&](auto value) {
            // A round that kept its start exactly (its solve did not move it) says nothing of the
            // direction: it does not cut a run of moves short.
            std::vector<double> estimates;
            for (const FitRound& r : result.rounds)
                if (!r.probe && s < r.materials.size() &&
                    (estimates.empty() || value(r.materials[s]) != estimates.back()))
                    estimates.push_back(value(r.materials[s]));
            return drift(estimates);
        };
        MaterialFit& m = result.materials[s];
        for (int c = 0; c < 3; ++c) {
            if (m.kdStd[c] > 0)
                m.kdStd[c] =
                    std::max(m.kdStd[c], along([c](const MaterialFit& f) { return f.kd[c]; }));
            if (m.ksStd[c] > 0)
                m.ksStd[c] =
                    std::max(m.ksStd[c], along([c](const MaterialFit& f) { return f.ks[c]; }));
        }
        if (m.nStd > 0) m.nStd = std::max(m.nStd, along([](const MaterialFit& f) { return f.n; }));
    }
}

}  // namespace phongfit
