// The film an image is rendered to: per pixel the mean of the samples it kept, with the variance
// of that mean. Fed by the tile loop (tile_loop.h), which sums each sample's radiance.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "renderer.h"

namespace phongfit {

class RgbFilm {
public:
    // `rendered`: per pixel, 0 where it takes no sample (RenderOptions::rendered); empty: every
    // pixel takes `spp`.
    RgbFilm(int width, int height, int spp, std::span<const std::uint8_t> rendered = {});

    int samples(std::uint32_t p) const { return rendered_.empty() || rendered_[p] ? spp_ : 0; }

    class Sample {
    public:
        Sample(RgbFilm& film, std::uint32_t pixel) : film_(film), pixel_(pixel) {}
        void add(const Color3&, std::span<const PathVertex>) {}  // the loop sums the radiance
        void keep(const Color3& radiance) { film_.add(pixel_, radiance); }
        void drop() {}

    private:
        RgbFilm& film_;
        std::uint32_t pixel_;
    };
    Sample startSample(std::size_t /*tile*/, std::uint32_t pixel, int /*sample*/) {
        return Sample(*this, pixel);
    }

    // The image, with the loop's stats.
    RenderResult result(RenderStats stats) const;

private:
    void add(std::uint32_t pixel, const Color3& radiance);

    int width_, height_, spp_;
    std::span<const std::uint8_t> rendered_;
    std::vector<double> sum_, sumSq_;  // 3 per pixel
    std::vector<std::uint32_t> count_;
};

}  // namespace phongfit
