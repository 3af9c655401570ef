// Cost per call of the BRDF and its samplers: eval for float, double and the Jet the fitter uses,
// sample() of every sampler for float and double. Inputs cycle through a fixed table of random
// directions and numbers, so the branches taken are those of a real render.
#include <benchmark/benchmark.h>
#include <ceres/jet.h>

#include <array>
#include <cmath>
#include <cstddef>

#include "phong_brdf.h"
#include "phong_sampler.h"
#include "rng.h"

namespace phongfit {
namespace {

constexpr std::size_t kTable = 1024;  // a power of two: index with & (kTable - 1)

template <typename T>
struct Inputs {
    std::array<Vec3<T>, kTable> wi, wo;
    std::array<T, kTable> uLobe;
    std::array<Vec2<T>, kTable> u;

    Inputs() {
        const CounterRng rng(1, 0);
        auto upper = [&](std::size_t i, std::uint32_t dim) {
            const double z = 1 - rng.uniform(i, dim), phi = 2 * kPi * rng.uniform(i, dim + 1);
            const double s = std::sqrt(1 - z * z);
            return Vec3<T>(T(s * std::cos(phi)), T(s * std::sin(phi)), T(z));
        };
        for (std::size_t i = 0; i < kTable; ++i) {
            wi[i] = upper(i, 0);
            wo[i] = upper(i, 2);
            uLobe[i] = T(rng.uniform(i, 4));
            u[i] = Vec2<T>(T(rng.uniform(i, 5)), T(rng.uniform(i, 6)));
        }
    }
};

template <typename T>
PhongParams<T> params() {
    PhongParams<T> p;
    p.kd = Color<T>(T(0.3), T(0.2), T(0.1));
    p.ks = Color<T>(T(0.6), T(0.5), T(0.4));
    p.n = T(100);
    return p;
}

template <typename T>
void BM_Eval(benchmark::State& state) {
    const Inputs<T> in;
    PhongParams<T> p = params<T>();
    p.n = T(state.range(0));
    std::size_t i = 0;
    for (auto _ : state) {
        const std::size_t k = i++ & (kTable - 1);
        benchmark::DoNotOptimize(phongEval(p, in.wi[k], in.wo[k]));
    }
}
// n 100, and 30000, where cos^n of most random directions is exactly 0.
BENCHMARK_TEMPLATE(BM_Eval, float)->Arg(100)->Arg(30000);
BENCHMARK_TEMPLATE(BM_Eval, double)->Arg(100)->Arg(30000);

// The fitter's case: Jet parameters (kd, ks, log n: 7 derivatives), double directions.
void BM_EvalJet7(benchmark::State& state) {
    using Jet = ceres::Jet<double, 7>;
    const Inputs<double> in;
    PhongParams<Jet> p;
    for (int c = 0; c < 3; ++c) {
        p.kd[c] = Jet(0.3, c);
        p.ks[c] = Jet(0.6, 3 + c);
    }
    p.n = exp(Jet(std::log(double(state.range(0))), 6));
    std::size_t i = 0;
    for (auto _ : state) {
        const std::size_t k = i++ & (kTable - 1);
        benchmark::DoNotOptimize(phongEval(p, in.wi[k], in.wo[k]));
    }
}
BENCHMARK(BM_EvalJet7)->Arg(100)->Arg(30000);

// exp(n log cos alpha) of random directions at n = 30000: std::exp, whose underflow path sets
// errno, against expOrZero, which skips exp where it is exactly 0 (the same bits).
template <bool kSkip>
void BM_LobePower(benchmark::State& state) {
    const Inputs<double> in;
    std::array<double, kTable> x;
    for (std::size_t k = 0; k < kTable; ++k) x[k] = 30000 * logCosAlpha(in.wi[k], in.wo[k]);
    std::size_t i = 0;
    for (auto _ : state) {
        const double v = x[i++ & (kTable - 1)];
        benchmark::DoNotOptimize(kSkip ? expOrZero(v) : std::exp(v));
    }
    state.SetLabel(kSkip ? "expOrZero" : "std::exp");
}
BENCHMARK_TEMPLATE(BM_LobePower, false);
BENCHMARK_TEMPLATE(BM_LobePower, true);

// range(0) indexes phongSamplerNames().
template <typename T>
void BM_Sample(benchmark::State& state) {
    const std::string& name = phongSamplerNames().at(std::size_t(state.range(0)));
    const auto sampler = makePhongSampler<T>(name);
    const Inputs<T> in;
    const PhongParams<T> p = params<T>();
    std::size_t i = 0;
    for (auto _ : state) {
        const std::size_t k = i++ & (kTable - 1);
        benchmark::DoNotOptimize(sampler->sample(p, in.wo[k], in.uLobe[k], in.u[k]));
    }
    state.SetLabel(name);
}
BENCHMARK_TEMPLATE(BM_Sample, float)->DenseRange(0, 4);
BENCHMARK_TEMPLATE(BM_Sample, double)->DenseRange(0, 4);

}  // namespace
}  // namespace phongfit

BENCHMARK_MAIN();
