// Portable float maps (.pfm): the linear float images that Tungsten (built without OpenEXR), pbrt
// and HDR tools write. The format is a three-token text header and raw floats, read here without
// a library, so that every byte a file declares is checked before anything is allocated.
#pragma once

#include <string>

#include "image.h"

namespace phongfit {

// Reads a PFM file: "PF" (RGB) or "Pf" (grey), width and height, then a scale whose sign gives
// the byte order (negative: little-endian) and whose magnitude is ignored, as Netpbm does; one
// whitespace byte; then the rows, from the bottom of the image up. Throws Error naming the file
// and what is wrong (the header, its size against kMaxImagePixels, the data against the file's
// size) before any pixel is allocated.
Image readPfm(const std::string& path);

}  // namespace phongfit
