#include "defensive_sampler.h"

#include <algorithm>

#include "warp.h"

namespace phongfit {

namespace {
constexpr double kLobeFloor = 0.25;
}

DefensiveSampler::DefensiveSampler(double defensive)
    : PhongSampler<double>("defensive"),
      defensive_(defensive),
      mixture_(makePhongSampler<double>("mixture")) {}

PhongMaterial DefensiveSampler::samplingMaterial(const PhongMaterial& m) {
    const double pd = m.kd.mean(), ps = m.ks.mean();
    double shareSpecular = pd + ps > 0 ? ps / (pd + ps) : 0.5;
    shareSpecular = std::clamp(shareSpecular, kLobeFloor, 1 - kLobeFloor);
    PhongMaterial s = m;
    s.kd = Color3::Constant(1 - shareSpecular);
    s.ks = Color3::Constant(shareSpecular);
    return s;
}

std::optional<PhongSample<double>> DefensiveSampler::sample(const PhongMaterial& m, const Vec3d& wo,
                                                            double uLobe, const Vec2d& u) const {
    if (!(wo.z() > 0)) return std::nullopt;
    Vec3d wi;
    Lobe lobe = Lobe::Diffuse;
    if (uLobe < defensive_) {
        wi = squareToCosineHemisphere(u);
    } else {
        const auto s =
            mixture_->sample(samplingMaterial(m), wo, (uLobe - defensive_) / (1 - defensive_), u);
        if (!s) return std::nullopt;
        wi = s->wi;
        lobe = s->lobe;
    }
    const double density = pdf(m, wo, wi);
    if (!(density > 0)) return std::nullopt;
    return PhongSample<double>{wi, density, phongEval(m, wi, wo) * (wi.z() / density), lobe};
}

double DefensiveSampler::pdf(const PhongMaterial& m, const Vec3d& wo, const Vec3d& wi) const {
    if (!(wo.z() > 0) || !(wi.z() > 0)) return 0;
    return unclippedPdf(m, wo, wi);
}

double DefensiveSampler::unclippedPdf(const PhongMaterial& m, const Vec3d& wo,
                                      const Vec3d& wi) const {
    return defensive_ * cosineHemispherePdf(wi) +
           (1 - defensive_) * mixture_->unclippedPdf(samplingMaterial(m), wo, wi);
}

}  // namespace phongfit
