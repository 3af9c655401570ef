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

// `theta` is indexed by material slot (PathVertex::slot); only the slots the pixel's vertices use
// are read.
template <typename T>
Color<T> replayPixel(const PathSet& paths, std::size_t pixel, const PhongParams<T>* theta) {
    Color<T> sum;
    for (int c = 0; c < 3; ++c) sum[c] = T(double(paths.background[pixel][c]));
    const std::uint32_t end = paths.pixelStart[pixel + 1];
    for (std::uint32_t t = paths.pixelStart[pixel]; t < end; ++t) {
        const PathTerm& term = paths.terms[t];
        const PathVertex* v = paths.vertices.data() + term.firstVertex;
        Color<T> f = phongEvalLogCos(theta[v[0].slot], v[0].logCos);
        for (std::uint32_t k = 1; k < term.vertexCount; ++k)
            f *= phongEvalLogCos(theta[v[k].slot], v[k].logCos);
        for (int c = 0; c < 3; ++c) sum[c] += f[c] * double(term.constant[c]);
    }
    return sum;
}

}  // namespace phongfit
