// I(theta) of one pixel from its recorded terms (DESIGN.md, "Path replay"):
//
//     I_p(theta) = background_p + sum over terms t of p:  constant_t * prod over vertices v of t
//                  f_theta(v)
//
// with f from phongEvalLogCos, the renderer's own BRDF, so the fitted model is exactly the rendered
// one. Templated on the parameter type: double to predict, ceres::Jet to differentiate.
#pragma once

#include <cstddef>

#include "path_set.h"
#include "phong_brdf.h"

namespace phongfit {

// The product of a term's BRDFs at theta (its constant left out). `theta` is indexed by material
// slot (PathVertex::slot); only the slots the term's vertices use are read.
template <typename T>
Color<T> termBrdfs(const PathSet& paths, const PathTerm& term, const PhongParams<T>* theta) {
    const PathVertex* v = paths.vertices.data() + term.firstVertex;
    Color<T> f = phongEvalLogCos(theta[v[0].slot], v[0].logCos);
    for (std::uint32_t k = 1; k < term.vertexCount; ++k)
        f *= phongEvalLogCos(theta[v[k].slot], v[k].logCos);
    return f;
}

// sum += f(logCos) * constant for a term of one vertex (direct light on a fitted material: most of
// a scene's terms) with material p: phongEvalLogCos's arithmetic, channel by channel, with no
// colour of Jets in between and plain numbers where it multiplied by constant Jets (the same
// values and derivatives to the last bit; the replay is where the fit's time goes).
template <typename T>
void addOneVertexTerm(Color<T>& sum, const PhongParams<T>& p, float logCos,
                      const Color<float>& constant) {
    const T power = phongPower(p.n, logCos);
    if (power == T(0)) {
        for (int c = 0; c < 3; ++c) sum[c] += p.kd[c] * kInvPi * double(constant[c]);
        return;
    }
    const T specular = (p.n + 2.0) * (0.5 * kInvPi) * power;
    for (int c = 0; c < 3; ++c)
        sum[c] += (p.kd[c] * kInvPi + p.ks[c] * specular) * double(constant[c]);
}

// The pixel's background plus its terms, `addOneVertex(sum, vertex, constant)` adding those of
// one vertex (replayPixel's addOneVertexTerm, or the fitter's seeded sums) and termBrdfs the rest.
template <typename T, typename AddOneVertex>
Color<T> replayTerms(const PathSet& paths, std::size_t pixel, const PhongParams<T>* theta,
                     AddOneVertex addOneVertex) {
    Color<T> sum;
    for (int c = 0; c < 3; ++c) sum[c] = T(double(paths.background[pixel][c]));
    const std::uint32_t end = paths.pixelStart[pixel + 1];
    for (std::uint32_t t = paths.pixelStart[pixel]; t < end; ++t) {
        const PathTerm& term = paths.terms[t];
        if (term.vertexCount == 1) {
            addOneVertex(sum, paths.vertices[term.firstVertex], term.constant);
            continue;
        }
        const Color<T> f = termBrdfs(paths, term, theta);
        for (int c = 0; c < 3; ++c) sum[c] += f[c] * double(term.constant[c]);
    }
    return sum;
}

template <typename T>
Color<T> replayPixel(const PathSet& paths, std::size_t pixel, const PhongParams<T>* theta) {
    return replayTerms(paths, pixel, theta,
                       [theta](Color<T>& sum, const PathVertex& v, const Color<float>& constant) {
                           addOneVertexTerm(sum, theta[v.slot], v.logCos, constant);
                       });
}

// The covariance over channels of one path of the pixel at theta, each term taken as a path of
// its own (terms of one camera path also covary; that is left out): N sum t t^T - (sum t)(sum t)^T
// over its terms t, each of which holds 1 / N of its path (its group's weight undone), N the
// pixel's paths. An image rendered with independent samples varies by this over its paths per
// pixel there. One path carries all three channels, so their noise covaries: under white light on
// a grey material the channels vary as one.
inline Eigen::Matrix3d replayPathCovariance(const PathSet& paths, std::size_t pixel,
                                            const PhongMaterial* theta) {
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    Eigen::Matrix3d squares = Eigen::Matrix3d::Zero();
    const std::uint32_t begin = paths.pixelStart[pixel], end = paths.pixelStart[pixel + 1];
    const PathGroups groups = paths.groups.empty() ? PathGroups{} : paths.groups[pixel];
    for (std::uint32_t t = begin; t < end; ++t) {
        const double weight =
            t - begin < groups.ringedTerms ? groups.ringedScale : groups.sampledScale;
        const Eigen::Vector3d x = (termBrdfs(paths, paths.terms[t], theta) *
                                   paths.terms[t].constant.cast<double>() / weight)
                                      .matrix();
        sum += x;
        squares += x * x.transpose();
    }
    const double n = paths.pathsAt(pixel);
    Eigen::Matrix3d covariance = n * squares - sum * sum.transpose();
    covariance.diagonal() = covariance.diagonal().cwiseMax(0.0);
    return covariance;
}

}  // namespace phongfit
