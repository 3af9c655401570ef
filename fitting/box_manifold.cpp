#include "box_manifold.h"

#include <algorithm>
#include <cassert>
#include <utility>

namespace phongfit {

BoxManifold::BoxManifold(std::vector<double> lower, std::vector<double> upper,
                         std::vector<bool> held)
    : lower_(std::move(lower)), upper_(std::move(upper)) {
    for (std::size_t i = 0; i < held.size(); ++i)
        if (!held[i]) free_.push_back(int(i));
    assert(!free_.empty() && lower_.size() == held.size() && upper_.size() == held.size());
}

bool BoxManifold::Plus(const double* x, const double* delta, double* xPlusDelta) const {
    std::copy(x, x + AmbientSize(), xPlusDelta);
    for (std::size_t k = 0; k < free_.size(); ++k) {
        const int i = free_[k];
        xPlusDelta[i] = std::clamp(x[i] + delta[k], lower_[i], upper_[i]);
    }
    return true;
}

bool BoxManifold::PlusJacobian(const double*, double* jacobian) const {
    const int tangent = TangentSize();
    std::fill(jacobian, jacobian + AmbientSize() * tangent, 0.0);
    for (int k = 0; k < tangent; ++k) jacobian[free_[k] * tangent + k] = 1;
    return true;
}

bool BoxManifold::RightMultiplyByPlusJacobian(const double*, int rows, const double* ambientMatrix,
                                              double* tangentMatrix) const {
    const int ambient = AmbientSize(), tangent = TangentSize();
    for (int r = 0; r < rows; ++r)
        for (int k = 0; k < tangent; ++k)
            tangentMatrix[r * tangent + k] = ambientMatrix[r * ambient + free_[k]];
    return true;
}

bool BoxManifold::Minus(const double* y, const double* x, double* yMinusX) const {
    for (std::size_t k = 0; k < free_.size(); ++k) yMinusX[k] = y[free_[k]] - x[free_[k]];
    return true;
}

bool BoxManifold::MinusJacobian(const double*, double* jacobian) const {
    const int ambient = AmbientSize();
    std::fill(jacobian, jacobian + TangentSize() * ambient, 0.0);
    for (int k = 0; k < TangentSize(); ++k) jacobian[k * ambient + free_[k]] = 1;
    return true;
}

}  // namespace phongfit
