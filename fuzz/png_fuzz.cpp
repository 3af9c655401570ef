// libFuzzer target: PNG reading as the tool does it, for images (readImage: 8/16-bit, grey or
// colour, decoded to linear) and for masks (readMask at the image's own size). A phongfit::Error is
// the expected answer to a bad file; anything else escaping is a bug. OpenCV, libpng, libjpeg and
// libtiff are system libraries, not instrumented. OpenCV picks the decoder by content, not by the
// name; phongfit hands it only PNG, JPEG and TIFF content (requireLdrContent), so those three
// decoders are reached (seeds of all three in corpus/png). Found here: DICOM content named .png
// made GDCM abort the process (tests/fuzz_regression_test.cpp).
#include <cstddef>
#include <cstdint>
#include <cstdlib>

#include "error.h"
#include "fuzz_input.h"
#include "image.h"

extern "C" int LLVMFuzzerInitialize(int*, char***) {
    // OpenCV allocates a whole image at the size its header claims (up to 2^30 pixels) before
    // decoding; capped here so that libFuzzer's malloc limit reports phongfit's allocations, not
    // that one. Its warnings about bad files are noise here.
    setenv("OPENCV_IO_MAX_IMAGE_PIXELS", "16777216", 1);
    setenv("OPENCV_LOG_LEVEL", "SILENT", 1);
    return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const std::string path = phongfit::fuzz::scratch().write("fuzz.png", data, size);
    try {
        const phongfit::Image image = phongfit::readImage(path);
        if (image.width <= 0 || image.height <= 0 || image.rgb.size() != 3 * image.pixelCount() ||
            image.clipped.size() != image.pixelCount())
            std::abort();
        const auto mask = phongfit::readMask(path, image.width, image.height);
        if (mask.size() != image.pixelCount()) std::abort();
    } catch (const phongfit::Error&) {
    }
    return 0;
}
