// Path tracer throughput on the Cornell box next to raw Embree rtcIntersect1 throughput for
// incoherent rays in the same scene, on 1 and 2 threads (issue target: the path tracer's rays/s at
// least 60% of the raw figure).
#include <benchmark/benchmark.h>
#include <embree3/rtcore.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <atomic>

#include "renderer.h"
#include "rng.h"
#include "scene_parser.h"

namespace phongfit {
namespace {

const Scene& cornell() {
    static const Scene scene = loadScene(PHONGFIT_SCENES_DIR "/cornell_phong.xml");
    return scene;
}

void BM_CornellPathTracer(benchmark::State& state) {
    const Renderer renderer(cornell());
    RenderOptions options;
    options.spp = int(state.range(0));
    options.threads = int(state.range(1));
    options.quiet = true;
    std::uint64_t rays = 0, samples = 0;
    double seconds = 0;
    for (auto _ : state) {
        const RenderResult r = renderer.render(options);
        rays += r.stats.rays;
        samples += r.stats.samples;
        seconds += r.stats.seconds;
    }
    state.counters["Mrays/s"] = rays / seconds / 1e6;
    state.counters["Msamples/s"] = samples / seconds / 1e6;
}
BENCHMARK(BM_CornellPathTracer)
    ->Args({64, 1})
    ->Args({64, 2})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

// Rays with origins uniform in the scene's bounds and uniform directions: as incoherent as path
// tracing's secondary rays, traced with nothing but rtcIntersect1.
void BM_CornellRawEmbree(benchmark::State& state) {
    const EmbreeScene geometry(cornell());
    const std::size_t n = 1 << 20;
    std::vector<RTCRayHit> rays(n);
    const Vec3d lo = geometry.boundsMin(), hi = geometry.boundsMax();
    const CounterRng rng(1, 2);
    for (std::size_t i = 0; i < n; ++i) {
        Vec3d o, d;
        for (int k = 0; k < 3; ++k) o[k] = lo[k] + (hi[k] - lo[k]) * rng.uniform(i, k);
        const double z = 1 - 2 * rng.uniform(i, 3), phi = 2 * kPi * rng.uniform(i, 4);
        const double r = std::sqrt(std::max(0.0, 1 - z * z));
        d = Vec3d(r * std::cos(phi), r * std::sin(phi), z);
        RTCRay& ray = rays[i].ray;
        ray.org_x = float(o.x()), ray.org_y = float(o.y()), ray.org_z = float(o.z());
        ray.dir_x = float(d.x()), ray.dir_y = float(d.y()), ray.dir_z = float(d.z());
        ray.tnear = 0, ray.time = 0, ray.mask = 0xFFFFFFFF, ray.id = 0, ray.flags = 0;
    }
    tbb::task_arena arena(int(state.range(0)));
    std::uint64_t traced = 0;
    for (auto _ : state) {
        arena.execute([&] {
            tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 4096), [&](const auto& range) {
                RTCIntersectContext ctx;
                rtcInitIntersectContext(&ctx);
                for (std::size_t i = range.begin(); i != range.end(); ++i) {
                    RTCRayHit& rh = rays[i];
                    rh.ray.tfar = std::numeric_limits<float>::infinity();
                    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
                    rtcIntersect1(geometry.rtcScene(), &ctx, &rh);
                }
            });
        });
        traced += n;
    }
    state.counters["Mrays/s"] =
        benchmark::Counter(double(traced) / 1e6, benchmark::Counter::kIsRate);
}
BENCHMARK(BM_CornellRawEmbree)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace phongfit

BENCHMARK_MAIN();
