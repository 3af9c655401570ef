#include "sharper_probe.h"

#include <algorithm>
#include <cmath>

#include "material_params.h"

namespace phongfit {

namespace {

bool probed(const MaterialFit& m) {
    return !m.isUnconstrained("n") && m.n > 0 && m.n * kProbeFactor <= kMaxExponent;
}

// 3 standard errors of log n.
double threeStd(const MaterialFit& m) { return 3.0 * m.nStd / m.n; }

double probeFactor(const MaterialFit& m) {
    return std::min(std::max(kProbeFactor, std::exp(threeStd(m))), kMaxExponent / m.n);
}

// Whether probe round `p` tells converged lobe `c`'s n from the probe's start: n resolved and
// 3 standard errors of log n short of the way between them.
bool tellsApart(const MaterialFit& c, const MaterialFit& p) {
    return p.nStd < p.n && threeStd(p) < std::log(probeFactor(c));
}

// The paths relative to the first round's that put a probe's standard error of log n kProbeMargin
// below what probeReturned asks, predicted from converged lobe `c`'s at `pathFactor`.
double pathsToTell(const MaterialFit& c, double pathFactor) {
    const double goal = std::log(probeFactor(c)) / (3 * kProbeMargin);
    return pathFactor * std::pow(c.nStd / c.n / goal, 2);
}

}  // namespace

std::vector<PhongMaterial> sharperProbe(const std::vector<MaterialFit>& materials,
                                        std::vector<PhongMaterial> at) {
    bool any = false;
    for (std::size_t s = 0; s < materials.size(); ++s) {
        const MaterialFit& m = materials[s];
        if (!probed(m)) continue;
        at[s].n = m.n * probeFactor(m);
        any = true;
    }
    return any ? at : std::vector<PhongMaterial>{};
}

bool sharperSideUntested(const std::vector<MaterialFit>& materials,
                         const std::vector<double>& sharpest) {
    for (std::size_t s = 0; s < materials.size() && s < sharpest.size(); ++s)
        if (probed(materials[s]) && sharpest[s] < std::sqrt(kProbeFactor) * materials[s].n)
            return true;
    return false;
}

double probePaths(const std::vector<MaterialFit>& converged, double pathFactor) {
    double paths = kProbePaths;
    for (const MaterialFit& c : converged) {
        if (!probed(c)) continue;
        const double need = pathsToTell(c, pathFactor);
        if (need <= kMostProbePaths) paths = std::max(paths, need);
    }
    return paths;
}

double firstProbePaths(const std::vector<MaterialFit>& converged, double pathFactor, bool last) {
    return last ? probePaths(converged, pathFactor) : kProbePaths;
}

bool probeTold(const std::vector<MaterialFit>& converged, const std::vector<MaterialFit>& probe) {
    for (std::size_t s = 0; s < converged.size() && s < probe.size(); ++s)
        if (probed(converged[s]) && !probe[s].isUnconstrained("n") &&
            !tellsApart(converged[s], probe[s]))
            return false;
    return true;
}

bool pulledBroader(const std::vector<MaterialFit>& converged, const std::vector<MaterialFit>& probe,
                   double pathFactor) {
    for (std::size_t s = 0; s < converged.size() && s < probe.size(); ++s) {
        const MaterialFit &c = converged[s], &p = probe[s];
        if (probed(c) && !p.isUnconstrained("n") && p.n < c.n &&
            pathsToTell(c, pathFactor) > kMostProbePaths)
            return true;
    }
    return false;
}

bool probeReturned(const std::vector<MaterialFit>& converged,
                   const std::vector<MaterialFit>& probe) {
    // A probe that cannot tell the converged n from its own start vouches for nothing.
    if (!probeTold(converged, probe)) return false;
    for (std::size_t s = 0; s < converged.size() && s < probe.size(); ++s) {
        const MaterialFit &c = converged[s], &p = probe[s];
        if (!probed(c) || p.isUnconstrained("n")) continue;
        const double reach = std::max(0.5 * std::log(probeFactor(c)), threeStd(p));
        if (std::abs(std::log(p.n) - std::log(c.n)) > reach) return false;
    }
    return true;
}

void widenToProbe(std::vector<MaterialFit>& converged, const std::vector<MaterialFit>& probe) {
    for (std::size_t s = 0; s < converged.size() && s < probe.size(); ++s) {
        MaterialFit& c = converged[s];
        const MaterialFit& p = probe[s];
        if (!probed(c) || p.isUnconstrained("n")) continue;
        // One that cannot tell them apart rules out nothing up to its start, nor within 3 of its
        // standard errors of where it went (beyond its start, where the lobe may be sharper yet).
        // Nor does one that went past the converged n to a broader lobe: that is the pull of its
        // few paths towards lobes they reach, not the images ruling its start out. One that told
        // them apart and went on sharper than its start saw the images ask for a lobe sharper
        // than any recording: none bounds it.
        const double start = c.n * probeFactor(c);
        double reach = std::abs(p.n - c.n) + 3 * p.nStd;
        if (!tellsApart(c, p) || p.n < c.n)
            reach = std::max(reach, start - c.n);
        else if (p.n >= start)
            reach = std::max(reach, kMaxExponent - c.n);
        c.nStd = std::max(c.nStd, reach);
    }
}

void widenToBound(std::vector<MaterialFit>& materials) {
    for (MaterialFit& m : materials)
        if (!m.isUnconstrained("n") && m.n > 0 && !probed(m))
            m.nStd = std::max(m.nStd, kMaxExponent - m.n);
}

}  // namespace phongfit
