// What the solver moves: the parameter blocks by kind, as Ceres sees them (internal coordinates,
// material_params.h), with the coordinates held at their start because the images do not
// constrain them.
//
// Blocks 0 .. materialCount() - 1 are the materials, one per slot of the path sets; with
// FitOptions::fitExposure one more block, the exposure (exposure_block.h), follows. "Flat"
// coordinates are all blocks' natural coordinates in a row, P per block, as the sums over pixels
// take them; index slot * P + i names one parameter.
#pragma once

#include <Eigen/Core>
#include <vector>

#include "exposure_block.h"
#include "material_params.h"
#include "phong_brdf.h"

namespace phongfit {

// An estimate by kind: one material per material block, and the exposure (1 when not fitted).
struct Estimate {
    std::vector<PhongMaterial> materials;
    double exposure = 1;
};

template <int P>
class ParameterState {
public:
    using L = BlockLayout<P>;
    using NaturalVector = Eigen::Matrix<double, P, 1>;

    // `start`: the materials' start values, which held parameters keep. The exposure starts at 1
    // until setExposure (the first round matches it to the images).
    ParameterState(const std::vector<PhongMaterial>& start, bool fitExposure);

    int materialCount() const { return materials_; }
    int blockCount() const { return int(held_.size()); }
    const ExposureBlock& exposure() const { return exposure_; }

    // By block; the residuals keep a view of it while Ceres runs.
    const std::vector<HeldParams>& held() const { return held_; }
    const HeldParams& held(int b) const { return held_[std::size_t(b)]; }
    const PhongMaterial& start(int b) const { return start_[std::size_t(b)]; }

    double* block(int b) { return x_.data() + std::size_t(b) * P; }
    const double* block(int b) const { return x_.data() + std::size_t(b) * P; }
    // All internal coordinates, to keep a point and return to it.
    const std::vector<double>& internal() const { return x_; }
    void setInternal(const std::vector<double>& x) { x_ = x; }

    // A round's start: every block at `estimate`, its held coordinates at their start values.
    void startAt(const Estimate& estimate);
    // Whether the images show a lobe is decided anew each round: a material's n is free again.
    void releaseExponents();
    // Material b's ks and n free again (a lobe lost, lost_lobe.h).
    void releaseLobe(int b);
    // A block no used pixel sees is held whole.
    void holdAll(int b);

    NaturalVector natural(int b) const;
    void setNatural(int b, const double* y);         // clamped into the box (toInternal)
    std::vector<double> naturalCoordinates() const;  // flat
    std::vector<NaturalVector> naturalBlocks() const;
    // Natural coordinates of an estimate, per block, as the convergence test compares them.
    std::vector<NaturalVector> naturalBlocks(const Estimate& estimate) const;

    static bool isHeld(const HeldParams& h, int i);
    bool isHeld(int b, int i) const { return isHeld(held_[std::size_t(b)], i); }
    // Per flat coordinate.
    static std::vector<bool> heldFlags(const std::vector<HeldParams>& held);
    std::vector<bool> heldFlags() const { return heldFlags(held_); }

    // Holds the flat parameters `indices` at their start values (or where they are, `atStart`
    // false), keeping the block's other parameters where they are; the exposure as holdExposure
    // does. True if any was free.
    bool hold(const std::vector<int>& indices, bool atStart = true);
    // Holds the flat ks parameters `indices` at 0, their start too (a round's startAt restores held
    // coordinates from the start): a lobe the images do not show. True if any was free.
    bool holdAtZero(const std::vector<int>& indices);

    // The exposure now, and (ExposureBlock::matched) its start and value set to s.
    double exposureValue() const;
    void setExposure(double s);

private:
    // An exposure the images do not constrain trades against the scale of every kd and ks: it
    // is held at ExposureBlock::heldValue and the free kd and ks rescaled to keep s kd and s ks.
    void holdExposure();

    int materials_;
    ExposureBlock exposure_;
    std::vector<PhongMaterial> start_;  // by block; the exposure's as ExposureBlock::asMaterial
    std::vector<HeldParams> held_;
    std::vector<double> x_;  // internal coordinates, P per block
};

extern template class ParameterState<kRgbBlock>;
extern template class ParameterState<kGreyBlock>;

}  // namespace phongfit
