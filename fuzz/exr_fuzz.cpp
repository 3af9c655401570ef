// libFuzzer target: EXR reading as the tool does it (readImage on a .exr file: the header checked
// against image_limits.h through OpenEXRCore, then OpenEXR's InputFile, R, G, B or Y as FLOAT), in
// its data window (environment maps) and framed in its display window (images to fit). A
// phongfit::Error is the expected answer to a bad file; anything else escaping is a bug, and so is
// an allocation over the fuzzer's limit. OpenEXR itself is the system library, not instrumented:
// this finds crashes, exceptions that phongfit lets through, what a header can make it allocate,
// and misuse of what OpenEXR returns.
#include <cstddef>
#include <cstdint>

#include "fuzz_input.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    phongfit::ReadOptions framed;
    framed.exrDisplayWindow = true;
    phongfit::fuzz::readImageOrError(data, size, "fuzz.exr", {phongfit::ReadOptions{}, framed});
    return 0;
}
