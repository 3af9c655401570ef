// libFuzzer target: EXR reading as the tool does it (readImage on a .exr file: OpenEXR's InputFile,
// R, G, B or Y as FLOAT). A phongfit::Error is the expected answer to a bad file; anything else
// escaping is a bug. OpenEXR itself is the system library, not instrumented: this finds crashes
// and exceptions that phongfit lets through, and misuse of what OpenEXR returns.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>

#include "error.h"
#include "fuzz_input.h"
#include "image.h"

namespace {

// OpenEXR 3.1 allocates every header attribute at the size the file claims before reading it (up
// to 2 GB from a few bytes); it then fails cleanly, but under ASan each such input takes seconds.
// Inputs whose attribute sizes exceed the input are skipped so the time goes to the rest.
bool attributeSizesFit(const std::uint8_t* data, std::size_t size) {
    std::size_t pos = 8;  // magic number and version
    for (int attribute = 0; attribute < 1000; ++attribute) {
        for (int field = 0; field < 2; ++field) {  // name and type, NUL-terminated
            const void* end = pos < size ? std::memchr(data + pos, 0, size - pos) : nullptr;
            if (!end) return true;
            const std::size_t length = static_cast<const std::uint8_t*>(end) - (data + pos);
            pos += length + 1;
            if (field == 0 && length == 0) return true;  // end of the header
        }
        if (pos + 4 > size) return true;
        const std::uint32_t bytes = std::uint32_t(data[pos]) | std::uint32_t(data[pos + 1]) << 8 |
                                    std::uint32_t(data[pos + 2]) << 16 |
                                    std::uint32_t(data[pos + 3]) << 24;
        pos += 4;
        if (bytes > size - pos) return false;
        pos += bytes;
    }
    return true;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    if (!attributeSizesFit(data, size)) return -1;  // not added to the corpus
    const std::string path = phongfit::fuzz::scratch().write("fuzz.exr", data, size);
    try {
        const phongfit::Image image = phongfit::readImage(path);
        if (image.width <= 0 || image.height <= 0 || image.rgb.size() != 3 * image.pixelCount())
            std::abort();
    } catch (const phongfit::Error&) {
    }
    return 0;
}
