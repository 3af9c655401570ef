// libFuzzer target: the scene parser (Mitsuba XML subset) on arbitrary text. A phongfit::Error is
// the expected answer to bad input; anything else escaping (another exception, a crash, a sanitizer
// report, a hang) is a bug. Relative OBJ names resolve in fuzz::sceneBaseDir().
#include <cstddef>
#include <cstdint>
#include <string>

#include "error.h"
#include "fuzz_input.h"
#include "scene_parser.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const std::string text(reinterpret_cast<const char*>(data), size);
    try {
        phongfit::parseScene(text, "fuzz.xml", {}, phongfit::fuzz::sceneBaseDir());
    } catch (const phongfit::Error&) {
    }
    return 0;
}
