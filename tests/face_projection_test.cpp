#include "face_projection.h"

#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <cmath>
#include <numbers>

#include "rng.h"

namespace phongfit {
namespace {

using L = BlockLayout<kGreyBlock>;
constexpr int P = kGreyBlock;

// A standard normal (Box-Muller) from the counter-based generator.
double normal(const CounterRng& rng, std::uint64_t sample, std::uint32_t dimension) {
    const double u = 1 - rng.uniform(sample, 2 * dimension);
    const double v = rng.uniform(sample, 2 * dimension + 1);
    return std::sqrt(-2 * std::log(u)) * std::cos(2 * std::numbers::pi * v);
}

// A truth on kd + ks = 1; unconstrained estimates around it with covariance V, minimised over the
// box in the metric H of a cost whose scores S = H V H. Where an estimate crosses the face, the
// box's minimum is its projection along H, biased along the face; projectOntoEnergyFace, given
// the cost's matrix, gradient and scores there, is unbiased.
TEST(FaceProjection, RemovesTheBiasOfTheBoxMinimumAlongTheFace) {
    const Eigen::Vector3d truth(0.3, 0.7, std::log(100.0));
    const double sigma = 0.01;
    Eigen::Matrix3d v;
    v << 1, -0.5, 0.3, -0.5, 4, 0.5, 0.3, 0.5, 2;
    v *= sigma * sigma;
    const Eigen::LLT<Eigen::Matrix3d> cholesky(v);
    ASSERT_EQ(cholesky.info(), Eigen::Success);
    const Eigen::Matrix3d h = Eigen::Matrix3d::Identity() / (sigma * sigma);
    const Eigen::MatrixXd s = h * v * h;
    const Eigen::Vector3d a(1, 1, 0);  // the face: a . y = 1
    const Eigen::Vector3d hInverseA = h.inverse() * a;
    const CounterRng rng(7, 0);
    Eigen::Vector3d boxSum = Eigen::Vector3d::Zero(), projectedSum = Eigen::Vector3d::Zero();
    Eigen::Vector3d projectedSquares = Eigen::Vector3d::Zero();
    int crossed = 0;
    for (std::uint64_t i = 0; i < 20000; ++i) {
        const Eigen::Vector3d z(normal(rng, i, 0), normal(rng, i, 1), normal(rng, i, 2));
        const Eigen::Vector3d unconstrained = truth + cholesky.matrixL() * z;
        const double beyond = a.dot(unconstrained) - 1;
        if (beyond <= 0) continue;  // inside the box: its own minimum
        ++crossed;
        const Eigen::Vector3d box = unconstrained - hInverseA * beyond / a.dot(hInverseA);
        ParameterState<P> params({{Color3::Constant(0.3), Color3::Constant(0.7), 100}}, false);
        params.setInternal({1.0, box[L::specular(0)], box[L::kLogN]});
        ASSERT_TRUE(onEnergyFace(params));
        ASSERT_TRUE(projectOntoEnergyFace(params, h, s, h * (box - unconstrained)));
        const Eigen::Vector3d projected = params.natural(0);
        ASSERT_NEAR(projected[0] + projected[1], 1.0, 1e-12);
        boxSum += box - truth;
        projectedSum += projected - truth;
        projectedSquares += (projected - truth).cwiseAbs2();
    }
    ASSERT_GT(crossed, 8000);
    const Eigen::Vector3d boxMean = boxSum / crossed, mean = projectedSum / crossed;
    const Eigen::Vector3d standardError =
        ((projectedSquares / crossed - mean.cwiseAbs2()) / crossed).cwiseSqrt();
    for (int i : {L::diffuse(0), L::kLogN}) {
        EXPECT_LT(std::abs(mean[i]), 3 * standardError[i]) << i;
        // The box's minimum is off by far more: what the projection is for.
        EXPECT_GT(std::abs(boxMean[i]), 20 * standardError[i]) << i;
    }
}

TEST(FaceProjection, LeavesAMinimumOffTheFaceWhereItIs) {
    ParameterState<P> params({{Color3::Constant(0.3), Color3::Constant(0.6), 100}}, false);
    EXPECT_FALSE(onEnergyFace(params));
    const std::vector<double> before = params.internal();
    EXPECT_FALSE(projectOntoEnergyFace(params, Eigen::Matrix3d::Identity(),
                                       Eigen::Matrix3d::Identity(), Eigen::Vector3d(1, 1, 1)));
    EXPECT_EQ(params.internal(), before);
}

// A Gauss-Newton step that ends 7 standard errors beyond the face is no step within the noise
// (a round recorded far from its solution): the box's minimum stands. One that ends 0.07 of them
// beyond is taken.
TEST(FaceProjection, DeclinesAStepFarBeyondTheFace) {
    const double sigma = 0.01;
    const Eigen::Matrix3d h = Eigen::Matrix3d::Identity() / (sigma * sigma);
    for (const double step : {0.1, 0.001}) {
        ParameterState<P> params({{Color3::Constant(0.3), Color3::Constant(0.7), 100}}, false);
        params.setInternal({1.0, 0.7, std::log(100.0)});
        ASSERT_TRUE(onEnergyFace(params));
        const std::vector<double> before = params.internal();
        const Eigen::Vector3d beyond(step, 0, step);
        const bool moved = projectOntoEnergyFace(params, h, h, -h * beyond);
        EXPECT_EQ(moved, step < 0.01) << step;
        EXPECT_EQ(params.internal() == before, !moved) << step;
        EXPECT_NEAR(params.natural(0)[L::diffuse(0)] + params.natural(0)[L::specular(0)], 1.0,
                    1e-12);
    }
}

}  // namespace
}  // namespace phongfit
