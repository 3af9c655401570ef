// Cost of replaying a pixel's recorded terms, the fitter's inner loop: the prediction (double), the
// generic Jet replay (replayPixel with the channel-packed Jets) and the fitter's seeded replay,
// which writes the one-vertex terms' Jet arithmetic out (the same bits). Pixels hold 64 one-vertex
// terms each, their lobe angles drawn around the mirror direction so that about half the terms
// are inside a lobe of exponent n.
#include <benchmark/benchmark.h>

#include <cmath>
#include <vector>

#include "material_params.h"
#include "replay.h"
#include "replay_jacobian.h"
#include "rng.h"

namespace phongfit {
namespace {

constexpr int kPixels = 1024, kTerms = 64;

PathSet onePixelTerms(double n) {
    const CounterRng rng(7, 0);
    PathSet paths;
    paths.width = kPixels;
    paths.height = 1;
    paths.spp = kTerms;
    paths.slots = 1;
    paths.pixelStart.push_back(0);
    for (int p = 0; p < kPixels; ++p) {
        paths.background.push_back(Color<float>(0.01f, 0.02f, 0.03f));
        for (int t = 0; t < kTerms; ++t) {
            const std::size_t i = std::size_t(p) * kTerms + std::size_t(t);
            // 1 - cos(alpha) spread over a few lobe widths (1 / n).
            const double h = 4.0 / n * rng.uniform(i, 0);
            paths.vertices.push_back({float(std::log1p(-h)), 0});
            PathTerm term;
            term.pixel = std::uint32_t(p);
            term.firstVertex = std::uint32_t(i);
            term.vertexCount = 1;
            term.constant = Color<float>(float(rng.uniform(i, 1)), 0.5f, 0.25f);
            paths.terms.push_back(term);
        }
        paths.pixelStart.push_back(std::uint32_t(paths.terms.size()));
    }
    return paths;
}

PhongMaterial material(double n) {
    PhongMaterial m;
    m.kd = Color3(0.3, 0.2, 0.1);
    m.ks = Color3(0.5, 0.4, 0.3);
    m.n = n;
    return m;
}

void BM_ReplayDouble(benchmark::State& state) {
    const PathSet paths = onePixelTerms(double(state.range(0)));
    const PhongMaterial m = material(double(state.range(0)));
    for (auto _ : state)
        for (int p = 0; p < kPixels; ++p) benchmark::DoNotOptimize(replayPixel(paths, p, &m));
    state.SetItemsProcessed(state.iterations() * kPixels * kTerms);
}
BENCHMARK(BM_ReplayDouble)->Arg(300)->Arg(30000);

// The Jets of packedParams at the material, as replayNaturalJacobian seeds them.
PhongParams<PackedJet> seededMaterial(double n) {
    const auto y = naturalFromPhong<kRgbBlock>(material(n));
    return packedParams<kRgbBlock>(y.data());
}

void BM_ReplayJetGeneric(benchmark::State& state) {
    const PathSet paths = onePixelTerms(double(state.range(0)));
    const PhongParams<PackedJet> m = seededMaterial(double(state.range(0)));
    for (auto _ : state)
        for (int p = 0; p < kPixels; ++p) benchmark::DoNotOptimize(replayPixel(paths, p, &m));
    state.SetItemsProcessed(state.iterations() * kPixels * kTerms);
}
BENCHMARK(BM_ReplayJetGeneric)->Arg(300)->Arg(30000);

void BM_ReplayJetSeeded(benchmark::State& state) {
    const PathSet paths = onePixelTerms(double(state.range(0)));
    const PhongParams<PackedJet> m = seededMaterial(double(state.range(0)));
    for (auto _ : state)
        for (int p = 0; p < kPixels; ++p)
            benchmark::DoNotOptimize(replaySeededPixel(paths, p, &m, 0));
    state.SetItemsProcessed(state.iterations() * kPixels * kTerms);
}
BENCHMARK(BM_ReplayJetSeeded)->Arg(300)->Arg(30000);

}  // namespace
}  // namespace phongfit

BENCHMARK_MAIN();
