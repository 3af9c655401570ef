#include "objective.h"

#include <algorithm>

#include "replay.h"

namespace phongfit {

std::unique_ptr<ceres::LossFunction> makeLoss(const FitOptions& options, double meanObserved) {
    // Ceres' losses act on the squared norm of a pixel's RGB residual; `a` is in residual units.
    const double a = std::max(options.lossScale * meanObserved, 1e-12);
    switch (options.loss) {
        case LossKind::Huber:
            return std::make_unique<ceres::HuberLoss>(a);
        case LossKind::Cauchy:
            return std::make_unique<ceres::CauchyLoss>(a);
        case LossKind::L2:
            break;
    }
    return nullptr;
}

template <int P>
Objective<P>::Objective(const std::vector<Observation>& observations,
                        const std::vector<PathSet>& first, const std::vector<PathSet>& second,
                        bool instrumental, int radius, int blocks, const ExposureBlock& exposure,
                        const FitOptions& options, int threads)
    : observations_(&observations),
      blocks_(blocks),
      exposure_(exposure),
      recordings_{&first, &second},
      instrumental_(instrumental),
      prep_(selectUsedPixels(observations, &first == &second ? SetLists{&first} : recordings_,
                             blocks, radius, exposure)),
      loss_(makeLoss(options, prep_.meanObserved)),
      arena_(threads) {}

template <int P>
double Objective<P>::lossWeight(double squaredNorm) const {
    double rho[3] = {0, 1, 0};
    if (loss_) loss_->Evaluate(squaredNorm, rho);
    return rho[1];
}

template <int P>
std::span<const std::uint32_t> Objective<P>::materialSlots(const UsedPixel& u) const {
    const std::span<const std::uint32_t> slots = prep_.slotsOf(u);
    const bool exposed =
        exposure_.fitted() && !slots.empty() && slots.back() == std::uint32_t(exposure_.slot());
    return slots.first(slots.size() - exposed);
}

template <int P>
Eigen::Vector3d Objective<P>::residual(int k, const UsedPixel& u, const double* y, Scratch& scratch,
                                       bool jacobians) const {
    if (!instrumental_) return pooledResidual(u, y, scratch, jacobians);
    return residual((*recordings_[k])[u.view], u, y, scratch,
                    jacobians ? &scratch.jacobians[k] : nullptr);
}

template <int P>
Eigen::Vector3d Objective<P>::pooledResidual(const UsedPixel& u, const double* y, Scratch& scratch,
                                             bool jacobians) const {
    std::vector<Jacobian>* ja = jacobians ? &scratch.jacobians[0] : nullptr;
    const Eigen::Vector3d ra = residual((*recordings_[0])[u.view], u, y, scratch, ja);
    if (recordings_[0] == recordings_[1]) return ra;
    std::vector<Jacobian>* jb = jacobians ? &scratch.jacobians[1] : nullptr;
    const Eigen::Vector3d rb = residual((*recordings_[1])[u.view], u, y, scratch, jb);
    for (std::uint32_t a = 0; jacobians && a < u.slotCount; ++a)
        (*ja)[a] = 0.5 * ((*ja)[a] + (*jb)[a]);
    return 0.5 * (ra + rb);
}

// The exposure's block, the last of a pixel's when it is fitted, is not replayed: the prediction
// is s I and its derivative with respect to log s is s I.
template <int P>
Eigen::Vector3d Objective<P>::residual(const PathSet& paths, const UsedPixel& u, const double* y,
                                       Scratch& scratch, std::vector<Jacobian>* jacobians) const {
    using L = BlockLayout<P>;
    const std::span<const std::uint32_t> materials = materialSlots(u);
    const bool exposed = materials.size() < u.slotCount;
    const double s = exposure_.value<P>(y);
    const double w = weight(u);
    Color3 predicted = Color3::Zero();
    if (jacobians != nullptr) jacobians->resize(u.slotCount);
    if (jacobians != nullptr && !materials.empty()) {
        std::vector<Jacobian>& j = *jacobians;
        for (std::size_t b = 0; b < materials.size(); ++b) {
            predicted = replayNaturalJacobian<P>(paths, u.pixel, materials, y, materials[b],
                                                 scratch.jets, j[b]);
            j[b] *= w * s;
        }
    } else {
        for (std::uint32_t m : materials)
            scratch.plain[m] = naturalToPhong<P>(y + std::size_t(m) * P);
        predicted = replayPixel(paths, u.pixel, scratch.plain.data());
    }
    if (jacobians != nullptr && exposed) {
        Jacobian& j = (*jacobians)[u.slotCount - 1];
        j.setZero();
        j.col(L::kLogN) = w * s * predicted.matrix();
    }
    return (w * (s * predicted - pixelObserved((*observations_)[u.view], u.pixel))).matrix();
}

template <int P>
Eigen::Matrix3d Objective<P>::pathCovariance(int k, const UsedPixel& u, const double* y,
                                             Scratch& scratch) const {
    for (std::uint32_t m : materialSlots(u))
        scratch.plain[m] = naturalToPhong<P>(y + std::size_t(m) * P);
    const double scale = weight(u) * exposure_.value<P>(y);
    return scale * scale *
           replayPathCovariance(recording(k, u.view), u.pixel, scratch.plain.data());
}

namespace {

// Least squares' sum of squares and (if sized) its gradient and Gauss-Newton matrix, over pixels.
struct NormalSums {
    double squares = 0;
    Eigen::VectorXd gradient;
    Eigen::MatrixXd gramian;

    NormalSums& operator+=(const NormalSums& other) {
        squares += other.squares;
        gradient += other.gradient;
        gramian += other.gramian;
        return *this;
    }
};

}  // namespace

template <int P>
void Objective<P>::leastSquaresSums(const double* y, const std::vector<double>& weights, bool cross,
                                    double& squares, Eigen::VectorXd* gradient,
                                    Eigen::MatrixXd* gramian) {
    const Eigen::Index size = Eigen::Index(blocks_) * P;
    const bool withJacobian = gradient != nullptr;
    const NormalSums zero{0.0, withJacobian ? Eigen::VectorXd::Zero(size) : Eigen::VectorXd(),
                          withJacobian ? Eigen::MatrixXd::Zero(size, size) : Eigen::MatrixXd()};
    NormalSums sums = sumPixels(
        prep_.seeingMaterial, zero, [&](std::size_t i, NormalSums& sum, Scratch& scratch) {
            const UsedPixel& u = prep_.pixels[i];
            const double w = weights.empty() ? 1.0 : weights[i];
            if (cross) {
                const Eigen::Vector3d ra = residual(0, u, y, scratch, withJacobian);
                const Eigen::Vector3d rb = residual(1, u, y, scratch, withJacobian);
                sum.squares += w * ra.dot(rb);
                if (!withJacobian) return;
                const std::span<const std::uint32_t> slots = prep_.slotsOf(u);
                const std::vector<Jacobian>& ja = scratch.jacobians[0];
                const std::vector<Jacobian>& jb = scratch.jacobians[1];
                for (std::uint32_t a = 0; a < u.slotCount; ++a) {
                    const Eigen::Index row = Eigen::Index(slots[a]) * P;
                    addPackedGradient<P>(sum.gradient.template segment<P>(row), 0.5 * w, ja[a], rb);
                    addPackedGradient<P>(sum.gradient.template segment<P>(row), 0.5 * w, jb[a], ra);
                    for (std::uint32_t b = 0; b < u.slotCount; ++b) {
                        addPackedGram<P>(
                            sum.gramian.template block<P, P>(row, Eigen::Index(slots[b]) * P),
                            0.5 * w, ja[a], jb[b]);
                        addPackedGram<P>(
                            sum.gramian.template block<P, P>(row, Eigen::Index(slots[b]) * P),
                            0.5 * w, jb[a], ja[b]);
                    }
                }
                return;
            }
            const Eigen::Vector3d r = pooledResidual(u, y, scratch, withJacobian);
            const std::vector<Jacobian>& j = scratch.jacobians[0];
            sum.squares += w * r.squaredNorm();
            if (!withJacobian) return;
            const std::span<const std::uint32_t> slots = prep_.slotsOf(u);
            for (std::uint32_t a = 0; a < u.slotCount; ++a) {
                const Eigen::Index row = Eigen::Index(slots[a]) * P;
                addPackedGradient<P>(sum.gradient.template segment<P>(row), w, j[a], r);
                for (std::uint32_t b = 0; b < u.slotCount; ++b)
                    addPackedGram<P>(
                        sum.gramian.template block<P, P>(row, Eigen::Index(slots[b]) * P), w, j[a],
                        j[b]);
            }
        });
    squares = sums.squares;
    if (!withJacobian) return;
    *gradient = std::move(sums.gradient);
    *gramian = std::move(sums.gramian);
}

template <int P>
double Objective<P>::crossScale(const double* y, const std::vector<double>& weights) {
    const NormalSums zero{0.0, Eigen::VectorXd(), Eigen::MatrixXd()};
    return sumPixels(prep_.seeingMaterial, zero,
                     [&](std::size_t i, NormalSums& sum, Scratch& scratch) {
                         const UsedPixel& u = prep_.pixels[i];
                         const double w = weights.empty() ? 1.0 : weights[i];
                         sum.squares += 0.5 * w *
                                        (residual(0, u, y, scratch, false).squaredNorm() +
                                         residual(1, u, y, scratch, false).squaredNorm());
                     })
        .squares;
}

template <int P>
Eigen::Vector2d Objective<P>::crossDifference(const double* y, const double* base) {
    return sumPixels(
        prep_.seeingMaterial, Eigen::Vector2d::Zero().eval(),
        [&](std::size_t i, Eigen::Vector2d& sum, Scratch& scratch) {
            const UsedPixel& u = prep_.pixels[i];
            const double d =
                residual(0, u, y, scratch, false).dot(residual(1, u, y, scratch, false)) -
                residual(0, u, base, scratch, false).dot(residual(1, u, base, scratch, false));
            sum += Eigen::Vector2d(d, d * d);
        });
}

template class Objective<kRgbBlock>;
template class Objective<kGreyBlock>;

}  // namespace phongfit
