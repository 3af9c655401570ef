// Paths recorded at the parameters theta0, replayed at any theta (DESIGN.md, "Path replay").
//
// A pixel's estimate is  I(theta) = background + sum over terms  constant * prod_k f_theta(v_k),
// where `constant` holds everything that does not depend on the fitted materials (emission,
// geometry and cosine terms, 1 / pdf at theta0, Russian-roulette and MIS weights at theta0, the
// BRDFs of materials that are not fitted, and 1 / spp), and v_k are the term's vertices on fitted
// materials. A vertex keeps only what f needs: its material slot and log(cos alpha).
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "default_init_allocator.h"
#include "math.h"

namespace phongfit {

struct PathVertex {
    float logCos;        // log(cos alpha) at the vertex; -infinity where cos(alpha) <= 0
    std::uint32_t slot;  // index of the fitted material
};

struct PathTerm {
    std::uint32_t pixel;        // y * width + x
    std::uint32_t firstVertex;  // into PathSet::vertices
    std::uint32_t vertexCount;  // >= 1; terms with no fitted vertex go to `background`
    Color<float> constant;
};

// A pixel whose first paths integrate area lights by rings and whose extra paths sample them
// holds two unbiased estimates of one value, the sampled one far noisier in a highlight: its
// estimate weights them by the inverse of their variances, not by their counts
// (docs/design/fitter.md, "Ringed and sampled paths"). The ringed paths' terms come first.
struct PathGroups {
    std::uint32_t ringedTerms = 0;
    // Each group's weight in the estimate over its share of the pixel's paths (1, 1: the mean).
    float ringedScale = 1, sampledScale = 1;
};

struct PathSet {
    int width = 0, height = 0;
    int spp = 0;
    int slots = 0;                         // number of fitted materials
    std::vector<Color<float>> background;  // per pixel: the part that does not depend on theta
    UninitializedVector<PathTerm> terms;   // sorted by pixel
    UninitializedVector<PathVertex> vertices;
    std::vector<std::uint32_t> pixelStart;  // terms of pixel p are [pixelStart[p], pixelStart[p+1])
    // Paths each pixel's estimate is the mean of, where they differ from `spp` (a recording that
    // spends more paths where they inform the fit); empty: `spp` everywhere.
    std::vector<std::uint32_t> pixelPaths;
    // Per pixel, where its first paths integrate area lights by rings and its extra ones sample
    // them (PathGroups); empty: every pixel the plain mean of its paths.
    std::vector<PathGroups> groups;

    // The paths pixel p's estimate is the mean of.
    std::uint32_t pathsAt(std::size_t p) const {
        return pixelPaths.empty() ? std::uint32_t(spp) : pixelPaths[p];
    }
};

}  // namespace phongfit
