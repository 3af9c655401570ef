#include "round_scatter.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "material_params.h"

namespace phongfit {

namespace {

// A full window's first move counts as travel above this many times the rms of its other moves.
// Four independent estimates' first move is that far out 1.2% of the time (simulated, 2e6 draws).
constexpr double kTravelRatio = 8;

// The factor by which a climb of n that does not slow must have gone for its end to be left open.
constexpr double kUnendedClimb = 2;

// sqrt(mean squared successive difference / 2) of `values`, made unbiased for their few degrees
// of freedom. A full window whose first move is travel (kTravelRatio) leaves its first value out.
double scatterOf(std::vector<double> values) {
    if (values.size() == std::size_t(kScatterRounds)) {
        const double first = values[1] - values[0];
        double others = 0;
        for (std::size_t k = 2; k < values.size(); ++k)
            others += std::pow(values[k] - values[k - 1], 2) / double(values.size() - 2);
        // Later moves of exactly 0 (solves that kept their start) say nothing of the noise.
        if (others > 0 && first * first > kTravelRatio * kTravelRatio * others)
            values.erase(values.begin());
    }
    double squares = 0;
    for (std::size_t k = 1; k < values.size(); ++k)
        squares += std::pow(values[k] - values[k - 1], 2);
    // The square root of a variance estimated from a few rounds is biased low (Jensen): from two
    // estimates it is sqrt(2 / pi) = 0.80 of the spread on average. Divided by that mean, c4, for
    // the degrees of freedom of the mean squared successive difference of k estimates,
    // 2 (k - 1)^2 / (3 k - 4) (von Neumann).
    const double k = double(values.size()), dof = 2 * (k - 1) * (k - 1) / (3 * k - 4);
    const double c4 =
        std::sqrt(2 / dof) * std::exp(std::lgamma((dof + 1) / 2) - std::lgamma(dof / 2));
    return std::sqrt(squares / (2 * (k - 1))) / c4;
}

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
    std::vector<MaterialScatter> out(estimates.back()->size());
    const auto scatter = [&](auto value) {
        std::vector<double> values;
        for (const std::vector<MaterialFit>* e : estimates) values.push_back(value(*e));
        return scatterOf(std::move(values));
    };
    for (std::size_t s = 0; s < out.size(); ++s) {
        for (int c = 0; c < 3; ++c) {
            out[s].kd[c] = scatter([&](const auto& e) { return e[s].kd[c]; });
            out[s].ks[c] = scatter([&](const auto& e) { return e[s].ks[c]; });
        }
        out[s].logN = scatter([&](const auto& e) { return std::log(e[s].n); });
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

// The last run of moves in the last move's direction: the last move, the run's moves and travel,
// and rho, by how much its moves shrink a round (geometric mean; 0 for a run of one move).
struct Run {
    double last = 0, travel = 0, rho = 0;
    std::size_t moves = 0;
};

Run lastRun(const std::vector<double>& estimates) {
    if (estimates.size() < 2) return {};
    std::size_t k = estimates.size() - 2;
    Run run;
    run.last = estimates.back() - estimates[k];
    while (k > 0 && (estimates[k] - estimates[k - 1]) * run.last > 0) --k;
    run.travel = std::abs(estimates.back() - estimates[k]);
    run.moves = estimates.size() - 1 - k;
    if (run.moves >= 2)
        run.rho = std::pow(std::abs(run.last / (estimates[k + 1] - estimates[k])),
                           1.0 / double(run.moves - 1));
    return run;
}

// How far the estimates may still go: the rest of the run's geometric series,
// last * rho / (1 - rho), at most the run's travel (all of it where the moves do not shrink), and
// at least the last move.
double drift(const Run& run) {
    if (run.rho >= 1) return run.travel;
    return std::max(std::abs(run.last),
                    std::min(std::abs(run.last) * run.rho / (1 - run.rho), run.travel));
}

}  // namespace

void widenToDrift(FitResult& result) {
    for (std::size_t s = 0; s < result.materials.size(); ++s) {
        const auto estimatesOf = [&](auto value) {
            // A round that kept its start exactly (its solve did not move it) says nothing of the
            // direction: it does not cut a run of moves short.
            std::vector<double> estimates;
            for (const FitRound& r : result.rounds)
                if (!r.probe && s < r.materials.size() &&
                    (estimates.empty() || value(r.materials[s]) != estimates.back()))
                    estimates.push_back(value(r.materials[s]));
            return estimates;
        };
        const auto along = [&](auto value) { return drift(lastRun(estimatesOf(value))); };
        MaterialFit& m = result.materials[s];
        for (int c = 0; c < 3; ++c) {
            if (m.kdStd[c] > 0)
                m.kdStd[c] =
                    std::max(m.kdStd[c], along([c](const MaterialFit& f) { return f.kd[c]; }));
            if (m.ksStd[c] > 0)
                m.ksStd[c] =
                    std::max(m.ksStd[c], along([c](const MaterialFit& f) { return f.ks[c]; }));
        }
        if (m.nStd > 0) {
            // n climbs by factors: its drift is judged in log n too, and the farther reach counts
            // (on the side it moved to, within n's range). A climb that at least doubled n and
            // does not slow has shown no end: recordings are blind to lobes sharper than theirs
            // (sharper_probe.h), so only the bound ends it.
            const Run run =
                lastRun(estimatesOf([](const MaterialFit& f) { return std::log(f.n); }));
            const bool unended =
                run.moves >= 2 && run.rho >= 1 && run.travel >= std::log(kUnendedClimb);
            const double reach = run.last <= 0 ? -m.n * std::expm1(-drift(run))
                                 : unended
                                     ? kMaxExponent - m.n
                                     : std::min(m.n * std::expm1(drift(run)), kMaxExponent - m.n);
            m.nStd = std::max({m.nStd, along([](const MaterialFit& f) { return f.n; }), reach});
        }
    }
}

}  // namespace phongfit
