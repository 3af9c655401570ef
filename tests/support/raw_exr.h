// Writes an RGB float EXR as it is: writeExr refuses non-finite values, and tests need files that
// hold them (the readers must cope with what other programs write).
#pragma once

#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfOutputFile.h>

#include <string>
#include <vector>

#include "image.h"

namespace phongfit::test {

// `image` as the data window `data` of a file framed in `display` (a crop window's render, an
// overscan).
inline void writeRawExr(const Image& image, const Imath::Box2i& display, const Imath::Box2i& data,
                        const std::string& file) {
    const std::size_t pixels = std::size_t(image.width) * std::size_t(image.height);
    std::vector<float> planes[3];
    for (int c = 0; c < 3; ++c)
        for (std::size_t p = 0; p < pixels; ++p) planes[c].push_back(image.rgb[3 * p + c]);
    Imf::Header header(display, data);
    Imf::FrameBuffer frame;
    const char* names[3] = {"R", "G", "B"};
    for (int c = 0; c < 3; ++c) {
        header.channels().insert(names[c], Imf::Channel(Imf::FLOAT));
        frame.insert(names[c], Imf::Slice::Make(Imf::FLOAT, planes[c].data(), data, sizeof(float),
                                                sizeof(float) * image.width));
    }
    Imf::OutputFile out(file.c_str(), header);
    out.setFrameBuffer(frame);
    out.writePixels(image.height);
}

inline void writeRawExr(const Image& image, const std::string& file) {
    const Imath::Box2i window({0, 0}, {image.width - 1, image.height - 1});
    writeRawExr(image, window, window, file);
}

}  // namespace phongfit::test
