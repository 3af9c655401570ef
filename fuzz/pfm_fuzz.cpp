// libFuzzer target: PFM reading as the tool does it (readImage on a .pfm file: pfm_file.h parses
// the header and checks the declared size against the limits and the file before allocating). A
// phongfit::Error is the expected answer to a bad file; anything else escaping is a bug, and so is
// an allocation over the fuzzer's limit.
#include <cstddef>
#include <cstdint>
#include <cstdlib>

#include "error.h"
#include "fuzz_input.h"
#include "image.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const std::string path = phongfit::fuzz::scratch().write("fuzz.pfm", data, size);
    try {
        const phongfit::Image image = phongfit::readImage(path);
        if (image.width <= 0 || image.height <= 0 || image.rgb.size() != 3 * image.pixelCount())
            std::abort();
    } catch (const phongfit::Error&) {
    }
    return 0;
}
