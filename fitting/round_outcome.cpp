#include "round_outcome.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "convergence.h"
#include "identifiability.h"

namespace phongfit {

template <int P>
MaterialFit materialFit(const ParameterState<P>& params, int m,
                        const std::vector<double>& stdNatural) {
    using L = BlockLayout<P>;
    const HeldParams& held = params.held(m);
    const Eigen::Matrix<double, P, 1> y = params.natural(m);
    MaterialFit fit;
    const PhongMaterial p = naturalToPhong<P>(y.data());
    fit.kd = p.kd;
    fit.ks = p.ks;
    fit.n = p.n;
    for (int c = 0; c < 3; ++c) {
        fit.kdStd[c] = stdNatural[L::diffuse(L::group(c))];
        fit.ksStd[c] = stdNatural[L::specular(L::group(c))];
    }
    // An n held at its start is reported, and the next round records, exactly as it started
    // (exp(log n) need not round-trip); one held where it is (holding.cpp: a lobe no pixel sees,
    // or one broader than the start) is reported there, where kd and ks were fitted with it.
    const PhongMaterial& start = params.start(m);
    if (held.n && y[L::kLogN] == naturalFromPhong<P>(start)[L::kLogN])
        fit.n = std::clamp(start.n, kMinExponent, kMaxExponent);
    fit.logNStd = stdNatural[L::kLogN];
    fit.nStd = fit.n * fit.logNStd;
    static constexpr const char* kChannel[3] = {"r", "g", "b"};
    for (const char* name : {"kd", "ks"}) {
        const bool diffuse = name[1] == 'd';
        const auto& flags = diffuse ? held.kd : held.ks;
        const int count = int(std::count(flags.begin(), flags.begin() + L::kGroups, true));
        if (count == L::kGroups) {
            fit.unconstrained.push_back(name);
        } else {
            for (int g = 0; g < L::kGroups; ++g)
                if (flags[g]) fit.unconstrained.push_back(fmt::format("{}.{}", name, kChannel[g]));
        }
    }
    if (held.n) fit.unconstrained.push_back("n");
    return fit;
}

bool lobeConfirmed(const MaterialFit& fit) {
    // A held ks channel keeps its start with a standard error of 0: no evidence of a lobe, and
    // left out as the rounds' test (showsNoLobe) leaves out held groups.
    SpecularGroups free;
    for (int c = 0; c < 3; ++c) {
        if (fit.channelUnconstrained("ks", c)) continue;
        free.ks.push_back(fit.ks[c]);
        free.std.push_back(fit.ksStd[c]);
    }
    return lobeConfirmed(free.ks, free.std);
}

bool lobeHoldsExponent(const MaterialFit& fit) { return fit.nStd < fit.n || lobeConfirmed(fit); }

bool noLobeSeen(const MaterialFit& fit) { return fit.isUnconstrained("n") && !lobeConfirmed(fit); }

bool exponentListedForNoLobe(const MaterialFit& fit) {
    return fit.isUnconstrained("n") && fit.nStd > 0;
}

void finishExponentUncertainty(MaterialFit& fit) {
    if (!(fit.n > 0)) return;
    fit.nStd = std::max(fit.nStd, logNormalStd(fit.n, fit.logNStd));
    if (!fit.isUnconstrained("n") && !lobeHoldsExponent(fit)) fit.unconstrained.push_back("n");
    if (fit.isUnconstrained("n")) return;
    const double s = std::max(fit.logNStd, fit.logNSharperImageStd);
    fit.nStd = std::max(fit.nStd, std::min(fit.n * std::expm1(3 * s), kMaxExponent - fit.n) / 3);
}

double logNormalStd(double n, double s) {
    if (!(n > 0) || !(s > 0)) return 0;
    // n lies in [kMinExponent, kMaxExponent]: no distribution there spreads more than half that.
    const double most = (kMaxExponent - kMinExponent) / 2;
    const double v = s * s;
    if (v > 300) return most;
    return std::min(n * std::sqrt(std::expm1(v) * std::exp(v)), most);
}

std::vector<std::string> unresolvedParameters(const MaterialFit& fit) {
    std::vector<std::string> names;
    for (const char* name : {"kd", "ks"}) {
        const bool diffuse = name[1] == 'd';
        const Color3& value = diffuse ? fit.kd : fit.ks;
        const Color3& std = diffuse ? fit.kdStd : fit.ksStd;
        for (int c = 0; c < 3; ++c)
            if (!fit.channelUnconstrained(name, c) &&
                std[c] >= std::max(value[c], kReflectanceFloor)) {
                names.push_back(name);
                break;
            }
    }
    if (!fit.isUnconstrained("n") && fit.nStd >= fit.n) names.push_back("n");
    return names;
}

template <int P>
ExposureFit exposureFit(const ParameterState<P>& params, const std::vector<double>& stdNatural) {
    using L = BlockLayout<P>;
    const int e = params.exposure().slot();
    ExposureFit fit;
    fit.value = ExposureBlock::fromCoordinate(params.natural(e)[L::kLogN]);
    fit.std = fit.value * stdNatural[L::kLogN];
    fit.unconstrained = params.held(e).n;
    return fit;
}

template <int P>
void countImageNoise(const ParameterState<P>& params, int m, const RoundOutcome& out,
                     MaterialFit& fit) {
    const std::size_t b = std::size_t(m);
    const MaterialFit image = materialFit(
        params, m,
        noisePart(out.naturalStd[b],
                  b < out.pathShare.size() ? out.pathShare[b] : std::vector<double>{}, false));
    fit.kdCountedImageStd = image.kdStd;
    fit.ksCountedImageStd = image.ksStd;
    fit.logNCountedImageStd = image.logNStd;
}

template void countImageNoise<kRgbBlock>(const ParameterState<kRgbBlock>&, int, const RoundOutcome&,
                                         MaterialFit&);
template void countImageNoise<kGreyBlock>(const ParameterState<kGreyBlock>&, int,
                                          const RoundOutcome&, MaterialFit&);
template MaterialFit materialFit<kRgbBlock>(const ParameterState<kRgbBlock>&, int,
                                            const std::vector<double>&);
template MaterialFit materialFit<kGreyBlock>(const ParameterState<kGreyBlock>&, int,
                                             const std::vector<double>&);
template ExposureFit exposureFit<kRgbBlock>(const ParameterState<kRgbBlock>&,
                                            const std::vector<double>&);
template ExposureFit exposureFit<kGreyBlock>(const ParameterState<kGreyBlock>&,
                                             const std::vector<double>&);

}  // namespace phongfit
