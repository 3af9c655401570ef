// The DiLiGenT ball (96 photographs, about 1.4 million used pixel-light pairs) on 2 threads:
// reading the capture, the Phong fit on all lights, and the hold-out run (fit lights 1-48, fit
// Lambertian-only too, predict 49-96). Issue target: fitting all 96 images in under 5 s wall.
// The per-pixel albedo fit (`fit --capture --albedo per-pixel`) of the ball and of pot2, as the
// command runs it on all 96 lights, reading and the decoding check included. Issue target: any
// 96-light DiLiGenT capture in at most 10 s wall.
#include <benchmark/benchmark.h>

#include <numeric>
#include <string>

#include "capture.h"
#include "capture_fit.h"
#include "capture_run.h"

namespace phongfit {
namespace {

constexpr int kThreads = 2;

const Capture& ball() {
    static const Capture capture = readCapture(PHONGFIT_BALL_DIR);
    return capture;
}

std::vector<int> lights(int first, int last) {
    std::vector<int> v(last - first + 1);
    std::iota(v.begin(), v.end(), first);
    return v;
}

void BM_BallRead(benchmark::State& state) {
    for (auto _ : state) {
        const Capture c = readCapture(PHONGFIT_BALL_DIR);
        benchmark::DoNotOptimize(readCaptureImages(c, lights(0, 95), {}, kThreads));
    }
}
BENCHMARK(BM_BallRead)->Unit(benchmark::kSecond)->UseRealTime()->Iterations(1);

void BM_BallFitAll96(benchmark::State& state) {
    const std::vector<CaptureImage> images = readCaptureImages(ball(), lights(0, 95), {}, kThreads);
    CaptureFitOptions options;
    options.fit.threads = kThreads;
    int iterations = 0;
    std::size_t pairs = 0;
    for (auto _ : state) {
        const CaptureFit fit = fitCapture(ball(), images, {}, options);
        for (const FitRound& r : fit.phong.rounds) iterations += r.iterations;
        pairs = fit.model.used;
    }
    state.counters["pairs"] = double(pairs);
    state.counters["ceres_iterations"] = double(iterations) / double(state.iterations());
}
BENCHMARK(BM_BallFitAll96)->Unit(benchmark::kSecond)->UseRealTime()->Iterations(1);

void BM_BallHoldout(benchmark::State& state) {
    const std::vector<CaptureImage> fitted = readCaptureImages(ball(), lights(0, 47), {}, kThreads);
    const std::vector<CaptureImage> heldOut =
        readCaptureImages(ball(), lights(48, 95), {}, kThreads);
    CaptureFitOptions options;
    options.fit.threads = kThreads;
    for (auto _ : state) benchmark::DoNotOptimize(fitCapture(ball(), fitted, heldOut, options));
}
BENCHMARK(BM_BallHoldout)->Unit(benchmark::kSecond)->UseRealTime()->Iterations(1);

void albedoMapRun(benchmark::State& state, const std::string& dir, Encoding encoding) {
    CaptureFitInputs inputs;
    inputs.dir = dir;
    inputs.read.decoding.encoding = encoding;
    inputs.fit.fit.threads = kThreads;
    inputs.perPixelAlbedo = true;
    std::size_t pairs = 0;
    for (auto _ : state) pairs = runCaptureFit(inputs, true).albedoMap->fit.pairs;
    state.counters["pairs"] = double(pairs);
}

void BM_BallAlbedoMapRun(benchmark::State& state) {
    albedoMapRun(state, PHONGFIT_BALL_DIR, Encoding::Auto);
}
BENCHMARK(BM_BallAlbedoMapRun)->Unit(benchmark::kSecond)->UseRealTime()->Iterations(1);

void BM_Pot2AlbedoMapRun(benchmark::State& state) {
    albedoMapRun(state, PHONGFIT_POT2_DIR, Encoding::Linear);
}
BENCHMARK(BM_Pot2AlbedoMapRun)->Unit(benchmark::kSecond)->UseRealTime()->Iterations(1);

}  // namespace
}  // namespace phongfit

BENCHMARK_MAIN();
