// A parameter block's bounds and held coordinates as one Ceres manifold: the tangent space is the
// free coordinates, and Plus clamps x + delta into [lower, upper], the projection Ceres applies to
// bounded parameters itself. Ceres then treats the problem as unconstrained and skips the projected
// line search it runs on every iteration of a bounded problem, which costs an extra Jacobian
// evaluation per iteration (half the time of an iteration here) for little gain.
#pragma once

#include <ceres/manifold.h>

#include <vector>

namespace phongfit {

class BoxManifold final : public ceres::Manifold {
public:
    // `held[i]`: coordinate i stays where it is. At least one coordinate must be free.
    BoxManifold(std::vector<double> lower, std::vector<double> upper, std::vector<bool> held);

    int AmbientSize() const override { return int(lower_.size()); }
    int TangentSize() const override { return int(free_.size()); }
    bool Plus(const double* x, const double* delta, double* xPlusDelta) const override;
    bool PlusJacobian(const double* x, double* jacobian) const override;
    // Column selection, called once per residual block and evaluation.
    bool RightMultiplyByPlusJacobian(const double* x, int rows, const double* ambientMatrix,
                                     double* tangentMatrix) const override;
    bool Minus(const double* y, const double* x, double* yMinusX) const override;
    bool MinusJacobian(const double* x, double* jacobian) const override;

private:
    std::vector<double> lower_, upper_;
    std::vector<int> free_;  // ambient index of each tangent coordinate
};

}  // namespace phongfit
