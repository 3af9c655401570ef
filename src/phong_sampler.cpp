#include "phong_sampler.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "error.h"
#include "warp.h"

namespace phongfit {
namespace {

// Chooses the diffuse or the specular lobe, then samples it. Serves lafortune (absorbing, Phong
// lobe), mixture (non-absorbing, Phong lobe) and cap (absorbing, uniform cap).
template <typename T>
class LobeMixtureSampler final : public PhongSampler<T> {
public:
    enum class SpecularWarp { PhongLobe, UniformCap };

    LobeMixtureSampler(std::string name, bool absorbing, SpecularWarp warp)
        : PhongSampler<T>(std::move(name)), absorbing_(absorbing), warp_(warp) {}

    std::optional<PhongSample<T>> sample(const PhongParams<T>& m, const Vec3<T>& wo, T uLobe,
                                         const Vec2<T>& u) const override {
        if (!(cosTheta(wo) > T(0))) return std::nullopt;
        const auto [pd, ps] = lobeProbabilities(m);
        Vec3<T> wi;
        Lobe lobe;
        if (uLobe < pd) {
            wi = squareToCosineHemisphere(u);
            lobe = Lobe::Diffuse;
        } else if (uLobe < pd + ps) {
            const Vec3<T> local = warp_ == SpecularWarp::PhongLobe
                                      ? squareToPhongLobe(u, m.n)
                                      : squareToUniformCap(u, phongCapHeight(m.n));
            wi = Frame<T>(reflectLocal(wo)).toWorld(local);
            lobe = Lobe::Specular;
        } else {
            return std::nullopt;  // absorbed
        }
        if (!(cosTheta(wi) > T(0))) return std::nullopt;
        const T density = pdf(m, wo, wi);
        if (!(density > T(0))) return std::nullopt;
        return PhongSample<T>{wi, density, phongEval(m, wi, wo) * (cosTheta(wi) / density), lobe};
    }

    T pdf(const PhongParams<T>& m, const Vec3<T>& wo, const Vec3<T>& wi) const override {
        if (!(cosTheta(wo) > T(0)) || !(cosTheta(wi) > T(0))) return T(0);
        return unclippedPdf(m, wo, wi);
    }

    T unclippedPdf(const PhongParams<T>& m, const Vec3<T>& wo, const Vec3<T>& wi) const override {
        const auto [pd, ps] = lobeProbabilities(m);
        const T diffuse = pd * cosineHemispherePdf(wi);
        if (!(ps > T(0))) return diffuse;
        const T h = oneMinusCosAlpha(wi, wo);
        const T specular = warp_ == SpecularWarp::PhongLobe ? phongLobePdf(h, m.n)
                                                            : uniformCapPdf(h, phongCapHeight(m.n));
        return diffuse + ps * specular;
    }

    T mass(const PhongParams<T>& m) const override {
        const auto [pd, ps] = lobeProbabilities(m);
        return pd + ps;
    }

private:
    std::pair<T, T> lobeProbabilities(const PhongParams<T>& m) const {
        const T pd = m.kd.mean(), ps = m.ks.mean();
        if (absorbing_) return {pd, ps};
        const T total = pd + ps;
        if (!(total > T(0))) return {T(1), T(0)};  // black material: any lobe will do
        return {pd / total, ps / total};
    }

    bool absorbing_;
    SpecularWarp warp_;
};

template <typename T>
class HemisphereSampler final : public PhongSampler<T> {
public:
    HemisphereSampler(std::string name, bool cosineWeighted)
        : PhongSampler<T>(std::move(name)), cosineWeighted_(cosineWeighted) {}

    std::optional<PhongSample<T>> sample(const PhongParams<T>& m, const Vec3<T>& wo, T,
                                         const Vec2<T>& u) const override {
        if (!(cosTheta(wo) > T(0))) return std::nullopt;
        const Vec3<T> wi =
            cosineWeighted_ ? squareToCosineHemisphere(u) : squareToUniformHemisphere(u);
        const T density = unclippedPdf(m, wo, wi);
        if (!(density > T(0))) return std::nullopt;
        return PhongSample<T>{wi, density, phongEval(m, wi, wo) * (cosTheta(wi) / density),
                              Lobe::Diffuse};
    }

    T pdf(const PhongParams<T>& m, const Vec3<T>& wo, const Vec3<T>& wi) const override {
        if (!(cosTheta(wo) > T(0))) return T(0);
        return unclippedPdf(m, wo, wi);
    }

    T unclippedPdf(const PhongParams<T>&, const Vec3<T>&, const Vec3<T>& wi) const override {
        return cosineWeighted_ ? cosineHemispherePdf(wi) : uniformHemispherePdf(wi);
    }

    T mass(const PhongParams<T>&) const override { return T(1); }

private:
    bool cosineWeighted_;
};

}  // namespace

const std::vector<std::string>& phongSamplerNames() {
    static const std::vector<std::string> names = {"lafortune", "mixture", "cap", "cosine",
                                                   "uniform"};
    return names;
}

template <typename T>
std::unique_ptr<PhongSampler<T>> makePhongSampler(std::string_view name) {
    using Mixture = LobeMixtureSampler<T>;
    using Warp = typename Mixture::SpecularWarp;
    if (name == "lafortune") return std::make_unique<Mixture>("lafortune", true, Warp::PhongLobe);
    if (name == "mixture") return std::make_unique<Mixture>("mixture", false, Warp::PhongLobe);
    if (name == "cap") return std::make_unique<Mixture>("cap", true, Warp::UniformCap);
    if (name == "cosine") return std::make_unique<HemisphereSampler<T>>("cosine", true);
    if (name == "uniform") return std::make_unique<HemisphereSampler<T>>("uniform", false);
    throw Error(fmt::format("unknown sampler '{}' (allowed: {})", name,
                            fmt::join(phongSamplerNames(), ", ")));
}

template std::unique_ptr<PhongSampler<float>> makePhongSampler<float>(std::string_view);
template std::unique_ptr<PhongSampler<double>> makePhongSampler<double>(std::string_view);

}  // namespace phongfit
