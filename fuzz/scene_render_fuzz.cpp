// libFuzzer target: whatever the scene parser accepts must render without a crash, a hang or a
// non-finite pixel (a non-finite sample is dropped and counted, never written). The scene is
// parsed as scene_parser_fuzz does, then made cheap (a film of at most 6x6 pixels, one sample,
// paths of at most 8 vertices) and rendered on one thread. A phongfit::Error from the parser or
// the renderer's set-up is an acceptable answer; anything else is a bug.
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>

#include "error.h"
#include "fuzz_input.h"
#include "renderer.h"
#include "scene_parser.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    phongfit::Scene scene;
    try {
        scene = phongfit::parseScene(std::string(reinterpret_cast<const char*>(data), size),
                                     "fuzz.xml", {}, phongfit::fuzz::sceneBaseDir());
    } catch (const phongfit::Error&) {
        return -1;  // the parser's own target covers these
    }
    scene.sensor.width = std::min(scene.sensor.width, 6);
    scene.sensor.height = std::min(scene.sensor.height, 6);
    scene.integrator.rrDepth = std::min(scene.integrator.rrDepth, 4);
    phongfit::RenderOptions options;
    options.spp = 1;
    options.threads = 1;
    options.quiet = true;
    options.maxDepth = scene.integrator.maxDepth < 0 ? 8 : std::min(scene.integrator.maxDepth, 8);
    try {
        const phongfit::Renderer renderer(std::move(scene));
        const phongfit::RenderResult r = renderer.render(options);
        for (const float v : r.rgb)
            if (!std::isfinite(v)) std::abort();
        if (r.stats.nonFiniteFirst.size() != std::min<std::uint64_t>(r.stats.nonFinite, 10))
            std::abort();
    } catch (const phongfit::Error&) {
    }
    return 0;
}
