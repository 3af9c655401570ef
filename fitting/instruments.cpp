#include "instruments.h"

#include <tbb/parallel_for.h>

#include <Eigen/Cholesky>
#include <algorithm>
#include <span>

namespace phongfit {

namespace {

// The estimating equations g and (if sized) dg/dy, summed over pixels.
struct MomentSums {
    Eigen::VectorXd g;
    Eigen::MatrixXd jacobian;

    MomentSums& operator+=(const MomentSums& other) {
        g += other.g;
        jacobian += other.jacobian;
        return *this;
    }
};

// The instruments' Gram matrix (sum of W Z^T Z, averaged over the sets), and the moments of the
// pixels that see no material.
struct InstrumentSums {
    Eigen::MatrixXd gram;
    Eigen::VectorXd constantMoments;

    InstrumentSums& operator+=(const InstrumentSums& other) {
        gram += other.gram;
        constantMoments += other.constantMoments;
        return *this;
    }
};

}  // namespace

template <int P>
void Instruments<P>::adopt(Objective<P>& objective, const Linearization<P>& at) {
    const UsedPixels& prep = objective.pixels();
    const int sets = objective.setCount();
    // The old instruments are not needed to make the new: released first.
    instruments_ = {};
    weights_ = {};
    for (int k = 0; k < sets; ++k) {
        // The Jacobians at `at`, replayed, of the pixels that see a material (the others count
        // as 0 in the smoothing).
        std::vector<StoredJacobian>& own = instruments_[k];
        own.assign(prep.slots.size(), StoredJacobian::Zero());
        objective.sumPixels(prep.seeingMaterial, 0,
                            [&](std::size_t i, int&, typename Objective<P>::Scratch& scratch) {
                                const UsedPixel& u = prep.pixels[i];
                                objective.residual(k, u, at.y.data(), scratch, true);
                                for (std::uint32_t a = 0; a < u.slotCount; ++a)
                                    own[u.slotBegin + a] =
                                        storeJacobian<P>(scratch.jacobians[k][a]);
                            });
        smoothJacobians(prep, own, objective.arena());
    }
    weights_ = at.weights;
    const std::vector<float> precision = residualPrecisions(prep, at.residuals);
    for (int k = 0; k < sets; ++k)
        for (std::size_t i = 0; i < precision.size(); ++i) weights_[k][i] *= precision[i];
    const Eigen::Index size = Eigen::Index(objective.blocks()) * P;
    const InstrumentSums zero{Eigen::MatrixXd::Zero(size, size), Eigen::VectorXd::Zero(size)};
    InstrumentSums sums = objective.sumPixels(
        prep.pixels.size(), zero,
        [&](std::size_t i, InstrumentSums& sum, typename Objective<P>::Scratch& scratch) {
            const UsedPixel& u = prep.pixels[i];
            const std::span<const std::uint32_t> slots = prep.slotsOf(u);
            for (int k = 0; k < sets; ++k)
                for (std::uint32_t a = 0; a < u.slotCount; ++a)
                    for (std::uint32_t b = 0; b < u.slotCount; ++b)
                        addPackedGram<P>(sum.gram.template block<P, P>(Eigen::Index(slots[a]) * P,
                                                                       Eigen::Index(slots[b]) * P),
                                         double(weights_[k][i]) / sets,
                                         loadJacobian<P>(instruments_[k][u.slotBegin + a]),
                                         loadJacobian<P>(instruments_[k][u.slotBegin + b]));
            if (u.seesMaterial) return;
            pixelMoment<P>(at, nullptr, this, sets, i, u, scratch.moment, nullptr);
            for (std::uint32_t a = 0; a < u.slotCount; ++a)
                sum.constantMoments.template segment<P>(Eigen::Index(slots[a]) * P) +=
                    scratch.moment.template segment<P>(Eigen::Index(a) * P);
        });
    gram_ = std::move(sums.gram);
    constantMoments_ = std::move(sums.constantMoments);
}

template <int P>
void Instruments<P>::momentSums(Objective<P>& objective, const double* y, Eigen::VectorXd& g,
                                Eigen::MatrixXd* jacobian) const {
    const UsedPixels& prep = objective.pixels();
    const Eigen::Index size = Eigen::Index(objective.blocks()) * P;
    const bool withJacobian = jacobian != nullptr;
    const MomentSums zero{Eigen::VectorXd::Zero(size),
                          withJacobian ? Eigen::MatrixXd::Zero(size, size) : Eigen::MatrixXd()};
    MomentSums sums = objective.sumPixels(
        prep.seeingMaterial, zero,
        [&](std::size_t i, MomentSums& sum, typename Objective<P>::Scratch& scratch) {
            const UsedPixel& u = prep.pixels[i];
            const std::span<const std::uint32_t> slots = prep.slotsOf(u);
            for (int k = 0; k < 2; ++k) {
                const int other = 1 - k;
                const Eigen::Vector3d r = objective.residual(k, u, y, scratch, withJacobian);
                const double w = weights_[other][i];
                for (std::uint32_t a = 0; a < u.slotCount; ++a) {
                    const Jacobian z = w * loadJacobian<P>(instruments_[other][u.slotBegin + a]);
                    const Eigen::Index row = Eigen::Index(slots[a]) * P;
                    addPackedGradient<P>(sum.g.template segment<P>(row), 1.0, z, r);
                    if (!withJacobian) continue;
                    for (std::uint32_t b = 0; b < u.slotCount; ++b)
                        addPackedGram<P>(
                            sum.jacobian.template block<P, P>(row, Eigen::Index(slots[b]) * P), 1.0,
                            z, scratch.jacobians[k][b]);
                }
            }
        });
    g = sums.g + constantMoments_;
    if (withJacobian) *jacobian = std::move(sums.jacobian);
}

template <int P>
Eigen::MatrixXd Instruments<P>::whitening(const std::vector<int>& free) const {
    Eigen::MatrixXd gram = gram_(free, free);
    const Eigen::Index n = gram.rows();
    // An instrument that is 0 at every pixel makes its equation 0 everywhere; any scale does.
    for (Eigen::Index i = 0; i < n; ++i)
        if (!(gram(i, i) > 0)) gram(i, i) = 1;
    const Eigen::VectorXd scale = gram.diagonal().cwiseSqrt().cwiseInverse();
    Eigen::MatrixXd correlation = scale.asDiagonal() * gram * scale.asDiagonal();
    // Collinear instruments: found unconstrained and held after this solve.
    correlation.diagonal().array() += 1e-12;
    const Eigen::LLT<Eigen::MatrixXd> llt(correlation);
    return llt.matrixL().solve(Eigen::MatrixXd(scale.asDiagonal()));
}

namespace {

// A row's entries as they were before it was smoothed: per x its first entry (width + 1 of them),
// the entries of the pixels that see a material.
struct SavedRow {
    std::vector<std::uint32_t> start;
    std::vector<StoredJacobian> entries;

    void save(const UsedPixels& prep, const std::vector<StoredJacobian>& jacobians,
              std::uint32_t view, int y) {
        const int width = prep.widths[view];
        start.assign(std::size_t(width) + 1, 0);
        entries.clear();
        for (int x = 0; x < width; ++x) {
            start[std::size_t(x)] = std::uint32_t(entries.size());
            const std::int32_t q = prep.index[view][std::size_t(y) * std::size_t(width) + x];
            if (q < 0 || !prep.pixels[std::size_t(q)].seesMaterial) continue;
            const UsedPixel& u = prep.pixels[std::size_t(q)];
            entries.insert(entries.end(), jacobians.begin() + u.slotBegin,
                           jacobians.begin() + u.slotBegin + u.slotCount);
        }
        start[std::size_t(width)] = std::uint32_t(entries.size());
    }
    // The entry of the pixel at x, in the `at`-th of its slots.
    const StoredJacobian& entry(int x, std::size_t at) const {
        return entries[start[std::size_t(x)] + at];
    }
};

// The last kInstrumentRadius + 1 rows saved; row y in y % its size.
using SavedRows = std::array<SavedRow, kInstrumentRadius + 1>;

// Smooths the entries of used pixel i, at (x, y) of its view: rows up to y read from `saved`,
// those below (not smoothed yet) from `jacobians`.
void smoothPixel(const UsedPixels& prep, std::vector<StoredJacobian>& jacobians,
                 const SavedRows& saved, std::size_t i, int x, int y) {
    const UsedPixel& u = prep.pixels[i];
    const int width = prep.widths[u.view], height = prep.heights[u.view];
    const int x0 = std::max(x - kInstrumentRadius, 0),
              x1 = std::min(x + kInstrumentRadius, width - 1);
    const int y0 = std::max(y - kInstrumentRadius, 0),
              y1 = std::min(y + kInstrumentRadius, height - 1);
    const double count = double((x1 - x0 + 1) * (y1 - y0 + 1));
    for (std::uint32_t a = 0; a < u.slotCount; ++a) {
        const std::uint32_t slot = prep.slots[u.slotBegin + a];
        Eigen::Matrix3d sum = Eigen::Matrix3d::Zero();
        for (int yy = y0; yy <= y1; ++yy)
            for (int xx = x0; xx <= x1; ++xx) {
                const std::int32_t q =
                    prep.index[u.view][std::size_t(yy) * std::size_t(width) + xx];
                if (q < 0 || !prep.pixels[std::size_t(q)].seesMaterial) continue;
                const UsedPixel& neighbour = prep.pixels[std::size_t(q)];
                const std::span<const std::uint32_t> slots = prep.slotsOf(neighbour);
                const auto b = std::lower_bound(slots.begin(), slots.end(), slot);
                if (b == slots.end() || *b != slot) continue;
                const std::size_t at = std::size_t(b - slots.begin());
                sum += (yy <= y ? saved[std::size_t(yy) % saved.size()].entry(xx, at)
                                : jacobians[neighbour.slotBegin + at])
                           .cast<double>();
            }
        jacobians[u.slotBegin + a] = (sum / count).cast<float>();
    }
}

}  // namespace

void smoothJacobians(const UsedPixels& prep, std::vector<StoredJacobian>& jacobians,
                     tbb::task_arena& arena) {
    // Row by row, in place: a row is saved as it was before its pixels are smoothed side by side,
    // for them and the rows below to read.
    SavedRows saved;
    arena.execute([&] {
        for (std::uint32_t view = 0; view < prep.widths.size(); ++view) {
            const int width = prep.widths[view];
            for (int y = 0; y < prep.heights[view]; ++y) {
                saved[std::size_t(y) % saved.size()].save(prep, jacobians, view, y);
                tbb::parallel_for(0, width, [&](int x) {
                    const std::int32_t i =
                        prep.index[view][std::size_t(y) * std::size_t(width) + x];
                    if (i >= 0) smoothPixel(prep, jacobians, saved, std::size_t(i), x, y);
                });
            }
        }
    });
}

std::vector<float> residualPrecisions(
    const UsedPixels& prep, const std::array<std::vector<Eigen::Vector3f>, 2>& residuals) {
    const std::size_t count = prep.pixels.size();
    std::vector<float> d(count), precision(count);
    double mean = 0;
    for (std::size_t i = 0; i < count; ++i) {
        d[i] = float(0.5 * (residuals[0][i] - residuals[1][i]).cast<double>().squaredNorm());
        mean += d[i] / double(count);
    }
    const double floor = std::max(1e-2 * mean, 1e-12 * prep.rmsObserved * prep.rmsObserved);
    for (std::size_t i = 0; i < count; ++i) {
        const UsedPixel& u = prep.pixels[i];
        const int width = prep.widths[u.view], height = prep.heights[u.view];
        const int x = int(u.pixel) % width, y = int(u.pixel) / width;
        double sum = 0;
        int n = 0;
        for (int yy = std::max(y - kInstrumentRadius, 0);
             yy <= std::min(y + kInstrumentRadius, height - 1); ++yy)
            for (int xx = std::max(x - kInstrumentRadius, 0);
                 xx <= std::min(x + kInstrumentRadius, width - 1); ++xx) {
                const std::int32_t q =
                    prep.index[u.view][std::size_t(yy) * std::size_t(width) + xx];
                if (q < 0 || std::size_t(q) == i) continue;
                sum += d[std::size_t(q)];
                ++n;
            }
        precision[i] = float(1 / ((n > 0 ? sum / n : mean) + floor));
    }
    return precision;
}

template <int P>
void pixelMoment(const Linearization<P>& at, const PixelJacobians<P>* own,
                 const Instruments<P>* instruments, int sets, std::size_t i, const UsedPixel& u,
                 Eigen::VectorXd& m, Eigen::MatrixXd* jacobian, double secondSign) {
    const bool instrumental = instruments != nullptr;
    const Eigen::Index n = Eigen::Index(u.slotCount) * P;
    m.setZero(n);
    if (jacobian != nullptr) jacobian->setZero(n, n);
    for (int k = 0; k < sets; ++k) {
        const int other = instrumental ? 1 - k : k;
        const double w = instrumental ? instruments->weights(other)[i] : at.weights[k][i];
        const double sign = k == 1 ? secondSign : 1.0;
        for (std::uint32_t a = 0; a < u.slotCount; ++a) {
            const Eigen::Matrix<double, 3, P> za =
                instrumental ? loadJacobian<P>(instruments->instruments(other)[u.slotBegin + a])
                             : (*own)[k][a];
            addPackedGradient<P>(m.segment<P>(Eigen::Index(a) * P), sign * w, za,
                                 at.residuals[k][i].template cast<double>());
            for (std::uint32_t b = 0; jacobian != nullptr && b < u.slotCount; ++b)
                addPackedGram<P>(jacobian->block<P, P>(Eigen::Index(a) * P, Eigen::Index(b) * P), w,
                                 za, (*own)[k][b]);
        }
    }
}

template class Instruments<kRgbBlock>;
template class Instruments<kGreyBlock>;
template void pixelMoment<kRgbBlock>(const Linearization<kRgbBlock>&,
                                     const PixelJacobians<kRgbBlock>*,
                                     const Instruments<kRgbBlock>*, int, std::size_t,
                                     const UsedPixel&, Eigen::VectorXd&, Eigen::MatrixXd*, double);
template void pixelMoment<kGreyBlock>(const Linearization<kGreyBlock>&,
                                      const PixelJacobians<kGreyBlock>*,
                                      const Instruments<kGreyBlock>*, int, std::size_t,
                                      const UsedPixel&, Eigen::VectorXd&, Eigen::MatrixXd*, double);

}  // namespace phongfit
