// libFuzzer target: the capture loader's text files (filenames.txt, light_directions.txt,
// light_intensities.txt) and the --lights list, as `fit --capture` reads them. The input is split
// at NUL bytes into those four texts; the folder also holds a 4x4 mask, normals facing the camera
// and photographs named 1.png, 2.png and 3.exr that filenames.txt may list. A phongfit::Error is
// the expected answer to bad input; anything else escaping is a bug.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "capture.h"
#include "error.h"
#include "fuzz_input.h"
#include "image.h"

namespace {

constexpr int kSize = 4;

std::string writeFolder() {
    const phongfit::fuzz::ScratchDir& dir = phongfit::fuzz::scratch();
    phongfit::Image normals(kSize, kSize), photo(kSize, kSize);
    for (int y = 0; y < kSize; ++y)
        for (int x = 0; x < kSize; ++x) {
            normals.set(x, y, phongfit::Color<float>(0, 0, 1));
            photo.set(x, y, phongfit::Color<float>::Constant(0.1f * float(x + y + 1)));
        }
    phongfit::writeExr(normals, (dir.path() / "normals.exr").string());
    phongfit::writeExr(photo, (dir.path() / "3.exr").string());
    phongfit::writePng(photo, (dir.path() / "1.png").string());
    phongfit::writePng(photo, (dir.path() / "2.png").string(), 4.0);
    phongfit::writePng(cv::Mat(kSize, kSize, CV_8U, cv::Scalar(255)),
                       (dir.path() / "mask.png").string());
    return dir.path().string();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    static const std::string folder = writeFolder();
    std::vector<std::string> parts(1);
    for (std::size_t i = 0; i < size; ++i) {
        if (data[i] == 0 && parts.size() < 4)
            parts.emplace_back();
        else
            parts.back() += char(data[i]);
    }
    parts.resize(4);
    const phongfit::fuzz::ScratchDir& dir = phongfit::fuzz::scratch();
    const char* names[3] = {"filenames.txt", "light_directions.txt", "light_intensities.txt"};
    for (int f = 0; f < 3; ++f)
        dir.write(names[f], reinterpret_cast<const std::uint8_t*>(parts[f].data()),
                  parts[f].size());
    try {
        const phongfit::Capture capture = phongfit::readCapture(folder);
        if (capture.lights.empty() || capture.pixels.size() != capture.normals.size()) std::abort();
        const std::vector<int> lights =
            phongfit::parseLightList(parts[3], int(capture.lights.size()), "--lights");
        for (const int l : lights)
            if (l < 0 || l >= int(capture.lights.size())) std::abort();
        phongfit::readCaptureImages(capture, lights, {}, 1);
    } catch (const phongfit::Error&) {
    }
    return 0;
}
