#include "face_projection.h"

#include <Eigen/LU>
#include <vector>

#include "uncertainty.h"

namespace phongfit {

namespace {

// A Gauss-Newton step that ends further beyond the face than this chi-square of its standard
// errors (5 of them, for one face) is no step within the noise: the cost is not near its quadratic
// model there (a round recorded far from the solution), and the box's minimum stands.
constexpr double kFarBeyondFace = 25;

// Per material and colour group on the face, the flat indices of its kd and ks.
template <int P>
std::vector<std::pair<Eigen::Index, Eigen::Index>> energyFaces(const ParameterState<P>& params) {
    using L = BlockLayout<P>;
    std::vector<std::pair<Eigen::Index, Eigen::Index>> faces;
    for (int s = 0; s < params.materialCount(); ++s)
        for (int g = 0; g < L::kGroups; ++g) {
            const HeldParams& held = params.held(s);
            // u = kd / (1 - ks), the internal coordinate, is 1 on the face.
            if (held.kd[g] || held.ks[g] || !(params.block(s)[L::diffuse(g)] >= 1)) continue;
            faces.emplace_back(Eigen::Index(s) * P + L::diffuse(g),
                               Eigen::Index(s) * P + L::specular(g));
        }
    return faces;
}

}  // namespace

template <int P>
bool onEnergyFace(const ParameterState<P>& params) {
    return !energyFaces(params).empty();
}

template <int P>
bool projectOntoEnergyFace(ParameterState<P>& params, const Eigen::MatrixXd& gram,
                           const Eigen::MatrixXd& scores, const Eigen::VectorXd& gradient) {
    const auto faces = energyFaces(params);
    if (faces.empty()) return false;
    const std::vector<bool> held = params.heldFlags();
    const Eigen::MatrixXd inverse = freeInverse(gram, held);
    const Eigen::MatrixXd covariance = inverse * scores * inverse.transpose();
    const std::vector<double> start = params.naturalCoordinates();
    const Eigen::VectorXd unconstrained =
        Eigen::Map<const Eigen::VectorXd>(start.data(), Eigen::Index(start.size())) -
        inverse * gradient;
    // Constraints A y = 1, one row per face: kd + ks = 1.
    const Eigen::Index k = Eigen::Index(faces.size());
    Eigen::MatrixXd a = Eigen::MatrixXd::Zero(k, unconstrained.size());
    for (Eigen::Index f = 0; f < k; ++f) a(f, faces[f].first) = a(f, faces[f].second) = 1;
    const Eigen::MatrixXd across = a * covariance * a.transpose();
    const Eigen::FullPivLU<Eigen::MatrixXd> lu(across);
    if (!lu.isInvertible()) return false;
    const Eigen::VectorXd beyond = a * unconstrained - Eigen::VectorXd::Ones(k);
    const Eigen::VectorXd pull = lu.solve(beyond);
    if (!(beyond.dot(pull) <= kFarBeyondFace)) return false;
    const Eigen::VectorXd projected = unconstrained - covariance * a.transpose() * pull;
    if (!projected.allFinite()) return false;
    for (int b = 0; b < params.materialCount(); ++b) params.setNatural(b, projected.data() + b * P);
    return true;
}

template bool onEnergyFace<kRgbBlock>(const ParameterState<kRgbBlock>&);
template bool onEnergyFace<kGreyBlock>(const ParameterState<kGreyBlock>&);
template bool projectOntoEnergyFace<kRgbBlock>(ParameterState<kRgbBlock>&, const Eigen::MatrixXd&,
                                               const Eigen::MatrixXd&, const Eigen::VectorXd&);
template bool projectOntoEnergyFace<kGreyBlock>(ParameterState<kGreyBlock>&, const Eigen::MatrixXd&,
                                                const Eigen::MatrixXd&, const Eigen::VectorXd&);

}  // namespace phongfit
