// The fit's objective on one round's path sets: the used pixels, each pixel's weighted residual
// and its Jacobian, and the least-squares sums over pixels.
//
// A pixel's residual in set k is r_k = weight (s I_k(y) - observed), with I_k the replayed
// prediction (replay.h) and s the exposure (1 unless fitted). Every sum over pixels runs through
// sumPixels(), deterministic whatever the thread count (pixel_sums.h).
#pragma once

#include <ceres/loss_function.h>
#include <tbb/task_arena.h>

#include <Eigen/Core>
#include <array>
#include <memory>
#include <span>
#include <vector>

#include "exposure_block.h"
#include "fitter.h"
#include "material_params.h"
#include "pixel_sums.h"
#include "replay_jacobian.h"
#include "round_paths.h"
#include "used_pixels.h"

namespace phongfit {

// The robust loss of FitOptions::loss, scaled by lossScale * meanObserved; null for L2.
std::unique_ptr<ceres::LossFunction> makeLoss(const FitOptions& options, double meanObserved);

template <int P>
class Objective {
public:
    using Jacobian = Eigen::Matrix<double, 3, P>;

    // Per block of pixels: what replaying them needs.
    struct Scratch {
        std::vector<PhongParams<PackedJet>> jets;
        std::vector<PhongMaterial> plain;
        std::array<std::vector<Jacobian>, 2> jacobians;  // per set, per slot of the pixel
        Eigen::VectorXd moment;                          // P per slot of the pixel
        Eigen::MatrixXd momentJacobian;
        std::vector<Eigen::Index> indices;  // of the pixel's natural coordinates
    };

    // `instrumental`: replay both recordings (else the least-squares sets); `radius`: see
    // selectUsedPixels; `blocks`: parameter blocks (materials, then the exposure if fitted).
    Objective(const std::vector<Observation>& observations, const std::vector<PathSet>& first,
              const std::vector<PathSet>& second, bool instrumental, int radius, int blocks,
              const ExposureBlock& exposure, const FitOptions& options, int threads);

    const UsedPixels& pixels() const { return prep_; }
    double weight(const UsedPixel& u) const {
        return pixelWeight((*observations_)[u.view], u.pixel);
    }
    Color3 observed(const UsedPixel& u) const {
        return pixelObserved((*observations_)[u.view], u.pixel);
    }
    int blocks() const { return blocks_; }
    int setCount() const { return instrumental_ ? 2 : 1; }
    const ExposureBlock& exposure() const { return exposure_; }
    tbb::task_arena& arena() { return arena_; }
    bool robust() const { return loss_ != nullptr; }  // FitOptions::loss is not L2

    // The weight rho' the robust loss gives a pixel with this squared residual norm (1 for L2).
    double lossWeight(double squaredNorm) const;

    // The weighted residual of pixel u in set k at flat natural coordinates y; with `jacobians`,
    // also its weighted Jacobians per slot of the pixel, in scratch.jacobians[k]. The
    // instrumental sets are the two recordings; least squares' one set is their pool.
    Eigen::Vector3d residual(int k, const UsedPixel& u, const double* y, Scratch& scratch,
                             bool jacobians) const;
    // The residual of the recordings' pool (both recordings' paths at half weight: the mean of
    // their predictions, so it is replayed as that, not kept as a third copy of the paths), its
    // Jacobians in scratch.jacobians[0]. Exact, noise-free recordings are their own pool.
    Eigen::Vector3d pooledResidual(const UsedPixel& u, const double* y, Scratch& scratch,
                                   bool jacobians) const;
    // The same in `paths`, Jacobians (if not null) into `jacobians`.
    Eigen::Vector3d residual(const PathSet& paths, const UsedPixel& u, const double* y,
                             Scratch& scratch, std::vector<Jacobian>* jacobians) const;

    // The two recordings are one exact, noise-free list.
    bool exact() const { return recordings_[0] == recordings_[1]; }
    // Recording k (0 or 1) of a view.
    const PathSet& recording(int k, std::uint32_t view) const { return (*recordings_[k])[view]; }
    // The covariance over channels of one path of pixel u in recording k at y
    // (replayPathCovariance), in the weighted residual's units: times (weight * exposure)^2.
    Eigen::Matrix3d pathCovariance(int k, const UsedPixel& u, const double* y,
                                   Scratch& scratch) const;

    // Sum over the first `count` used pixels of body(pixel index, sum, scratch).
    template <typename Value, typename Body>
    Value sumPixels(std::size_t count, const Value& zero, const Body& body) {
        return sumOverPixels(
            arena_, count, zero,
            [this] {
                Scratch scratch;
                scratch.jets.resize(blocks_);
                scratch.plain.resize(blocks_);
                return scratch;
            },
            body);
    }

    // Over the pixels that see a material (the others' residuals do not depend on y): the sum
    // of w |r|^2 in the least-squares sets, with w the robust `weights` per pixel (empty: all 1),
    // and if `gradient` is not null of w J^T r and w J^T J (into `gramian`). With `cross`, of
    // w r_A . r_B over the two recordings instead, and of the symmetrised w (J_A^T r_B + J_B^T
    // r_A) / 2 and w (J_A^T J_B + J_B^T J_A) / 2.
    void leastSquaresSums(const double* y, const std::vector<double>& weights, bool cross,
                          double& squares, Eigen::VectorXd* gradient, Eigen::MatrixXd* gramian);

    // Over the same pixels, the sum of d = r_A . r_B at y minus at `base` (robust weights 1),
    // and of d^2: how much better the cross products fit at y, and (the pixels' recordings being
    // independent) the variance of that sum about its expectation, its sum of squares.
    Eigen::Vector2d crossDifference(const double* y, const double* base);

    // Over the same pixels, the sum of w (|r_A|^2 + |r_B|^2) / 2: at least |w r_A . r_B| pixel by
    // pixel, the scale of the recordings' noise against which the cross products are minimised.
    double crossScale(const double* y, const std::vector<double>& weights);

private:
    // The pixel's slots that are materials (all but the exposure's, when it is fitted).
    std::span<const std::uint32_t> materialSlots(const UsedPixel& u) const;

    const std::vector<Observation>* observations_;
    int blocks_;
    ExposureBlock exposure_;
    // The two recordings; exact, noise-free sets are passed as the same list twice.
    SetLists recordings_;
    bool instrumental_;
    UsedPixels prep_;
    std::unique_ptr<ceres::LossFunction> loss_;
    tbb::task_arena arena_;
};

extern template class Objective<kRgbBlock>;
extern template class Objective<kGreyBlock>;

}  // namespace phongfit
