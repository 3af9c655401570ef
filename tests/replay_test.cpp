#include "replay.h"

#include <ceres/gradient_checker.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include "least_squares_residual.h"
#include "material_params.h"
#include "moment_residual.h"
#include "replay_jacobian.h"

namespace phongfit {
namespace {

// A vertex as generated: the directions it came from, so the model can be evaluated directly.
struct DirectVertex {
    std::uint32_t slot;
    Vec3d wi, wo;
};
struct DirectTerm {
    Color3 constant;
    std::vector<DirectVertex> vertices;
};

Vec3d randomUpper(std::mt19937& rng) {
    std::normal_distribution<double> normal;
    Vec3d w;
    do {
        w = Vec3d(normal(rng), normal(rng), normal(rng));
    } while (w.norm() < 1e-3);
    w.normalize();
    w.z() = std::abs(w.z()) + 0.05;
    return w.normalized();
}

// Pixels with 0 to 4 terms of 1 to 3 vertices on two slots; vertex directions random in the upper
// hemisphere, some of them right on the mirror direction (the lobe's peak).
struct RandomPaths {
    PathSet paths;
    std::vector<std::vector<DirectTerm>> direct;  // per pixel

    explicit RandomPaths(int pixels, unsigned seed) {
        std::mt19937 rng(seed);
        std::uniform_real_distribution<double> uniform(0, 1);
        paths.width = pixels;
        paths.height = 1;
        paths.spp = 4;
        paths.slots = 2;
        direct.resize(pixels);
        paths.pixelStart.push_back(0);
        for (int p = 0; p < pixels; ++p) {
            paths.background.push_back(Color<float>(0.01f * float(p % 3), 0.02f, 0.0f));
            const int terms = p % 5;
            for (int t = 0; t < terms; ++t) {
                DirectTerm dt;
                dt.constant = Color3(uniform(rng), uniform(rng), uniform(rng)) * 2;
                PathTerm term;
                term.pixel = std::uint32_t(p);
                term.firstVertex = std::uint32_t(paths.vertices.size());
                term.vertexCount = 1 + (p + t) % 3;
                term.constant = dt.constant.cast<float>();
                for (std::uint32_t k = 0; k < term.vertexCount; ++k) {
                    DirectVertex v;
                    v.slot = (p + t + k) % 2;
                    v.wo = randomUpper(rng);
                    v.wi = (p + k) % 4 == 0 ? reflectLocal(v.wo) : randomUpper(rng);
                    dt.vertices.push_back(v);
                    paths.vertices.push_back({float(logCosAlpha(v.wi, v.wo)), v.slot});
                }
                paths.terms.push_back(term);
                direct[p].push_back(dt);
            }
            paths.pixelStart.push_back(std::uint32_t(paths.terms.size()));
        }
    }

    Color3 directEvaluation(int p, const std::vector<PhongMaterial>& theta) const {
        Color3 sum = paths.background[p].cast<double>();
        for (const DirectTerm& t : direct[p]) {
            Color3 f = Color3::Ones();
            for (const DirectVertex& v : t.vertices) f *= phongEval(theta[v.slot], v.wi, v.wo);
            sum += t.constant * f;
        }
        return sum;
    }
};

std::vector<PhongMaterial> twoMaterials() {
    PhongMaterial a, b;
    a.kd = Color3(0.5, 0.3, 0.2);
    a.ks = Color3(0.2, 0.4, 0.1);
    a.n = 30;
    b.kd = Color3(0.1, 0.6, 0.3);
    b.ks = Color3(0.7, 0.1, 0.4);
    b.n = 800;
    return {a, b};
}

TEST(Replay, EqualsDirectEvaluationOfTheModel) {
    const RandomPaths r(60, 1);
    const std::vector<PhongMaterial> theta = twoMaterials();
    int withTerms = 0;
    for (int p = 0; p < r.paths.width; ++p) {
        const Color3 replayed = replayPixel(r.paths, p, theta.data());
        const Color3 direct = r.directEvaluation(p, theta);
        withTerms += !r.direct[p].empty();
        for (int c = 0; c < 3; ++c) {
            // logCos is stored in float: n * (float rounding of log cos) of relative error.
            EXPECT_NEAR(replayed[c], direct[c], 1e-5 * (1 + std::abs(direct[c])))
                << "pixel " << p << " channel " << c;
        }
    }
    EXPECT_GT(withTerms, 40);
}

// Every entry of a pixel's 3 x 3 `actual` within `relative` (1 + |entry|) of `expected`'s.
void expectNear(const Eigen::Matrix3d& actual, const Eigen::Matrix3d& expected, double relative,
                int pixel) {
    for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b)
            EXPECT_NEAR(actual(a, b), expected(a, b), relative * (1 + std::abs(expected(a, b))))
                << pixel << " " << a << b;
}

// Each term taken as one of the pixel's N paths (spp, or pixelPaths where set): N sum t t^T -
// (sum t)(sum t)^T over channels, its diagonal at least 0, with t the terms' values at theta
// (their constants hold 1 / N).
TEST(Replay, PathCovarianceIsTheSpreadOfThePixelsTerms) {
    RandomPaths r(60, 2);
    const std::vector<PhongMaterial> theta = twoMaterials();
    const auto expected = [&](int p, double paths) -> Eigen::Matrix3d {
        Eigen::Vector3d sum = Eigen::Vector3d::Zero();
        Eigen::Matrix3d squares = Eigen::Matrix3d::Zero();
        for (const DirectTerm& t : r.direct[p]) {
            Color3 f = Color3::Ones();
            for (const DirectVertex& v : t.vertices) f *= phongEval(theta[v.slot], v.wi, v.wo);
            const Eigen::Vector3d x = (t.constant * f).matrix();
            sum += x;
            for (int a = 0; a < 3; ++a)
                for (int b = 0; b < 3; ++b) squares(a, b) += x[a] * x[b];
        }
        Eigen::Matrix3d c = paths * squares - sum * sum.transpose();
        for (int a = 0; a < 3; ++a) c(a, a) = std::max(c(a, a), 0.0);
        return c;
    };
    int spread = 0, covarying = 0;
    for (int p = 0; p < r.paths.width; ++p) {
        const Eigen::Matrix3d covariance = replayPathCovariance(r.paths, p, theta.data());
        const Eigen::Matrix3d truth = expected(p, r.paths.spp);
        spread += (truth.diagonal().array() > 0).any();
        covarying += std::abs(truth(0, 1)) > 1e-3 * truth(0, 0);
        expectNear(covariance, truth, 1e-4, p);
    }
    EXPECT_GT(spread, 30);
    EXPECT_GT(covarying, 30);
    // Per-pixel path counts where a recording spent more paths in some pixels; a pixel with no
    // term has no spread.
    for (int p = 0; p < r.paths.width; ++p) r.paths.pixelPaths.push_back(std::uint32_t(4 + p % 7));
    for (int p = 0; p < r.paths.width; ++p) {
        const Eigen::Matrix3d covariance = replayPathCovariance(r.paths, p, theta.data());
        const Eigen::Matrix3d truth = expected(p, 4 + p % 7);
        expectNear(covariance, truth, 1e-4, p);
        if (r.direct[p].empty()) {
            EXPECT_TRUE(covariance.isZero(0)) << p;
        }
    }
}

// Under white light on a grey material every term is grey: the channels vary as one, so the
// covariance is its variance in every entry (the image-noise model's sum over channels counts
// them together, not as three independent draws).
TEST(Replay, PathCovarianceOfGreyTermsIsOneVariance) {
    RandomPaths r(60, 4);
    std::vector<PhongMaterial> theta = twoMaterials();
    for (PhongMaterial& m : theta) {
        m.kd = Color3::Constant(m.kd.mean());
        m.ks = Color3::Constant(m.ks.mean());
    }
    for (std::size_t t = 0; t < r.paths.terms.size(); ++t)
        r.paths.terms[t].constant =
            decltype(r.paths.terms[t].constant)::Constant(r.paths.terms[t].constant.mean());
    int spread = 0;
    for (int p = 0; p < r.paths.width; ++p) {
        const Eigen::Matrix3d covariance = replayPathCovariance(r.paths, p, theta.data());
        spread += covariance(0, 0) > 0;
        expectNear(covariance, Eigen::Matrix3d::Constant(covariance(0, 0)), 1e-9, p);
    }
    EXPECT_GT(spread, 30);
}

// A pixel whose ringed and sampled paths are weighted (PathGroups) has its terms scaled by their
// group's weight; the path covariance undoes that, so it is the plain recording's.
TEST(Replay, PathCovarianceUndoesTheWeightsOfRingedAndSampledPaths) {
    const RandomPaths r(60, 3);
    const std::vector<PhongMaterial> theta = twoMaterials();
    PathSet weighted = r.paths;
    weighted.groups.resize(std::size_t(weighted.width));
    for (std::size_t p = 0; p < weighted.groups.size(); ++p) {
        PathGroups& g = weighted.groups[p];
        const std::uint32_t begin = weighted.pixelStart[p], end = weighted.pixelStart[p + 1];
        g.ringedTerms = (end - begin) / 2;
        g.ringedScale = 3.5f + float(p % 3);
        g.sampledScale = 0.25f;
        for (std::uint32_t t = begin; t < end; ++t)
            weighted.terms[t].constant *=
                t - begin < g.ringedTerms ? g.ringedScale : g.sampledScale;
    }
    int spread = 0;
    for (int p = 0; p < r.paths.width; ++p) {
        const Eigen::Matrix3d plain = replayPathCovariance(r.paths, std::size_t(p), theta.data());
        const Eigen::Matrix3d covariance =
            replayPathCovariance(weighted, std::size_t(p), theta.data());
        spread += (plain.diagonal().array() > 0).any();
        expectNear(covariance, plain, 1e-5, p);
    }
    EXPECT_GT(spread, 30);
}

TEST(Replay, VertexBehindTheLobeContributesOnlyDiffuse) {
    PathSet paths;
    paths.width = paths.height = 1;
    paths.slots = 1;
    paths.background = {Color<float>(0.5f, 0.25f, 0.0f)};
    paths.vertices = {{-std::numeric_limits<float>::infinity(), 0}};
    paths.terms = {{0, 0, 1, Color<float>(2.0f, 2.0f, 2.0f)}};
    paths.pixelStart = {0, 1};
    PhongMaterial m;
    m.kd = Color3(0.3, 0.3, 0.3);
    m.ks = Color3(0.5, 0.5, 0.5);
    m.n = 1e6;
    const Color3 value = replayPixel(paths, 0, &m);
    EXPECT_NEAR(value[0], 0.5 + 2 * 0.3 / kPi, 1e-12);
    EXPECT_NEAR(value[2], 2 * 0.3 / kPi, 1e-12);

    using Jet = ceres::Jet<double, 7>;
    const double y[7] = {0.3, 0.3, 0.3, 0.5, 0.5, 0.5, std::log(1e6)};
    Jet yj[7];
    for (int i = 0; i < 7; ++i) yj[i] = Jet(y[i], i);
    const PhongParams<Jet> mj = naturalToPhong<7>(yj);
    const Color<Jet> jet = replayPixel(paths, 0, &mj);
    for (int c = 0; c < 3; ++c) {
        EXPECT_TRUE(jet[c].v.allFinite());
        EXPECT_NEAR(jet[c].v[c], 2 / kPi, 1e-12);
        EXPECT_EQ(jet[c].v[3 + c], 0.0);
        EXPECT_EQ(jet[c].v[6], 0.0);
    }
}

// d I / d (kd, ks, log n) of both slots from Jets against central differences.
TEST(Replay, JetGradientsMatchCentralDifferences) {
    const RandomPaths r(40, 2);
    const std::vector<PhongMaterial> theta = twoMaterials();
    using Jet = ceres::Jet<double, 7>;
    std::vector<Eigen::Matrix<double, 7, 1>> y = {naturalFromPhong<7>(theta[0]),
                                                  naturalFromPhong<7>(theta[1])};
    int checked = 0;
    for (int p = 0; p < r.paths.width; ++p) {
        for (int slot = 0; slot < 2; ++slot) {
            std::vector<PhongParams<Jet>> tj(2);
            for (int s = 0; s < 2; ++s) {
                Jet yj[7];
                for (int i = 0; i < 7; ++i) yj[i] = s == slot ? Jet(y[s][i], i) : Jet(y[s][i]);
                tj[s] = naturalToPhong<7>(yj);
            }
            const Color<Jet> jet = replayPixel(r.paths, p, tj.data());
            for (int i = 0; i < 7; ++i) {
                const double h = 1e-6;
                Color3 value[2];
                for (int side = 0; side < 2; ++side) {
                    auto ys = y;
                    ys[slot][i] += side == 0 ? h : -h;
                    const std::vector<PhongMaterial> t = {naturalToPhong<7>(ys[0].data()),
                                                          naturalToPhong<7>(ys[1].data())};
                    value[side] = replayPixel(r.paths, p, t.data());
                }
                for (int c = 0; c < 3; ++c) {
                    const double numeric = (value[0][c] - value[1][c]) / (2 * h);
                    EXPECT_NEAR(jet[c].v[i], numeric, 1e-5 * (1 + std::abs(numeric)))
                        << "pixel " << p << " slot " << slot << " parameter " << i;
                    checked += numeric != 0;
                }
            }
        }
    }
    EXPECT_GT(checked, 200);
}

// The replays of one-vertex terms (addOneVertexTerm) give what every term through phongEvalLogCos
// gives (termBrdfs), values and derivatives, bit for bit, lobes exactly 0 (n 1e6 off its peak,
// vertices behind it) included. The seeded replay sums the seeded slot's terms in another order
// (SeededOneVertexSums): the same to rounding, a few ulps of the terms' magnitudes.
template <typename T>
Color<T> termByTerm(const PathSet& paths, int pixel, const PhongParams<T>* theta) {
    Color<T> sum;
    for (int c = 0; c < 3; ++c) sum[c] = T(double(paths.background[pixel][c]));
    for (std::uint32_t t = paths.pixelStart[pixel]; t < paths.pixelStart[pixel + 1]; ++t) {
        const Color<T> f = termBrdfs(paths, paths.terms[t], theta);
        for (int c = 0; c < 3; ++c) sum[c] += f[c] * double(paths.terms[t].constant[c]);
    }
    return sum;
}

// Per channel, the sum over the pixel's terms of |f k| in the value and each derivative: the scale
// of their rounding.
Color<PackedJet> termMagnitudes(const PathSet& paths, int pixel,
                                const PhongParams<PackedJet>* theta) {
    Color<PackedJet> sum;
    for (int c = 0; c < 3; ++c) sum[c] = PackedJet(std::abs(double(paths.background[pixel][c])));
    for (std::uint32_t t = paths.pixelStart[pixel]; t < paths.pixelStart[pixel + 1]; ++t) {
        const Color<PackedJet> f = termBrdfs(paths, paths.terms[t], theta);
        for (int c = 0; c < 3; ++c) {
            const double k = std::abs(double(paths.terms[t].constant[c]));
            sum[c].a += std::abs(f[c].a) * k;
            sum[c].v += f[c].v.cwiseAbs() * k;
        }
    }
    return sum;
}

TEST(Replay, OneVertexReplaysAreTheBrdfs) {
    const RandomPaths r(60, 5);
    std::vector<PhongMaterial> theta = twoMaterials();
    int seededDiffer = 0;
    for (const double n : {30.0, 1e6}) {
        theta[0].n = n;
        for (int p = 0; p < r.paths.width; ++p) {
            const Color3 value = replayPixel(r.paths, p, theta.data()),
                         reference = termByTerm(r.paths, p, theta.data());
            for (int c = 0; c < 3; ++c) EXPECT_EQ(value[c], reference[c]) << "pixel " << p;
        }
        for (std::uint32_t seeded = 0; seeded < 2; ++seeded) {
            std::vector<PhongParams<PackedJet>> jets(2);
            for (std::uint32_t s = 0; s < 2; ++s) {
                const Eigen::Matrix<double, kRgbBlock, 1> y = naturalFromPhong<kRgbBlock>(theta[s]);
                jets[s] = s == seeded ? packedParams<kRgbBlock>(y.data())
                                      : constantParams<PackedJet>(theta[s]);
            }
            for (int p = 0; p < r.paths.width; ++p) {
                const Color<PackedJet> reference = termByTerm(r.paths, p, jets.data()),
                                       generic = replayPixel(r.paths, p, jets.data()),
                                       seededJets =
                                           replaySeededPixel(r.paths, p, jets.data(), seeded),
                                       scale = termMagnitudes(r.paths, p, jets.data());
                for (int c = 0; c < 3; ++c) {
                    EXPECT_EQ(generic[c].a, reference[c].a) << "pixel " << p << " n " << n;
                    EXPECT_NEAR(seededJets[c].a, reference[c].a, 1e-14 * scale[c].a)
                        << "pixel " << p << " n " << n;
                    seededDiffer += seededJets[c].a != reference[c].a;
                    for (int i = 0; i < 3; ++i) {
                        EXPECT_EQ(generic[c].v[i], reference[c].v[i])
                            << "pixel " << p << " n " << n << " derivative " << i;
                        EXPECT_NEAR(seededJets[c].v[i], reference[c].v[i], 1e-14 * scale[c].v[i])
                            << "pixel " << p << " n " << n << " derivative " << i;
                    }
                }
            }
        }
    }
    // The tolerance is not idle: the orders differ.
    EXPECT_GT(seededDiffer, 0);
}

// sum over pixels of |1.5 (I_p - observed)|^2 through LeastSquaresResidual: its residual and
// Jacobian must give Ceres the cost, gradient and Gauss-Newton matrix of the stacked per-pixel
// residuals R(x), whose Jacobian is taken here by central differences in the internal
// coordinates (the free ones: Ceres' manifold holds the others).
template <int P>
void checkLeastSquaresBlock(const HeldParams& heldFirst) {
    const RandomPaths r(30, 3);
    const std::vector<PhongMaterial> theta = twoMaterials();
    const std::vector<HeldParams> held = {heldFirst, HeldParams{}};
    double x[2][P];
    for (int s = 0; s < 2; ++s) toInternal<P>(naturalFromPhong<P>(theta[s]).data(), held[s], x[s]);
    const std::vector<std::uint32_t> bothSlots = {0, 1};
    const Color3 observed(0.3, 0.2, 0.1);
    const int pixels = r.paths.width;
    const auto stacked = [&](const double(&at)[2][P]) {
        const std::vector<PhongMaterial> phong = {toPhong<P>(at[0], held[0]),
                                                  toPhong<P>(at[1], held[1])};
        Eigen::VectorXd out(3 * pixels);
        for (int p = 0; p < pixels; ++p)
            out.segment<3>(3 * p) =
                (1.5 * (replayPixel(r.paths, p, phong.data()) - observed)).matrix();
        return out;
    };
    const auto sums = [&](const double* y, double& squares, Eigen::VectorXd* gradient,
                          Eigen::MatrixXd* gramian) {
        squares = 0;
        if (gradient != nullptr) {
            gradient->setZero(2 * P);
            gramian->setZero(2 * P, 2 * P);
        }
        std::vector<PhongParams<PackedJet>> scratch(2);
        for (int p = 0; p < pixels; ++p) {
            Eigen::Matrix<double, 3, P> jacobian[2];
            Color3 predicted;
            for (std::uint32_t b = 0; b < 2; ++b)
                predicted =
                    replayNaturalJacobian<P>(r.paths, p, bothSlots, y, b, scratch, jacobian[b]);
            const Eigen::Vector3d residual = (1.5 * (predicted - observed)).matrix();
            squares += residual.squaredNorm();
            for (int a = 0; gradient != nullptr && a < 2; ++a) {
                gradient->template segment<P>(a * P) += 1.5 * jacobian[a].transpose() * residual;
                for (int b = 0; b < 2; ++b)
                    gramian->template block<P, P>(a * P, b * P) +=
                        2.25 * jacobian[a].transpose() * jacobian[b];
            }
        }
    };
    std::vector<int> free, freeX;  // natural indices; internal ones
    for (int s = 0; s < 2; ++s) {
        const std::vector<int> constant = heldCoordinates<P>(held[s]);
        for (int i = 0; i < P; ++i)
            if (std::find(constant.begin(), constant.end(), i) == constant.end()) {
                free.push_back(s * P + i);
                freeX.push_back(s * P + i);
            }
    }
    const LeastSquaresResidual<P> block(sums, bothSlots, held, free);
    const int f = int(free.size());
    ASSERT_EQ(block.num_residuals(), f + 1);

    Eigen::MatrixXd numeric(3 * pixels, f);
    for (int k = 0; k < f; ++k) {
        double plus[2][P], minus[2][P];
        std::copy(&x[0][0], &x[0][0] + 2 * P, &plus[0][0]);
        std::copy(&x[0][0], &x[0][0] + 2 * P, &minus[0][0]);
        const int s = freeX[k] / P, i = freeX[k] % P;
        const double h = 1e-6 * std::max(1.0, std::abs(x[s][i]));
        plus[s][i] += h;
        minus[s][i] -= h;
        numeric.col(k) = (stacked(plus) - stacked(minus)) / (2 * h);
    }
    const Eigen::VectorXd residuals = stacked(x);

    Eigen::VectorXd c(f + 1), plain(f + 1);
    Eigen::Matrix<double, Eigen::Dynamic, P, Eigen::RowMajor> j0(f + 1, P), j1(f + 1, P);
    double* jacobians[2] = {j0.data(), j1.data()};
    const double* parameters[2] = {x[0], x[1]};
    ASSERT_TRUE(block.Evaluate(parameters, c.data(), jacobians));
    ASSERT_TRUE(block.Evaluate(parameters, plain.data(), nullptr));
    Eigen::MatrixXd jc(f + 1, f);
    for (int k = 0; k < f; ++k) jc.col(k) = (freeX[k] < P ? j0 : j1).col(freeX[k] % P);

    const double cost = residuals.squaredNorm();
    EXPECT_NEAR(c.squaredNorm(), cost, 1e-10 * cost);
    EXPECT_NEAR(plain.squaredNorm(), cost, 1e-10 * cost);
    const Eigen::VectorXd gradient = numeric.transpose() * residuals;
    EXPECT_LE((jc.transpose() * c - gradient).norm(), 1e-6 * gradient.norm())
        << gradient.transpose();
    const Eigen::MatrixXd gauss = numeric.transpose() * numeric;
    EXPECT_LE((jc.transpose() * jc - gauss).norm(), 1e-6 * gauss.norm());
}

TEST(LeastSquaresResidual, GivesTheStackedResidualsCostGradientAndGaussNewtonMatrixRgb) {
    checkLeastSquaresBlock<kRgbBlock>(HeldParams{});
}

TEST(LeastSquaresResidual, GivesTheStackedResidualsCostGradientAndGaussNewtonMatrixGrey) {
    checkLeastSquaresBlock<kGreyBlock>(HeldParams{});
}

TEST(LeastSquaresResidual, GivesTheStackedResidualsCostGradientAndGaussNewtonMatrixWithHeld) {
    HeldParams held;
    held.kd = {true, false, true};
    held.n = true;
    checkLeastSquaresBlock<kRgbBlock>(held);
}

// Moment equations g = sum over pixels and slots of Z^T r, random instruments Z against the
// replay's residuals r, through MomentResidual: the chain rule to the internal coordinates, the
// whitening and the equations of held coordinates left out.
template <int P>
void checkMomentGradients(const HeldParams& heldFirst) {
    const RandomPaths r(30, 4);
    const std::vector<PhongMaterial> theta = twoMaterials();
    const std::vector<HeldParams> held = {heldFirst, HeldParams{}};
    double x[2][P];
    for (int s = 0; s < 2; ++s) toInternal<P>(naturalFromPhong<P>(theta[s]).data(), held[s], x[s]);
    std::mt19937 rng(5);
    std::normal_distribution<double> normal;
    std::vector<Eigen::Matrix<double, 3, P>> z(2 * r.paths.width);  // per pixel and slot
    for (auto& m : z)
        for (int i = 0; i < 3 * P; ++i) m.data()[i] = normal(rng);
    const std::vector<std::uint32_t> bothSlots = {0, 1};
    const auto moments = [&](const double* y, Eigen::VectorXd& g, Eigen::MatrixXd* dg) {
        g.setZero(2 * P);
        if (dg != nullptr) dg->setZero(2 * P, 2 * P);
        std::vector<PhongParams<PackedJet>> scratch(2);
        for (int p = 0; p < r.paths.width; ++p) {
            Eigen::Matrix<double, 3, P> jacobian[2];
            Color3 predicted;
            for (std::uint32_t b = 0; b < 2; ++b)
                predicted =
                    replayNaturalJacobian<P>(r.paths, p, bothSlots, y, b, scratch, jacobian[b]);
            const Eigen::Vector3d residual = (predicted - Color3(0.3, 0.2, 0.1)).matrix();
            for (int a = 0; a < 2; ++a) {
                g.template segment<P>(a * P) += z[2 * p + a].transpose() * residual;
                for (int b = 0; dg != nullptr && b < 2; ++b)
                    dg->template block<P, P>(a * P, b * P) +=
                        z[2 * p + a].transpose() * jacobian[b];
            }
        }
    };
    std::vector<int> free;
    for (int s = 0; s < 2; ++s) {
        const std::vector<int> constant = heldCoordinates<P>(held[s]);
        for (int i = 0; i < P; ++i)
            if (std::find(constant.begin(), constant.end(), i) == constant.end())
                free.push_back(s * P + i);
    }
    const Eigen::Index f = Eigen::Index(free.size());
    Eigen::MatrixXd whitening = Eigen::MatrixXd::Zero(f, f);
    for (Eigen::Index i = 0; i < f; ++i)
        for (Eigen::Index k = 0; k <= i; ++k) whitening(i, k) = i == k ? 1 + i : normal(rng);
    const MomentResidual<P> residual(moments, bothSlots, held, free, whitening);
    ASSERT_EQ(residual.num_residuals(), int(f));

    const std::vector<const ceres::Manifold*>* noManifolds = nullptr;
    ceres::NumericDiffOptions numeric;
    numeric.ridders_relative_initial_step_size = 1e-4;
    ceres::GradientChecker checker(&residual, noManifolds, numeric);
    ceres::GradientChecker::ProbeResults results;
    const double* parameters[2] = {x[0], x[1]};
    checker.Probe(parameters, 1e-6, &results);
    ASSERT_TRUE(results.return_value);
    for (int b = 0; b < 2; ++b) {
        const double scale = results.numeric_jacobians[b].cwiseAbs().maxCoeff();
        EXPECT_GT(scale, 0);
        EXPECT_LE((results.jacobians[b] - results.numeric_jacobians[b]).cwiseAbs().maxCoeff(),
                  1e-7 * scale)
            << "block " << b << "\n"
            << results.error_log;
    }

    // The residuals are L^-1 times the equations kept.
    std::vector<double> y(2 * P);
    for (int s = 0; s < 2; ++s) toNatural<P>(x[s], held[s], y.data() + s * P);
    Eigen::VectorXd g;
    moments(y.data(), g, nullptr);
    Eigen::VectorXd values(f);
    ASSERT_TRUE(residual.Evaluate(parameters, values.data(), nullptr));
    EXPECT_LT((values - whitening * g(free)).norm(), 1e-12 * values.norm());
}

TEST(MomentResidual, PassesGradientCheckerRgb) { checkMomentGradients<kRgbBlock>(HeldParams{}); }

TEST(MomentResidual, PassesGradientCheckerGreyWithHeldExponent) {
    HeldParams held;
    held.n = true;
    checkMomentGradients<kGreyBlock>(held);
}

TEST(MomentResidual, PassesGradientCheckerWithHeldDiffuse) {
    HeldParams held;
    held.kd = {true, false, true};
    held.ks[1] = true;
    checkMomentGradients<kRgbBlock>(held);
}

// Ceres evaluates an accepted trial point again with Jacobians, and dogleg tries the same trial
// point again after a rejected step while its region is larger than the step: the blocks sum every
// pixel once a point, Jacobians included, and hand back what they summed there, the same numbers;
// a new point is summed.
TEST(EvaluationCache, APointIsSummedOnce) {
    constexpr int P = kGreyBlock;
    int leastSquaresSums = 0, momentSums = 0;
    bool summedWithoutJacobians = false;
    const auto sums = [&](const double* y, double& squares, Eigen::VectorXd* gradient,
                          Eigen::MatrixXd* gramian) {
        ++leastSquaresSums;
        squares = 1 + y[0] * y[0] + y[2] * y[2];
        if (gradient == nullptr) {
            summedWithoutJacobians = true;
            return;
        }
        *gradient = Eigen::Vector3d(2 * y[0], 0, 2 * y[2]);
        *gramian = 2 * Eigen::Matrix3d::Identity();
    };
    const auto moments = [&](const double* y, Eigen::VectorXd& g, Eigen::MatrixXd* dg) {
        ++momentSums;
        g = Eigen::Vector3d(y[0] - 0.5, y[1] - 0.1, y[2] - 3);
        if (dg == nullptr) {
            summedWithoutJacobians = true;
            return;
        }
        *dg = Eigen::Matrix3d::Identity();
    };
    const std::vector<HeldParams> held(1);
    const LeastSquaresResidual<P> leastSquares(sums, {0}, held, {0, 1, 2});
    const MomentResidual<P> moment(moments, {0}, held, {0, 1, 2}, Eigen::Matrix3d::Identity());
    const double a[P] = {0.6, 0.3, 2.0}, b[P] = {0.5, 0.2, 3.0};
    const double* at[1] = {a};
    const double* other[1] = {b};
    double first[P + 1], again[P + 1], moved[P + 1];
    double jacobian[(P + 1) * P], jacobianAgain[(P + 1) * P];
    double* jacobians[1] = {jacobian};
    double* jacobiansAgain[1] = {jacobianAgain};
    for (const ceres::CostFunction* block : {static_cast<const ceres::CostFunction*>(&leastSquares),
                                             static_cast<const ceres::CostFunction*>(&moment)}) {
        const int* calls = block == &leastSquares ? &leastSquaresSums : &momentSums;
        const int rows = block->num_residuals();
        ASSERT_TRUE(block->Evaluate(at, first, nullptr));
        ASSERT_TRUE(block->Evaluate(at, again, nullptr));
        EXPECT_EQ(*calls, 1);
        EXPECT_TRUE(std::equal(first, first + rows, again));
        // The accepted point's Jacobians: from the same sums (least squares' residuals then
        // hold the cost's part along the gradient in rows of their own).
        ASSERT_TRUE(block->Evaluate(at, again, jacobians));
        EXPECT_EQ(*calls, 1);
        EXPECT_TRUE(block != &moment || std::equal(first, first + rows, again));
        double withJacobians[P + 1];
        std::copy(again, again + rows, withJacobians);
        ASSERT_TRUE(block->Evaluate(other, moved, nullptr));
        EXPECT_EQ(*calls, 2);
        EXPECT_FALSE(std::equal(first, first + rows, moved));
        ASSERT_TRUE(block->Evaluate(at, again, jacobiansAgain));
        EXPECT_EQ(*calls, 3);
        EXPECT_TRUE(std::equal(withJacobians, withJacobians + rows, again));
        EXPECT_TRUE(std::equal(jacobian, jacobian + rows * P, jacobianAgain));
    }
    EXPECT_FALSE(summedWithoutJacobians);
}

}  // namespace
}  // namespace phongfit
