// The instrumental-variables moments (docs/design/fitter.md):
//
//     g(y) = sum over pixels and sets k of W_other Z_other^T r_k(y)
//
// with the instruments Z of each set its Jacobians at the instrument point, smoothed over the
// pixels around, and W its robust loss weights over the pixel's residual variance. Any function of
// the other set is a valid instrument; these make the estimate efficient and robust.
#pragma once

#include <tbb/task_arena.h>

#include <Eigen/Core>
#include <array>
#include <cstddef>
#include <vector>

#include "material_params.h"
#include "objective.h"

namespace phongfit {

// Instruments are averaged over this many pixels on each side, and pixels this near one that sees
// a material enter the moments.
inline constexpr int kInstrumentRadius = 2;

// One point (the last analysis, analysis.h): its flat natural coordinates, and each set's
// weighted residuals and robust loss weights per pixel, as floats (the fitter holds these for
// every used pixel; docs/design/fitter.md, "Memory"). The Jacobians there are replayed where
// needed rather than kept: 2 x 36 bytes a pixel more than all of this.
template <int P>
struct Linearization {
    std::vector<double> y;
    std::array<std::vector<Eigen::Vector3f>, 2> residuals;
    std::array<std::vector<float>, 2> weights;
};

// A pixel's weighted Jacobians per set and slot of the pixel (Objective::Scratch::jacobians).
template <int P>
using PixelJacobians = std::array<std::vector<Eigen::Matrix<double, 3, P>>, 2>;

template <int P>
class Instruments {
public:
    using Jacobian = Eigen::Matrix<double, 3, P>;

    bool empty() const { return instruments_[0].empty(); }
    const std::vector<StoredJacobian>& instruments(int k) const { return instruments_[k]; }
    const std::vector<float>& weights(int k) const { return weights_[k]; }

    // Makes the Jacobians and loss weights of `at` the instruments; also their Gram matrix, for
    // the whitening, and the moments of the pixels that see no material, which do not depend on
    // the parameters.
    void adopt(Objective<P>& objective, const Linearization<P>& at);

    // g at flat natural coordinates y and, if `jacobian` is not null, dg/dy.
    void momentSums(Objective<P>& objective, const double* y, Eigen::VectorXd& g,
                    Eigen::MatrixXd* jacobian) const;

    // L^-1 with L L^T the instruments' Gram matrix over the flat coordinates `free`.
    Eigen::MatrixXd whitening(const std::vector<int>& free) const;

private:
    std::array<std::vector<StoredJacobian>, 2> instruments_;  // per set, per pixel slot
    std::array<std::vector<float>, 2> weights_;               // per set and pixel
    Eigen::MatrixXd gram_;
    Eigen::VectorXd constantMoments_;
};

// 1 / the variance of each used pixel's residual, estimated from the two sets' residuals at its
// neighbours (not the pixel itself, so the weight is independent of the residual it weights).
std::vector<float> residualPrecisions(const UsedPixels& pixels,
                                      const std::array<std::vector<Eigen::Vector3f>, 2>& residuals);

// Replaces each entry of `jacobians` (per pixel slot) by its average over the
// (2 kInstrumentRadius + 1)^2 pixels around its pixel, in the same slot (pixels that are not used
// or see no material count as 0): a few samples make a pixel's Jacobian as noisy as its value,
// and instruments that noisy cost the estimate precision. In place, holding a few rows aside: a
// second copy would be the largest part of the fit's state as it makes the second set's
// instruments (docs/design/fitter.md, "Memory").
void smoothJacobians(const UsedPixels& pixels, std::vector<StoredJacobian>& jacobians,
                     tbb::task_arena& arena);

// Pixel i's term m of the estimating equations and, if `jacobian` is not null, its Jacobian, over
// the pixel's slots, from `at`: W_other Z_other^T r_k summed over the sets with `instruments`,
// least squares' rho' J^T r (its instruments are its own Jacobians) when that is null. `own`: the
// pixel's Jacobians at `at` (read for least squares or with `jacobian`; may be null otherwise).
// `secondSign` -1 takes the second set's residual negated: with two sets the term's part that is
// the recordings' own noise (the image's cancels), for recordingShare.
template <int P>
void pixelMoment(const Linearization<P>& at, const PixelJacobians<P>* own,
                 const Instruments<P>* instruments, int sets, std::size_t i, const UsedPixel& u,
                 Eigen::VectorXd& m, Eigen::MatrixXd* jacobian, double secondSign = 1);

extern template class Instruments<kRgbBlock>;
extern template class Instruments<kGreyBlock>;

}  // namespace phongfit
