// libFuzzer target: the scene parser (Mitsuba XML subset) on arbitrary text. A phongfit::Error is
// the expected answer to bad input; anything else escaping (another exception, a crash, a sanitizer
// report, a hang) is a bug. Relative OBJ names resolve in a scratch directory holding one small
// mesh, `mesh.obj`, so obj shapes are reached too.
#include <cstddef>
#include <cstdint>
#include <string>

#include "error.h"
#include "fuzz_input.h"
#include "scene_parser.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    static const std::string baseDir = [] {
        const std::string mesh = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 3 4\n";
        phongfit::fuzz::scratch().write(
            "mesh.obj", reinterpret_cast<const std::uint8_t*>(mesh.data()), mesh.size());
        return phongfit::fuzz::scratch().path().string();
    }();
    const std::string text(reinterpret_cast<const char*>(data), size);
    try {
        phongfit::parseScene(text, "fuzz.xml", {}, baseDir);
    } catch (const phongfit::Error&) {
    }
    return 0;
}
