// The sampler paths are recorded with at fitted vertices. Replay is unbiased for any theta only
// where the recording pdf is positive wherever f_theta can be (DESIGN.md), so a share `defensive`
// of the samples is cosine-weighted (covering a diffuse lobe that is 0 at theta0), and the rest
// picks the Phong lobes with floored probabilities (so a specular lobe that is 0 at theta0 is still
// explored).
#pragma once

#include "phong_sampler.h"

namespace phongfit {

class DefensiveSampler final : public PhongSampler<double> {
public:
    explicit DefensiveSampler(double defensive);

    std::optional<PhongSample<double>> sample(const PhongMaterial& m, const Vec3d& wo, double uLobe,
                                              const Vec2d& u) const override;
    double pdf(const PhongMaterial& m, const Vec3d& wo, const Vec3d& wi) const override;
    double unclippedPdf(const PhongMaterial& m, const Vec3d& wo, const Vec3d& wi) const override;
    double mass(const PhongMaterial&) const override { return 1; }

private:
    // The material the lobe mixture samples with: lobe weights floored at kLobeFloor.
    static PhongMaterial samplingMaterial(const PhongMaterial& m);

    double defensive_;
    std::unique_ptr<PhongSampler<double>> mixture_;
};

}  // namespace phongfit
