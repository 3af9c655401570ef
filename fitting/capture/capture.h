// A photometric-stereo capture in the DiLiGenT layout: one fixed orthographic camera, one
// photograph per distant light, known normals. A folder holds
//
//     filenames.txt          image names (relative to the folder), one per line, in light order
//     light_directions.txt   per light: x y z, unit, towards the light, in the camera frame
//     light_intensities.txt  per light: R G B, the light's relative intensity
//     mask.png               the object's pixels (nonzero)
//     normals.exr            per pixel the unit normal (x, y, z) as R, G, B
//
// Camera frame: x to the right of the image, y up, z towards the camera; the view direction is
// (0, 0, 1) at every pixel. Images are 8/16-bit PNG (or JPEG, TIFF) or EXR, all of one size.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "image.h"
#include "math.h"

namespace phongfit {

// Normals and light directions may be off unit length by this much (rounding in the files); they
// are normalised on reading.
inline constexpr double kUnitTolerance = 1e-3;
// The largest text file of a capture (a line per light): far above any real capture.
inline constexpr std::uintmax_t kMaxCaptureTextBytes = std::uintmax_t(16) << 20;

struct CaptureLight {
    int number = 0;  // 1-based: the line of filenames.txt
    std::string imagePath;
    Vec3d direction;  // unit, towards the light
    Color3 intensity;
};

// The capture without its photographs: lights, mask and normals, restricted to the mask.
struct Capture {
    std::string dir;
    std::string maskPath, normalsPath;
    int width = 0, height = 0;
    std::vector<std::uint32_t> pixels;  // y * width + x of each mask pixel, in row order
    std::vector<Vec3d> normals;         // per mask pixel, unit, camera frame
    // Mask pixels left out because their normal is zero, not unit or not finite (real data has
    // such pixels: DiLiGenT's pot2 has 73 zero normals inside its mask).
    std::size_t badNormals = 0;
    std::vector<CaptureLight> lights;  // every light of the folder, in order
};

struct CaptureReadOptions {
    ReadOptions decoding;  // how 8- and 16-bit values become linear (16-bit: linear by default)
    // A pixel with a channel at or above this linear value (before the light's intensity is
    // divided out) is clipped, as is one at the format's maximum.
    std::optional<double> saturation;
    std::string mask;  // used instead of DIR/mask.png when not empty
};

enum class PixelState : std::uint8_t { Ok, Clipped, NonFinite };

// One light's photograph on the mask pixels.
struct CaptureImage {
    int light = 0;                         // index into Capture::lights
    std::vector<Color<float>> rgb;         // per mask pixel, divided by the light's intensity
    std::vector<PixelState> state;         // per mask pixel
    std::string decoding;                  // Image::decoding of the photograph
    std::optional<Encoding> integerCurve;  // Image::integerCurve
};

// More than this fraction of the mask's pixels with a bad normal means the normals (or the mask) do
// not belong to the capture: an error rather than pixels left out.
inline constexpr double kMaxBadNormalFraction = 0.05;
// More than this fraction of a set of lights' (mask pixel, light) pairs with a NaN or infinite
// value means the photographs are broken, not a few bad pixels: an error rather than pairs left
// out.
inline constexpr double kMaxNonFiniteFraction = 0.05;

// Reads and checks the text files, the mask and the normals (not the photographs). A mask pixel
// whose normal is not unit within kUnitTolerance is left out and counted (Capture::badNormals).
// Throws Error naming the file for: a missing folder or file, a line that is not three numbers,
// counts that disagree between the three text files, a light direction that is not unit, an
// intensity that is not > 0, bad normals in more than kMaxBadNormalFraction of the mask (naming
// the first), and a mask of the wrong size or that selects no pixel.
Capture readCapture(const std::string& dir, const CaptureReadOptions& options = {});

// Reads the photographs of `lights` (indices into capture.lights), in parallel on `threads` threads
// (0 = all hardware threads). Throws Error naming the file if one is missing or unreadable, not the
// normals' size, or black everywhere inside the mask.
std::vector<CaptureImage> readCaptureImages(const Capture& capture, const std::vector<int>& lights,
                                            const CaptureReadOptions& options, int threads = 0);

// A list of 1-based light numbers such as "1-10,20,30-40", as indices (0-based) into a capture of
// `count` lights, in the order given. Throws Error naming `flag` for malformed text, numbers
// outside 1..count, descending ranges and repeated lights.
std::vector<int> parseLightList(const std::string& text, int count, const std::string& flag);

}  // namespace phongfit
