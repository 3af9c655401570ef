#include "parameter_state.h"

#include <algorithm>
#include <cmath>

namespace phongfit {

template <int P>
ParameterState<P>::ParameterState(const std::vector<PhongMaterial>& start, bool fitExposure)
    : materials_(int(start.size())), start_(start), held_(start.size()) {
    if (fitExposure) {
        exposure_ = ExposureBlock(materials_);
        start_.push_back(ExposureBlock::asMaterial(1));
        held_.push_back(ExposureBlock::startHeld());
    }
    x_.assign(held_.size() * P, 0.0);  // startAt sets every block
}

template <int P>
void ParameterState<P>::startAt(const Estimate& estimate) {
    x_.assign(held_.size() * P, 0.0);
    for (int b = 0; b < blockCount(); ++b) {
        const PhongMaterial theta = b < materials_ ? estimate.materials[std::size_t(b)]
                                                   : ExposureBlock::asMaterial(estimate.exposure);
        NaturalVector y = naturalFromPhong<P>(theta);
        const NaturalVector y0 = naturalFromPhong<P>(start(b));
        for (int i = 0; i < P; ++i)
            if (isHeld(b, i)) y[i] = y0[i];
        toInternal<P>(y.data(), held(b), block(b));
    }
}

template <int P>
void ParameterState<P>::releaseExponents() {
    for (int b = 0; b < materials_; ++b) held_[std::size_t(b)].n = false;
}

template <int P>
void ParameterState<P>::releaseLobe(int b) {
    HeldParams& h = held_[std::size_t(b)];
    h.ks.fill(false);
    h.n = false;
}

template <int P>
void ParameterState<P>::holdAll(int b) {
    HeldParams& h = held_[std::size_t(b)];
    h.kd.fill(true);
    h.ks.fill(true);
    h.n = true;
}

template <int P>
typename ParameterState<P>::NaturalVector ParameterState<P>::natural(int b) const {
    NaturalVector y;
    toNatural<P>(block(b), held(b), y.data());
    return y;
}

template <int P>
void ParameterState<P>::setNatural(int b, const double* y) {
    toInternal<P>(y, held(b), block(b));
}

template <int P>
std::vector<double> ParameterState<P>::naturalCoordinates() const {
    std::vector<double> y(held_.size() * P);
    for (int b = 0; b < blockCount(); ++b)
        toNatural<P>(block(b), held(b), y.data() + std::size_t(b) * P);
    return y;
}

template <int P>
std::vector<typename ParameterState<P>::NaturalVector> ParameterState<P>::naturalBlocks() const {
    std::vector<NaturalVector> y(held_.size());
    for (int b = 0; b < blockCount(); ++b) toNatural<P>(block(b), held(b), y[b].data());
    return y;
}

template <int P>
std::vector<typename ParameterState<P>::NaturalVector> ParameterState<P>::naturalBlocks(
    const Estimate& estimate) const {
    std::vector<NaturalVector> y;
    for (const PhongMaterial& m : estimate.materials) y.push_back(naturalFromPhong<P>(m));
    if (exposure_.fitted())
        y.push_back(naturalFromPhong<P>(ExposureBlock::asMaterial(estimate.exposure)));
    return y;
}

template <int P>
bool ParameterState<P>::isHeld(const HeldParams& h, int i) {
    if (i == L::kLogN) return h.n;
    return i < L::kGroups ? h.kd[i] : h.ks[i - L::kGroups];
}

template <int P>
std::vector<bool> ParameterState<P>::heldFlags(const std::vector<HeldParams>& held) {
    std::vector<bool> flags(held.size() * P);
    for (std::size_t b = 0; b < held.size(); ++b)
        for (int i = 0; i < P; ++i) flags[b * P + i] = isHeld(held[b], i);
    return flags;
}

template <int P>
bool ParameterState<P>::hold(const std::vector<int>& indices, bool atStart) {
    bool changed = false;
    for (int index : indices) {
        const int b = index / P, i = index % P;
        if (isHeld(b, i)) continue;
        changed = true;
        if (b == exposure_.slot()) {
            holdExposure();
            continue;
        }
        NaturalVector y = natural(b);
        if (atStart) y[i] = naturalFromPhong<P>(start(b))[i];
        HeldParams& h = held_[std::size_t(b)];
        if (i == L::kLogN)
            h.n = true;
        else if (i < L::kGroups)
            h.kd[i] = true;
        else
            h.ks[i - L::kGroups] = true;
        setNatural(b, y.data());
    }
    return changed;
}

template <int P>
bool ParameterState<P>::holdAtZero(const std::vector<int>& indices) {
    for (int index : indices) {
        const int b = index / P, g = index % P - L::kGroups;
        if (L::kGroups == 3)
            start_[std::size_t(b)].ks[g] = 0;
        else
            start_[std::size_t(b)].ks.setZero();
    }
    return hold(indices);
}

template <int P>
void ParameterState<P>::holdExposure() {
    const int e = exposure_.slot();
    std::vector<NaturalVector> y = naturalBlocks();
    const double current = ExposureBlock::fromCoordinate(y[e][L::kLogN]);
    double highest = 0;  // of kd + ks over the materials' colour groups
    for (int m = 0; m < materials_; ++m)
        for (int g = 0; g < L::kGroups; ++g)
            highest = std::max(highest, y[m][L::diffuse(g)] + y[m][L::specular(g)]);
    const double s =
        ExposureBlock::heldValue(ExposureBlock::fromMaterial(start(e)), current, highest);
    for (int m = 0; m < materials_; ++m) {
        for (int i = 0; i < L::kLogN; ++i)
            if (!isHeld(m, i)) y[m][i] *= current / s;
        setNatural(m, y[m].data());
    }
    held_[std::size_t(e)].n = true;
    start_[std::size_t(e)] = ExposureBlock::asMaterial(s);
    y[e][L::kLogN] = std::log(start(e).n);
    setNatural(e, y[e].data());
}

template <int P>
double ParameterState<P>::exposureValue() const {
    return exposure_.value<P>(naturalCoordinates().data());
}

template <int P>
void ParameterState<P>::setExposure(double s) {
    const int e = exposure_.slot();
    start_[std::size_t(e)] = ExposureBlock::asMaterial(s);
    NaturalVector y = natural(e);
    y[L::kLogN] = std::log(s * kExposureCentre);
    setNatural(e, y.data());
}

template class ParameterState<kRgbBlock>;
template class ParameterState<kGreyBlock>;

}  // namespace phongfit
