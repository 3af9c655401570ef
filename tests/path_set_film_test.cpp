// PathSetFilm (path_set_film.h): the set it assembles holds each pixel's terms, and their
// vertices, in the order they were traced, pass after pass, whatever order the tiles' records
// interleave the pixels in; a dropped sample leaves nothing, and a pixel that kept fewer samples
// is the mean of those it kept.
#include "path_set_film.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <vector>

namespace phongfit {
namespace {

// Term k of pixel p's sample s: a vertex count and a log-cosine that say which it is.
std::uint32_t vertexCount(std::uint32_t p, int s) { return 1 + (p + std::uint32_t(s)) % 3; }
float logCos(std::uint32_t p, int s, std::uint32_t v) { return -float(1000 * p + 10 * s + v); }

TEST(PathSetFilm, EachPixelKeepsItsTermsInTheOrderTracedAcrossPasses) {
    // A 32x2 film in two 16x2 tiles, as the tile loop traces it: passes of 1, 2, 4 and 4 samples,
    // each over every tile's pixels in order. Some samples leave no term, some two, one is dropped.
    const int width = 32, height = 2, spp = 11;
    std::vector<int> paths(width * height, spp);
    paths[3] = 7;  // a pixel that takes fewer
    PathSetFilm film(width, height, paths, 2);
    const auto terms = [](std::uint32_t p, int s) {
        return (p * 7 + std::uint32_t(s)) % 4 == 0 ? 0 : 1 + (s % 5 == 4);
    };
    const auto dropped = [](std::uint32_t p, int s) { return p == 17 && s == 5; };
    for (const auto& [s0, s1] : {std::pair{0, 1}, {1, 3}, {3, 7}, {7, 11}})
        for (std::size_t tile = 0; tile < 2; ++tile)
            for (std::uint32_t y = 0; y < std::uint32_t(height); ++y)
                for (std::uint32_t x = 16 * std::uint32_t(tile); x < 16 * (tile + 1); ++x) {
                    const std::uint32_t p = y * width + x;
                    for (int s = s0; s < std::min(s1, film.samples(p)); ++s) {
                        auto sample = film.startSample(tile, p);
                        for (int t = 0; t < terms(p, s); ++t) {
                            std::vector<PathVertex> vertices;
                            for (std::uint32_t v = 0; v < vertexCount(p, s); ++v)
                                vertices.push_back({logCos(p, s, v), p});
                            sample.add(Color3::Constant(s + 0.25 * t), vertices);
                        }
                        if (dropped(p, s))
                            sample.drop();
                        else
                            sample.keep(Color3::Zero());
                    }
                }
    const PathSet set = film.assemble(spp, 1);

    ASSERT_EQ(set.pixelStart.size(), std::size_t(width * height + 1));
    for (std::uint32_t p = 0; p < std::uint32_t(width * height); ++p) {
        const int kept = paths[p] - (p == 17 ? 1 : 0);
        std::uint32_t i = set.pixelStart[p];
        for (int s = 0; s < paths[p]; ++s) {
            if (dropped(p, s)) continue;
            for (int t = 0; t < terms(p, s); ++t, ++i) {
                ASSERT_LT(i, set.pixelStart[p + 1]) << "pixel " << p << " sample " << s;
                const PathTerm& term = set.terms[i];
                EXPECT_EQ(term.pixel, p);
                EXPECT_FLOAT_EQ(term.constant[0], float((s + 0.25 * t) / kept)) << p << " " << s;
                ASSERT_EQ(term.vertexCount, vertexCount(p, s));
                for (std::uint32_t v = 0; v < term.vertexCount; ++v)
                    EXPECT_EQ(set.vertices[term.firstVertex + v].logCos, logCos(p, s, v))
                        << "pixel " << p << " sample " << s << " vertex " << v;
            }
        }
        EXPECT_EQ(i, set.pixelStart[p + 1]) << "pixel " << p;
    }
}

}  // namespace
}  // namespace phongfit
