// libFuzzer target: PFM reading as the tool does it (readImage on a .pfm file: pfm_file.h parses
// the header and checks the declared size against the limits and the file before allocating). A
// phongfit::Error is the expected answer to a bad file; anything else escaping is a bug, and so is
// an allocation over the fuzzer's limit.
#include <cstddef>
#include <cstdint>

#include "fuzz_input.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    phongfit::fuzz::readImageOrError(data, size, "fuzz.pfm");
    return 0;
}
