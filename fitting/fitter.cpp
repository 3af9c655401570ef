#include "fitter.h"

#include <ceres/ceres.h>
#include <fmt/format.h>
#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <memory>
#include <span>
#include <thread>

#include "box_manifold.h"
#include "error.h"
#include "identifiability.h"
#include "material_params.h"
#include "pixel_residual.h"
#include "replay.h"
#include "uncertainty.h"

namespace phongfit {

LossKind parseLoss(const std::string& name) {
    if (name == "l2") return LossKind::L2;
    if (name == "huber") return LossKind::Huber;
    if (name == "cauchy") return LossKind::Cauchy;
    throw Error(fmt::format("loss '{}' is unknown (allowed: l2, huber, cauchy)", name));
}

PhongMaterial MaterialFit::material() const {
    PhongMaterial m;
    m.kd = kd;
    m.ks = ks;
    m.n = n;
    return m;
}

namespace {

// Beyond this many free parameters the normal equations are sparse enough (each pixel touches few
// materials) for a sparse solver to beat a dense one on a tall Jacobian.
constexpr int kDenseLimit = 64;
// Reflectances below this are compared absolutely in the convergence test.
constexpr double kReflectanceFloor = 0.01;

double secondsSince(std::chrono::steady_clock::time_point start) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

bool finite(const Color<float>& c) { return c.allFinite(); }

// A pixel that enters the fit: observed, finite, and seen through at least one fitted material.
struct UsedPixel {
    std::uint32_t view, pixel;
    std::uint32_t slotBegin, slotCount;  // into Prepared::slots: the slots its vertices use
    Color3 observed;
    double weight;
};

struct Prepared {
    std::vector<UsedPixel> pixels;
    std::vector<std::uint32_t> slots;
    std::vector<bool> slotSeen;
    std::map<std::string, std::size_t> leftOut;
    double meanObserved = 0;  // over used pixels and channels
    double rmsObserved = 0;   // of weight * observation
};

void checkPathSet(const PathSet& paths, const Observation& obs, int view, int slots) {
    const auto where = [&] { return fmt::format("path set of view {}", view); };
    if (paths.width != obs.width || paths.height != obs.height)
        throw Error(fmt::format("{} is {}x{} but its image is {}x{} (they must match)", where(),
                                paths.width, paths.height, obs.width, obs.height));
    if (paths.slots != slots)
        throw Error(fmt::format("{} has {} material slots but {} materials are fitted", where(),
                                paths.slots, slots));
    const std::size_t pixels = std::size_t(obs.width) * std::size_t(obs.height);
    if (paths.background.size() != pixels || paths.pixelStart.size() != pixels + 1 ||
        paths.pixelStart.front() != 0 || paths.pixelStart.back() != paths.terms.size())
        throw Error(
            fmt::format("{}: background ({}) and pixelStart ({}) must hold {} and {} "
                        "entries, pixelStart from 0 to the term count {}",
                        where(), paths.background.size(), paths.pixelStart.size(), pixels,
                        pixels + 1, paths.terms.size()));
    for (std::size_t p = 0; p < pixels; ++p) {
        if (paths.pixelStart[p] > paths.pixelStart[p + 1])
            throw Error(fmt::format("{}: pixelStart decreases at pixel {}", where(), p));
        for (std::uint32_t t = paths.pixelStart[p]; t < paths.pixelStart[p + 1]; ++t) {
            const PathTerm& term = paths.terms[t];
            if (term.pixel != p || term.vertexCount == 0 ||
                std::size_t(term.firstVertex) + term.vertexCount > paths.vertices.size())
                throw Error(
                    fmt::format("{}: term {} (pixel {}, vertices {}+{}) is not pixel {}'s "
                                "or has no valid vertex range (there are {} vertices)",
                                where(), t, term.pixel, term.firstVertex, term.vertexCount, p,
                                paths.vertices.size()));
        }
    }
    for (std::size_t i = 0; i < paths.vertices.size(); ++i) {
        const PathVertex& v = paths.vertices[i];
        if (v.slot >= std::uint32_t(slots) || std::isnan(v.logCos) || v.logCos > 0)
            throw Error(
                fmt::format("{}: vertex {} has slot {} and log cos alpha {} (allowed: slot "
                            "< {}, log cos alpha <= 0 or -inf)",
                            where(), i, v.slot, v.logCos, slots));
    }
}

void checkObservation(const Observation& obs, int view) {
    const std::size_t pixels =
        std::size_t(std::max(obs.width, 0)) * std::size_t(std::max(obs.height, 0));
    if (obs.width <= 0 || obs.height <= 0 || obs.rgb.size() != 3 * pixels ||
        (!obs.valid.empty() && obs.valid.size() != pixels) ||
        (!obs.weight.empty() && obs.weight.size() != pixels))
        throw Error(fmt::format(
            "observation of view {}: {}x{} needs 3 values per pixel ({} given), "
            "and a mask and weights with one per pixel or none ({} and {} "
            "given)",
            view, obs.width, obs.height, obs.rgb.size(), obs.valid.size(), obs.weight.size()));
    for (std::size_t p = 0; p < obs.weight.size(); ++p)
        if (!(obs.weight[p] >= 0) || !std::isfinite(obs.weight[p]))
            throw Error(
                fmt::format("observation of view {}: weight {} at pixel ({}, {}) is invalid "
                            "(allowed: finite, >= 0)",
                            view, obs.weight[p], p % obs.width, p / obs.width));
}

Prepared prepare(const std::vector<Observation>& observations, const std::vector<PathSet>& paths,
                 int slots) {
    Prepared prep;
    prep.slotSeen.assign(slots, false);
    std::size_t masked = 0, nonFinite = 0, noMaterial = 0;
    double sum = 0, sumSquares = 0;
    std::vector<std::uint32_t> used;
    for (std::size_t view = 0; view < observations.size(); ++view) {
        const Observation& obs = observations[view];
        const PathSet& ps = paths[view];
        checkPathSet(ps, obs, int(view), slots);
        const std::size_t pixels = ps.background.size();
        for (std::size_t p = 0; p < pixels; ++p) {
            const double weight = obs.weight.empty() ? 1.0 : obs.weight[p];
            if ((!obs.valid.empty() && obs.valid[p] == 0) || weight == 0) {
                ++masked;
                continue;
            }
            const Color<float> observed(obs.rgb[3 * p], obs.rgb[3 * p + 1], obs.rgb[3 * p + 2]);
            bool ok = finite(observed) && finite(ps.background[p]);
            used.clear();
            for (std::uint32_t t = ps.pixelStart[p]; ok && t < ps.pixelStart[p + 1]; ++t) {
                const PathTerm& term = ps.terms[t];
                ok = finite(term.constant);
                for (std::uint32_t k = 0; k < term.vertexCount; ++k)
                    used.push_back(ps.vertices[term.firstVertex + k].slot);
            }
            if (!ok) {
                ++nonFinite;
                continue;
            }
            if (used.empty()) {
                ++noMaterial;
                continue;
            }
            std::sort(used.begin(), used.end());
            used.erase(std::unique(used.begin(), used.end()), used.end());
            UsedPixel u;
            u.view = std::uint32_t(view);
            u.pixel = std::uint32_t(p);
            u.slotBegin = std::uint32_t(prep.slots.size());
            u.slotCount = std::uint32_t(used.size());
            u.observed = observed.cast<double>();
            u.weight = weight;
            for (std::uint32_t s : used) prep.slotSeen[s] = true;
            prep.slots.insert(prep.slots.end(), used.begin(), used.end());
            prep.pixels.push_back(u);
            sum += u.observed.sum();
            sumSquares += weight * weight * u.observed.square().sum();
        }
    }
    if (prep.pixels.empty())
        throw Error(
            fmt::format("no pixel of any view can be fitted: {} masked, {} not finite, {} "
                        "not seen through a fitted material",
                        masked, nonFinite, noMaterial));
    prep.leftOut = {
        {"masked", masked}, {"non_finite", nonFinite}, {"no_fitted_material", noMaterial}};
    const double values = 3.0 * double(prep.pixels.size());
    prep.meanObserved = sum / values;
    prep.rmsObserved = std::sqrt(sumSquares / values);
    return prep;
}

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

// The outcome of one round: the solution with its uncertainty and what the round cost.
struct RoundOutcome {
    std::vector<MaterialFit> materials;
    std::vector<std::vector<double>> naturalStd;  // per slot, in natural coordinates
    double rmse = 0;
    int iterations = 0;
    double minimizerSeconds = 0;
    std::size_t pixelsUsed = 0;
    std::map<std::string, std::size_t> leftOut;
};

// Sums over pixels in natural coordinates (per slot: kd, ks per colour group, log n), with J the
// pixel's residual Jacobian, r its residual and rho' the robust loss' weight.
struct Information {
    Eigen::MatrixXd fisher;  // sum of rho' J^T J (the Gauss-Newton Hessian)
    Eigen::MatrixXd scores;  // sum of rho'^2 J^T r r^T J

    Information& operator+=(const Information& other) {
        fisher += other.fisher;
        scores += other.scores;
        return *this;
    }
};

// Solves one round on fixed path sets. P is the block size (RGB or grey).
template <int P>
class RoundSolver {
    using L = BlockLayout<P>;
    using NaturalVector = Eigen::Matrix<double, P, 1>;

public:
    RoundSolver(const std::vector<Observation>& observations, const std::vector<PathSet>& paths,
                const std::vector<PhongMaterial>& start, const FitOptions& options, int threads)
        : paths_(paths),
          start_(start),
          options_(options),
          threads_(threads),
          slots_(int(start.size())),
          prep_(prepare(observations, paths, slots_)),
          loss_(makeLoss(options, prep_.meanObserved)),
          arena_(threads) {}

    // `theta` is the estimate to start from; `held` persists across rounds and grows.
    RoundOutcome solve(const std::vector<PhongMaterial>& theta, std::vector<HeldParams>& held) {
        RoundOutcome out;
        for (int s = 0; s < slots_; ++s)
            if (!prep_.slotSeen[s]) holdAll(held[s]);
        x_.assign(std::size_t(slots_) * P, 0.0);
        for (int s = 0; s < slots_; ++s) {
            NaturalVector y = naturalFromPhong<P>(theta[s]);
            const NaturalVector y0 = naturalFromPhong<P>(start_[s]);
            for (int i = 0; i < P; ++i)
                if (isHeld(held[s], i)) y[i] = y0[i];
            toInternal<P>(y.data(), held[s], block(s));
        }
        for (;;) {
            const ceres::Solver::Summary summary = minimize(held);
            out.iterations += summary.num_successful_steps + summary.num_unsuccessful_steps;
            out.minimizerSeconds += summary.minimizer_time_in_seconds;
            const Information info = information(held);
            if (hold(findUnconstrained(info.fisher, 3.0 * double(prep_.pixels.size()),
                                       prep_.rmsObserved, heldFlags(held)),
                     held))
                continue;
            out.naturalStd = naturalStd(held, summary.final_cost, info);
            if (holdUnseenExponents(out.naturalStd, held)) continue;
            break;
        }
        for (int s = 0; s < slots_; ++s)
            out.materials.push_back(materialFit(s, held[s], out.naturalStd[s]));
        out.rmse = rmse(held);
        out.pixelsUsed = prep_.pixels.size();
        out.leftOut = prep_.leftOut;
        return out;
    }

private:
    double* block(int s) { return x_.data() + std::size_t(s) * P; }

    static bool isHeld(const HeldParams& h, int i) {
        if (i == L::kLogN) return h.n;
        return i < L::kGroups ? h.kd[i] : h.ks[i - L::kGroups];
    }

    static void holdAll(HeldParams& h) {
        h.kd.fill(true);
        h.ks.fill(true);
        h.n = true;
    }

    std::vector<bool> heldFlags(const std::vector<HeldParams>& held) const {
        std::vector<bool> flags(std::size_t(slots_) * P);
        for (int s = 0; s < slots_; ++s)
            for (int i = 0; i < P; ++i) flags[std::size_t(s) * P + i] = isHeld(held[s], i);
        return flags;
    }

    // Holds the natural parameters `indices` (slot * P + i) at their start values, keeping the
    // other parameters of the slot where they are. True if any was not held before.
    bool hold(const std::vector<int>& indices, std::vector<HeldParams>& held) {
        bool changed = false;
        for (int index : indices) {
            const int s = index / P, i = index % P;
            if (isHeld(held[s], i)) continue;
            NaturalVector y;
            toNatural<P>(block(s), held[s], y.data());
            y[i] = naturalFromPhong<P>(start_[s])[i];
            if (i == L::kLogN)
                held[s].n = true;
            else if (i < L::kGroups)
                held[s].kd[i] = true;
            else
                held[s].ks[i - L::kGroups] = true;
            toInternal<P>(y.data(), held[s], block(s));
            changed = true;
        }
        return changed;
    }

    // n only shapes the lobe: when no group's ks is significantly above 0 (or every ks is held),
    // the images do not constrain n.
    bool holdUnseenExponents(const std::vector<std::vector<double>>& stdNatural,
                             std::vector<HeldParams>& held) {
        std::vector<int> indices;
        for (int s = 0; s < slots_; ++s) {
            if (held[s].n) continue;
            NaturalVector y;
            toNatural<P>(block(s), held[s], y.data());
            std::vector<double> ks, ksStd;
            for (int g = 0; g < L::kGroups; ++g) {
                if (held[s].ks[g]) continue;
                ks.push_back(y[L::specular(g)]);
                ksStd.push_back(stdNatural[s][L::specular(g)]);
            }
            if (!lobeDetected(ks, ksStd)) indices.push_back(s * P + L::kLogN);
        }
        return hold(indices, held);
    }

    ceres::Solver::Summary minimize(const std::vector<HeldParams>& held) {
        ceres::Problem::Options problemOptions;
        problemOptions.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
        problem_ = std::make_unique<ceres::Problem>(problemOptions);
        int freeCount = 0;
        for (int s = 0; s < slots_; ++s) {
            if (!prep_.slotSeen[s]) continue;
            double* x = block(s);
            problem_->AddParameterBlock(x, P);
            const std::vector<int> constant = heldCoordinates<P>(held[s]);
            if (int(constant.size()) == P) {
                problem_->SetParameterBlockConstant(x);
            } else {
                std::vector<double> lower(P), upper(P);
                internalBounds<P>(held[s], x, lower.data(), upper.data());
                std::vector<bool> fixed(P, false);
                for (int i : constant) fixed[i] = true;
                problem_->SetManifold(x, new BoxManifold(lower, upper, fixed));
            }
            freeCount += P - int(constant.size());
        }
        const std::span<const HeldParams> heldSpan(held);
        std::vector<double*> blocks;
        for (const UsedPixel& u : prep_.pixels) {
            const std::span<const std::uint32_t> slots(prep_.slots.data() + u.slotBegin,
                                                       u.slotCount);
            blocks.clear();
            for (std::uint32_t s : slots) blocks.push_back(block(int(s)));
            problem_->AddResidualBlock(new PixelResidual<P>(paths_[u.view], u.pixel, u.observed,
                                                            u.weight, slots, heldSpan),
                                       loss_.get(), blocks.data(), int(blocks.size()));
        }
        freeParameters_ = freeCount;

        ceres::Solver::Options solverOptions;
        solverOptions.linear_solver_type =
            freeCount <= kDenseLimit ? ceres::DENSE_QR : ceres::SPARSE_NORMAL_CHOLESKY;
        // Dogleg reuses one factorization across rejected steps, which the far starts (n off by
        // 100x) produce several of; measured 2x fewer Jacobian evaluations than
        // Levenberg-Marquardt.
        solverOptions.trust_region_strategy_type = ceres::DOGLEG;
        solverOptions.num_threads = threads_;
        solverOptions.max_num_iterations = options_.maxIterations;
        solverOptions.function_tolerance = 1e-10;
        solverOptions.parameter_tolerance = 1e-10;
        solverOptions.logging_type =
            options_.verbose ? ceres::PER_MINIMIZER_ITERATION : ceres::SILENT;
        solverOptions.minimizer_progress_to_stdout = options_.verbose;
        ceres::Solver::Summary summary;
        ceres::Solve(solverOptions, problem_.get(), &summary);
        if (options_.verbose) fmt::print(stderr, "{}\n", summary.BriefReport());
        if (!summary.IsSolutionUsable())
            throw Error(fmt::format("the fit failed: {}", summary.message));
        return summary;
    }

    // Sum over the used pixels of body(pixel, sum), in parallel.
    template <typename Value, typename Body>
    Value sumOverPixels(const Value& zero, const Body& body) {
        tbb::enumerable_thread_specific<Value> partial(zero);
        arena_.execute([&] {
            tbb::parallel_for(tbb::blocked_range<std::size_t>(0, prep_.pixels.size(), 512),
                              [&](const tbb::blocked_range<std::size_t>& range) {
                                  Value& sum = partial.local();
                                  for (std::size_t i = range.begin(); i != range.end(); ++i)
                                      body(prep_.pixels[i], sum);
                              });
        });
        Value total = zero;
        for (const Value& v : partial) total += v;
        return total;
    }

    Information information(const std::vector<HeldParams>& held) {
        std::vector<double> y(std::size_t(slots_) * P);
        for (int s = 0; s < slots_; ++s)
            toNatural<P>(block(s), held[s], y.data() + std::size_t(s) * P);
        const Eigen::Index size = Eigen::Index(slots_) * P;
        const Information zero{Eigen::MatrixXd::Zero(size, size),
                               Eigen::MatrixXd::Zero(size, size)};
        return sumOverPixels(zero, [&](const UsedPixel& u, Information& sum) {
            const std::span<const std::uint32_t> slots(prep_.slots.data() + u.slotBegin,
                                                       u.slotCount);
            std::vector<PhongParams<PackedJet>> theta(slots_);
            std::vector<Eigen::Matrix<double, 3, P>> jacobians(u.slotCount);
            Color3 predicted = Color3::Zero();
            for (std::uint32_t b = 0; b < u.slotCount; ++b) {
                predicted = replayNaturalJacobian<P>(paths_[u.view], u.pixel, slots, y.data(),
                                                     slots[b], theta, jacobians[b]);
                jacobians[b] *= u.weight;
            }
            const Eigen::Vector3d residual = (u.weight * (predicted - u.observed)).matrix();
            double rho[3] = {0, 1, 0};
            if (loss_) loss_->Evaluate(residual.squaredNorm(), rho);
            for (std::uint32_t a = 0; a < u.slotCount; ++a) {
                const Eigen::Matrix<double, P, 1> scoreA = jacobians[a].transpose() * residual;
                for (std::uint32_t b = 0; b < u.slotCount; ++b) {
                    const Eigen::Index row = Eigen::Index(slots[a]) * P;
                    const Eigen::Index col = Eigen::Index(slots[b]) * P;
                    sum.fisher.block<P, P>(row, col) +=
                        rho[1] * jacobians[a].transpose() * jacobians[b];
                    sum.scores.block<P, P>(row, col) +=
                        rho[1] * rho[1] * scoreA *
                        (jacobians[b].transpose() * residual).transpose();
                }
            }
        });
    }

    // Standard errors of the natural parameters per slot: Ceres' covariance of the internal
    // coordinates (held ones have none), scaled by the residual variance 2 cost / (m - p), mapped
    // by the delta method; or the sandwich estimate where that is larger (uncertainty.h). The
    // pseudo-inverse covers the one singular point of the map (ks = 1, where u does not matter).
    std::vector<std::vector<double>> naturalStd(const std::vector<HeldParams>& held,
                                                double finalCost, const Information& info) {
        const std::vector<double> sandwich =
            sandwichVariances(info.fisher, info.scores, heldFlags(held));
        std::vector<std::vector<double>> result(slots_, std::vector<double>(P, 0.0));
        std::vector<std::pair<const double*, const double*>> pairs;
        std::vector<int> covered;
        for (int s = 0; s < slots_; ++s) {
            if (!prep_.slotSeen[s] || int(heldCoordinates<P>(held[s]).size()) == P) continue;
            pairs.emplace_back(block(s), block(s));
            covered.push_back(s);
        }
        if (pairs.empty()) return result;
        ceres::Covariance::Options covarianceOptions;
        covarianceOptions.num_threads = threads_;
        const auto dense = [&] {
            covarianceOptions.algorithm_type = ceres::DENSE_SVD;
            covarianceOptions.null_space_rank = -1;
        };
        if (freeParameters_ <= kDenseLimit) dense();
        auto covariance = std::make_unique<ceres::Covariance>(covarianceOptions);
        if (!covariance->Compute(pairs, problem_.get())) {
            dense();
            covariance = std::make_unique<ceres::Covariance>(covarianceOptions);
            if (!covariance->Compute(pairs, problem_.get()))
                throw Error("the covariance of the fitted parameters could not be computed");
        }
        const double residuals = 3.0 * double(prep_.pixels.size());
        const double variance = 2 * finalCost / std::max(residuals - freeParameters_, 1.0);
        for (int s : covered) {
            Eigen::Matrix<double, P, P, Eigen::RowMajor> c;
            covariance->GetCovarianceBlock(block(s), block(s), c.data());
            const Eigen::Matrix<double, P, P> d = naturalJacobian<P>(block(s), held[s]);
            const Eigen::Matrix<double, P, P> natural = variance * d * c * d.transpose();
            for (int i = 0; i < P; ++i) {
                const double v = std::max(natural(i, i), sandwich[std::size_t(s) * P + i]);
                result[s][i] =
                    isHeld(held[s], i) || !(v > 0) || !std::isfinite(v) ? 0 : std::sqrt(v);
            }
        }
        return result;
    }

    MaterialFit materialFit(int s, const HeldParams& held, const std::vector<double>& stdNatural) {
        NaturalVector y;
        toNatural<P>(block(s), held, y.data());
        MaterialFit m;
        const PhongMaterial p = naturalToPhong<P>(y.data());
        m.kd = p.kd;
        m.ks = p.ks;
        m.n = p.n;
        for (int c = 0; c < 3; ++c) {
            m.kdStd[c] = stdNatural[L::diffuse(L::group(c))];
            m.ksStd[c] = stdNatural[L::specular(L::group(c))];
        }
        // exp(log n) need not round-trip: a held n is reported exactly as it started.
        if (held.n) m.n = std::clamp(start_[s].n, kMinExponent, kMaxExponent);
        m.nStd = m.n * stdNatural[L::kLogN];
        static constexpr const char* kChannel[3] = {"r", "g", "b"};
        for (const char* name : {"kd", "ks"}) {
            const bool diffuse = name[1] == 'd';
            const auto& flags = diffuse ? held.kd : held.ks;
            const int count = int(std::count(flags.begin(), flags.begin() + L::kGroups, true));
            if (count == L::kGroups) {
                m.unconstrained.push_back(name);
            } else {
                for (int g = 0; g < L::kGroups; ++g)
                    if (flags[g])
                        m.unconstrained.push_back(fmt::format("{}.{}", name, kChannel[g]));
            }
        }
        if (held.n) m.unconstrained.push_back("n");
        return m;
    }

    double rmse(const std::vector<HeldParams>& held) {
        std::vector<PhongMaterial> theta(slots_);
        for (int s = 0; s < slots_; ++s) theta[s] = toPhong<P>(block(s), held[s]);
        const double sum = sumOverPixels(0.0, [&](const UsedPixel& u, double& total) {
            total +=
                (replayPixel(paths_[u.view], u.pixel, theta.data()) - u.observed).square().sum();
        });
        return std::sqrt(sum / (3.0 * double(prep_.pixels.size())));
    }

    const std::vector<PathSet>& paths_;
    const std::vector<PhongMaterial>& start_;
    const FitOptions& options_;
    int threads_;
    int slots_;
    Prepared prep_;
    std::unique_ptr<ceres::LossFunction> loss_;
    tbb::task_arena arena_;
    std::vector<double> x_;  // internal coordinates, P per slot
    std::unique_ptr<ceres::Problem> problem_;
    int freeParameters_ = 0;
};

// Whether the round's solution is where the round recorded (see FitOptions::tolerance).
template <int P>
bool converged(const std::vector<PhongMaterial>& recorded, const RoundOutcome& out,
               const FitOptions& options) {
    using L = BlockLayout<P>;
    for (std::size_t s = 0; s < recorded.size(); ++s) {
        const auto before = naturalFromPhong<P>(recorded[s]);
        const auto after = naturalFromPhong<P>(out.materials[s].material());
        for (int i = 0; i < P; ++i) {
            const double change = std::abs(after[i] - before[i]);
            const double scale =
                i == L::kLogN ? 1.0 : std::max(std::abs(before[i]), kReflectanceFloor);
            if (change > options.tolerance * scale &&
                change > options.stdTolerance * out.naturalStd[s][i])
                return false;
        }
    }
    return true;
}

using RecordAll =
    std::function<const std::vector<PathSet>&(const std::vector<PhongMaterial>&, int round)>;

template <int P>
FitResult runRounds(const std::vector<Observation>& observations, const RecordAll& recordAll,
                    const std::vector<PhongMaterial>& start, const FitOptions& options,
                    int maxRounds) {
    const auto begin = std::chrono::steady_clock::now();
    const int threads = options.threads > 0 ? options.threads
                                            : std::max(1, int(std::thread::hardware_concurrency()));
    FitResult result;
    std::vector<PhongMaterial> theta = start;
    std::vector<HeldParams> held(start.size());
    for (int round = 0; round < maxRounds; ++round) {
        const auto roundBegin = std::chrono::steady_clock::now();
        const std::vector<PathSet>& paths = recordAll(theta, round);
        if (paths.size() != observations.size())
            throw Error(fmt::format("the recorder returned {} path sets for {} views", paths.size(),
                                    observations.size()));
        const double recordSeconds = secondsSince(roundBegin);
        RoundSolver<P> solver(observations, paths, start, options, threads);
        RoundOutcome out = solver.solve(theta, held);

        FitRound r;
        r.round = round;
        r.recordSeconds = recordSeconds;
        r.timeSeconds = secondsSince(roundBegin);
        r.rmse = out.rmse;
        r.iterations = out.iterations;
        r.secondsPerIteration = out.minimizerSeconds / std::max(out.iterations, 1);
        r.materials = out.materials;
        result.rounds.push_back(r);
        if (options.onRound) options.onRound(r);
        result.converged = converged<P>(theta, out, options);
        result.materials = out.materials;
        result.rmse = out.rmse;
        result.pixelsUsed = out.pixelsUsed;
        result.pixelsLeftOut = out.leftOut;
        for (std::size_t s = 0; s < theta.size(); ++s) theta[s] = out.materials[s].material();
        if (result.converged) break;
    }
    result.timeSeconds = secondsSince(begin);
    return result;
}

FitResult fit(const std::vector<Observation>& observations, const RecordAll& recordAll,
              const std::vector<PhongMaterial>& start, const FitOptions& options, int maxRounds) {
    if (observations.empty()) throw Error("the fit needs at least one view");
    if (start.empty()) throw Error("the fit needs at least one material");
    if (maxRounds < 1 || options.maxIterations < 1 || !(options.tolerance > 0) ||
        !(options.stdTolerance >= 0) || !(options.lossScale > 0))
        throw Error(
            fmt::format("fit options: rounds {} and iterations {} must be >= 1, tolerance "
                        "{} and loss scale {} > 0, std tolerance {} >= 0",
                        maxRounds, options.maxIterations, options.tolerance, options.lossScale,
                        options.stdTolerance));
    for (std::size_t s = 0; s < start.size(); ++s)
        validatePhong(start[s], fmt::format("start value of material {}", s));
    for (std::size_t v = 0; v < observations.size(); ++v) checkObservation(observations[v], int(v));
    return options.grey ? runRounds<kGreyBlock>(observations, recordAll, start, options, maxRounds)
                        : runRounds<kRgbBlock>(observations, recordAll, start, options, maxRounds);
}

}  // namespace

FitResult fitMaterials(const std::vector<Observation>& observations, const PathRecorder& record,
                       const std::vector<PhongMaterial>& start, const FitOptions& options) {
    std::vector<PathSet> paths;
    const RecordAll recordAll = [&](const std::vector<PhongMaterial>& theta,
                                    int round) -> const std::vector<PathSet>& {
        paths.clear();
        for (std::size_t v = 0; v < observations.size(); ++v)
            paths.push_back(record(int(v), theta, round));
        return paths;
    };
    return fit(observations, recordAll, start, options, options.maxRounds);
}

FitResult fitPathSets(const std::vector<Observation>& observations,
                      const std::vector<PathSet>& paths, const std::vector<PhongMaterial>& start,
                      const FitOptions& options) {
    const RecordAll recordAll = [&](const std::vector<PhongMaterial>&,
                                    int) -> const std::vector<PathSet>& { return paths; };
    return fit(observations, recordAll, start, options, 1);
}

}  // namespace phongfit
