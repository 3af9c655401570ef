// libFuzzer target: EXR reading as the tool does it (readImage on a .exr file: the header checked
// against image_limits.h through OpenEXRCore, then OpenEXR's InputFile, R, G, B or Y as FLOAT). A
// phongfit::Error is the expected answer to a bad file; anything else escaping is a bug, and so is
// an allocation over the fuzzer's limit. OpenEXR itself is the system library, not instrumented:
// this finds crashes, exceptions that phongfit lets through, what a header can make it allocate,
// and misuse of what OpenEXR returns.
#include <cstddef>
#include <cstdint>
#include <cstdlib>

#include "error.h"
#include "fuzz_input.h"
#include "image.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const std::string path = phongfit::fuzz::scratch().write("fuzz.exr", data, size);
    try {
        const phongfit::Image image = phongfit::readImage(path);
        if (image.width <= 0 || image.height <= 0 || image.rgb.size() != 3 * image.pixelCount())
            std::abort();
    } catch (const phongfit::Error&) {
    }
    return 0;
}
