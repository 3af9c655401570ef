// `phongfit` on malformed input, run as a user runs it (a subprocess): each case of the table is
// refused with its exit code and a one-line message holding the expected fragment, and leaves
// nothing behind in its folder (no output, no temporary).
#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfOutputFile.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <functional>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <random>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "image.h"
#include "subprocess.h"

namespace phongfit {
namespace {

namespace fs = std::filesystem;

constexpr int kSize = 8;  // film and image side

// A valid scene; cases change it by replacing one of its lines.
const std::string kScene = R"(<scene version="0.6.0">
    <integrator type="path"><integer name="maxDepth" value="3"/></integrator>
    <sensor type="perspective">
        <float name="fov" value="40"/>
        <transform name="toWorld">
            <lookat origin="0, 0, 5" target="0, 0, 0" up="0, 1, 0"/>
        </transform>
        <sampler type="independent"><integer name="sampleCount" value="1"/></sampler>
        <film type="hdrfilm">
            <integer name="width" value="8"/>
            <integer name="height" value="8"/>
        </film>
    </sensor>
    <bsdf type="phong" id="ball">
        <float name="exponent" value="20"/>
        <rgb name="diffuseReflectance" value="0.5"/>
        <rgb name="specularReflectance" value="0.2"/>
    </bsdf>
    <shape type="sphere">
        <float name="radius" value="1"/>
        <ref id="ball"/>
    </shape>
    <emitter type="point">
        <point name="position" x="2" y="2" z="4"/>
        <spectrum name="intensity" value="10"/>
    </emitter>
</scene>
)";

void writeText(const fs::path& file, const std::string& text) {
    std::ofstream(file, std::ios::binary) << text;
}

// kScene with `from` replaced by `to` (each pair in turn); `from` must occur.
std::string scene(const std::vector<std::pair<std::string, std::string>>& edits) {
    std::string s = kScene;
    for (const auto& [from, to] : edits) {
        const std::size_t at = s.find(from);
        if (at == std::string::npos) throw std::logic_error("not in the base scene: " + from);
        s.replace(at, from.size(), to);
    }
    return s;
}

// Prepares s.xml as kScene with one edit.
std::function<void(const fs::path&)> sceneEdit(const std::string& from, const std::string& to) {
    return [=](const fs::path& d) { writeText(d / "s.xml", scene({{from, to}})); };
}

std::string toWorld(const std::string& operations) {
    return "<transform name=\"toWorld\">" + operations + "</transform>";
}

const std::string kRadius = R"(<float name="radius" value="1"/>)";
const std::string kWidth = R"(<integer name="width" value="8"/>)";
const std::string kSphereRef = R"(<ref id="ball"/>)";
const std::string kLookat = R"(<lookat origin="0, 0, 5" target="0, 0, 0" up="0, 1, 0"/>)";
const std::string kShape = R"(<shape type="sphere">)";

// kScene with the sphere replaced by an obj shape loading m.obj, which holds `obj`.
std::function<void(const fs::path&)> objScene(const std::string& obj) {
    return [=](const fs::path& d) {
        writeText(d / "s.xml",
                  scene({{kShape, R"(<shape type="obj"><string name="filename" value="m.obj"/>)"},
                         {kRadius, ""}}));
        writeText(d / "m.obj", obj);
    };
}

// A float EXR with the named channels, each filled with `value` (NaN at pixel 3 if `nanAt3`).
void writeExrChannels(const fs::path& file, const std::vector<std::string>& names, int width,
                      int height, float value, bool nanAt3 = false) {
    std::vector<float> plane(std::size_t(width) * height, value);
    if (nanAt3) plane[3] = std::numeric_limits<float>::quiet_NaN();
    Imf::Header header(width, height);
    Imf::FrameBuffer frame;
    for (const std::string& c : names) {
        header.channels().insert(c, Imf::Channel(Imf::FLOAT));
        frame.insert(c, Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(plane.data()), sizeof(float),
                                   sizeof(float) * width));
    }
    Imf::OutputFile out(file.c_str(), header);
    out.setFrameBuffer(frame);
    out.writePixels(height);
}

// A 1x1 EXR whose header then claims a data window of `side` x `side` pixels, followed by a line
// offset table of that length (zeros: OpenEXR opens the file and reconstructs the table).
void writeExrClaimingSize(const fs::path& file, int side) {
    writeExrChannels(file, {"R", "G", "B"}, 1, 1, 0.5f);
    std::ifstream in(file, std::ios::binary);
    std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    const std::string key("dataWindow\0box2i\0", 17);
    const std::size_t at = bytes.find(key);
    if (at == std::string::npos) throw std::logic_error("no dataWindow in the EXR header");
    // After the name, type and 4-byte size: xMin, yMin, xMax, yMax, little-endian int32.
    for (const std::size_t offset : {8, 12})
        for (int b = 0; b < 4; ++b)
            bytes[at + key.size() + 4 + offset + b] = char((side - 1) >> (8 * b) & 0xff);
    bytes.append(8 * std::size_t(side), '\0');
    std::ofstream(file, std::ios::binary | std::ios::trunc) << bytes;
}

std::uint32_t crc32(const std::string& bytes) {
    std::uint32_t c = 0xffffffffu;
    for (const char ch : bytes) {
        c ^= std::uint8_t(ch);
        for (int k = 0; k < 8; ++k) c = c & 1 ? 0xedb88320u ^ (c >> 1) : c >> 1;
    }
    return ~c;
}

std::string bigEndian(std::uint32_t v) {
    return {char(v >> 24), char(v >> 16 & 0xff), char(v >> 8 & 0xff), char(v & 0xff)};
}

std::string pngChunk(const std::string& type, const std::string& data) {
    return bigEndian(std::uint32_t(data.size())) + type + data + bigEndian(crc32(type + data));
}

// A PNG whose header says 0 x 0 pixels, with valid checksums and an empty zlib stream.
void writeZeroSizePng(const fs::path& file) {
    const std::string ihdr = bigEndian(0) + bigEndian(0) + std::string("\x08\x02\x00\x00\x00", 5);
    const std::string emptyZlib("\x78\x9c\x03\x00\x00\x00\x00\x01", 8);
    writeText(file, std::string("\x89PNG\r\n\x1a\n", 8) + pngChunk("IHDR", ihdr) +
                        pngChunk("IDAT", emptyZlib) + pngChunk("IEND", ""));
}

// The valid inputs of a fit: s.xml and a matching image i.exr.
void fitInputs(const fs::path& d) {
    writeText(d / "s.xml", kScene);
    writeExrChannels(d / "i.exr", {"R", "G", "B"}, kSize, kSize, 0.25f);
}

void writeMask(const fs::path& file, int width, int height, int depth, double value) {
    cv::imwrite(file.string(), cv::Mat(height, width, depth, cv::Scalar(value)));
}

// A valid photometric-stereo capture of two lights in d/cap, 8x8 pixels, with `edit` applied to
// one of its files (name, new content; no name: unchanged).
std::function<void(const fs::path&)> capture(const std::string& file = "",
                                             const std::string& content = "") {
    return [=](const fs::path& d) {
        const fs::path c = d / "cap";
        fs::create_directory(c);
        Image normals(kSize, kSize);
        for (int y = 0; y < kSize; ++y)
            for (int x = 0; x < kSize; ++x) normals.set(x, y, Color<float>(0, 0, 1));
        writeExr(normals, (c / "normals.exr").string());
        writeMask(c / "mask.png", kSize, kSize, CV_8U, 255);
        cv::imwrite((c / "1.png").string(), cv::Mat(kSize, kSize, CV_16UC3, cv::Scalar::all(2e4)));
        cv::imwrite((c / "2.png").string(), cv::Mat(kSize, kSize, CV_16UC3, cv::Scalar::all(3e4)));
        writeText(c / "filenames.txt", "1.png\n2.png\n");
        writeText(c / "light_directions.txt", "0 0 1\n0.6 0 0.8\n");
        writeText(c / "light_intensities.txt", "1 1 1\n2 2 2\n");
        if (!file.empty()) writeText(c / file, content);
    };
}

struct Case {
    std::string name;
    std::function<void(const fs::path& dir)> prepare;  // writes the inputs into the folder
    std::vector<std::string> args;  // after the executable; "{d}" stands for the folder
    std::string fragment;           // expected in the one line on stderr
    int exitCode = 1;               // 1: phongfit's errors; 105: a value outside a flag's range
};

const std::vector<std::string> kRender = {"render", "{d}/s.xml",   "-o",     "{d}/out.exr",
                                          "--png",  "{d}/out.png", "--quiet"};
const std::vector<std::string> kCapture = {"fit", "--capture", "{d}/cap",
                                           "-o",  "{d}/out",   "--quiet"};
const std::vector<std::string> kFit = {
    "fit", "--view", "{d}/s.xml:{d}/i.exr", "--material", "ball", "-o", "{d}/out", "--quiet"};

std::vector<std::string> with(std::vector<std::string> base, const std::vector<std::string>& more) {
    base.insert(base.end(), more.begin(), more.end());
    return base;
}

std::vector<std::string> fitView(const std::string& view, const std::vector<std::string>& more) {
    std::vector<std::string> args = kFit;
    args[2] = view;
    return with(args, more);
}

const std::vector<Case> kCases = {
    // XML structure
    {"TruncatedXml",
     [](const fs::path& d) { writeText(d / "s.xml", kScene.substr(0, kScene.size() / 2)); },
     kRender, "malformed XML"},
    {"EmptyFile", [](const fs::path& d) { writeText(d / "s.xml", ""); }, kRender, "malformed XML"},
    {"BinaryGarbage",
     [](const fs::path& d) { writeText(d / "s.xml", std::string("\x89PNG\r\n\x1a\n\0\0", 10)); },
     kRender, "malformed XML"},
    {"WrongRoot", [](const fs::path& d) { writeText(d / "s.xml", "<mitsuba version=\"0.6.0\"/>"); },
     kRender, "the root element must be <scene"},
    {"UnsupportedVersion", sceneEdit(R"(<scene version="0.6.0">)", R"(<scene version="2.0.0">)"),
     kRender, "version '2.0.0' is not supported"},
    {"TextInsideElement", sceneEdit(kSphereRef, kSphereRef + "radius=2"), kRender,
     "unexpected text 'radius=2'"},
    {"UnknownElement", sceneEdit(kShape, "<texture type=\"bitmap\"/>" + kShape), kRender,
     "unknown element in <scene>"},
    {"UnknownShapeType", sceneEdit(kShape, R"(<shape type="ply">)"), kRender, "unknown type 'ply'"},
    {"UnknownParameter", sceneEdit(kRadius, kRadius + R"(<float name="radiuss" value="1"/>)"),
     kRender, "unknown parameter 'radiuss'"},
    {"NoSensor",
     [](const fs::path& d) { writeText(d / "s.xml", "<scene version=\"0.6.0\"></scene>"); },
     kRender, "no <sensor>"},
    // Wrong types and numbers
    {"WrongTypeTag", sceneEdit(kWidth, R"(<float name="width" value="8"/>)"), kRender,
     "wrong type <float> for 'width'"},
    {"IntegerNotANumber", sceneEdit(kWidth, R"(<integer name="width" value="eight"/>)"), kRender,
     "'eight' is not a valid integer"},
    {"FloatWithTwoDots", sceneEdit(kRadius, R"(<float name="radius" value="1.2.3"/>)"), kRender,
     "'1.2.3' is not a valid number"},
    {"ColorWithTwoNumbers",
     sceneEdit(R"(<rgb name="diffuseReflectance" value="0.5"/>)",
               R"(<rgb name="diffuseReflectance" value="0.5, 0.2"/>)"),
     kRender, "has 2 numbers"},
    {"HugeFloat", sceneEdit(kRadius, R"(<float name="radius" value="1e999"/>)"), kRender,
     "'1e999' is not a valid number"},
    {"HugeInteger", sceneEdit(kWidth, R"(<integer name="width" value="99999999999"/>)"), kRender,
     "'99999999999' is not a valid integer"},
    {"NanRadius", sceneEdit(kRadius, R"(<float name="radius" value="nan"/>)"), kRender,
     "'nan' is not a valid number"},
    {"NanInColor",
     sceneEdit(R"(<rgb name="diffuseReflectance" value="0.5"/>)",
               R"(<rgb name="diffuseReflectance" value="0.5, NaN, 0.5"/>)"),
     kRender, "'NaN' is not a valid number"},
    {"InfinityInPoint", sceneEdit(R"(x="2" y="2" z="4")", R"(x="inf" y="2" z="4")"), kRender,
     "'inf' is not a valid number"},
    // Values out of range, and the limits that keep memory and time bounded
    {"NegativeRadius", sceneEdit(kRadius, R"(<float name="radius" value="-1"/>)"), kRender,
     "radius -1 is invalid (allowed: > 0)"},
    {"ZeroRadius", sceneEdit(kRadius, R"(<float name="radius" value="0"/>)"), kRender,
     "radius 0 is invalid"},
    {"FovOf180",
     sceneEdit(R"(<float name="fov" value="40"/>)", R"(<float name="fov" value="180"/>)"), kRender,
     "fov 180 is out of range"},
    {"FilmSideTooLarge", sceneEdit(kWidth, R"(<integer name="width" value="100000"/>)"), kRender,
     "width 100000 is out of range (allowed: 1 to 16384)"},
    {"FilmTooManyPixels",
     [](const fs::path& d) {
         writeText(d / "s.xml", scene({{kWidth, R"(<integer name="width" value="16384"/>)"},
                                       {R"(<integer name="height" value="8"/>)",
                                        R"(<integer name="height" value="16384"/>)"}}));
     },
     kRender, "pixels (allowed: up to 33554432"},
    {"SampleCountTooLarge",
     sceneEdit(R"(<integer name="sampleCount" value="1"/>)",
               R"(<integer name="sampleCount" value="5000000"/>)"),
     kRender, "sampleCount 5000000 is too large (allowed: up to 1048576"},
    {"PathDepthTooLarge",
     sceneEdit(R"(<integer name="maxDepth" value="3"/>)",
               R"(<integer name="maxDepth" value="100000"/>)"),
     kRender, "maxDepth 100000 is too large (allowed: up to 1000)"},
    {"RouletteDepthZero",
     sceneEdit(R"(<integer name="maxDepth" value="3"/>)", R"(<integer name="rrDepth" value="0"/>)"),
     kRender, "rrDepth 0 is invalid"},
    {"RouletteDepthTooLarge",
     sceneEdit(R"(<integer name="maxDepth" value="3"/>)",
               R"(<integer name="rrDepth" value="5000"/>)"),
     kRender, "rrDepth 5000 is too large"},
    {"SppFlagTooLarge", [](const fs::path& d) { writeText(d / "s.xml", kScene); },
     with(kRender, {"--spp", "2000000"}), "--spp", 105},
    {"MaxDepthFlagTooLarge", [](const fs::path& d) { writeText(d / "s.xml", kScene); },
     with(kRender, {"--max-depth", "5000"}), "--max-depth", 105},
    {"EnergyNotConserved",
     sceneEdit(R"(<rgb name="specularReflectance" value="0.2"/>)",
               R"(<rgb name="specularReflectance" value="0.9"/>)"),
     kRender, "exceeds 1"},
    {"NegativeReflectance",
     sceneEdit(R"(<rgb name="diffuseReflectance" value="0.5"/>)",
               R"(<rgb name="diffuseReflectance" value="-0.5"/>)"),
     kRender, "kd = -0.5 in channel R is invalid"},
    {"NegativeIntensity",
     sceneEdit(R"(<spectrum name="intensity" value="10"/>)",
               R"(<spectrum name="intensity" value="-10"/>)"),
     kRender, "intensity (-10, -10, -10) is negative"},
    // Degenerate and extreme transforms
    {"ScaleByZero", sceneEdit(kSphereRef, kSphereRef + toWorld(R"(<scale y="0"/>)")), kRender,
     "a scale factor of 0 collapses space"},
    {"RankDeficientMatrix",
     sceneEdit(kSphereRef,
               kSphereRef + toWorld(R"(<matrix value="1 0 0 0 0 1 0 0 1 1 0 0 0 0 0 1"/>)")),
     kRender, "the transform is degenerate"},
    {"MatrixNotAffine",
     sceneEdit(kSphereRef,
               kSphereRef + toWorld(R"(<matrix value="1 0 0 0 0 1 0 0 0 0 1 0 0 0 1 1"/>)")),
     kRender, "the last row is not 0 0 0 1"},
    {"RotationAboutZeroAxis",
     sceneEdit(kSphereRef, kSphereRef + toWorld(R"(<rotate angle="30"/>)")), kRender,
     "the rotation axis x, y, z is zero"},
    {"LookatOriginIsTarget", sceneEdit(kLookat, R"(<lookat origin="1, 1, 1" target="1, 1, 1"/>)"),
     kRender, "origin and target coincide"},
    {"LookatUpAlongView",
     sceneEdit(kLookat, R"(<lookat origin="0, 0, 5" target="0, 0, 0" up="0, 0, 1"/>)"), kRender,
     "up is zero or parallel"},
    {"NonUniformSphereScale",
     sceneEdit(kSphereRef, kSphereRef + toWorld(R"(<scale x="1" y="2" z="1"/>)")), kRender,
     "scales a sphere non-uniformly"},
    {"ShapeBeyondFloatRange",
     sceneEdit(kSphereRef, kSphereRef + toWorld(R"(<translate x="1e35"/>)")), kRender,
     "in world space (allowed: coordinates and sizes within +-1e+15"},
    // Inside float's range but beyond Embree's for a ray origin (it aborted on an assertion).
    {"ShapeBeyondEmbreeRange",
     sceneEdit(kSphereRef, kSphereRef + toWorld(R"(<translate x="1e20"/>)")), kRender,
     "the shape reaches 1e+20 in world space"},
    {"CameraBeyondFloatRange",
     sceneEdit(kLookat, R"(<lookat origin="0, 0, 1e35" target="0, 0, 0" up="0, 1, 0"/>)"), kRender,
     "the camera is placed beyond"},
    // References and variables
    {"UnknownReference", sceneEdit(kSphereRef, R"(<ref id="nope"/>)"), kRender,
     "no object with id 'nope' is defined above"},
    {"ForwardReference",
     [](const fs::path& d) {
         std::string s = scene({{kSphereRef, R"(<ref id="late"/>)"}});
         s.insert(s.find("</scene>"), R"(<bsdf type="diffuse" id="late"/>)");
         writeText(d / "s.xml", s);
     },
     kRender, "no object with id 'late' is defined above"},
    {"ReferenceToAShape",
     sceneEdit(kShape, R"(<shape type="sphere" id="other"/>)" + kShape + R"(<ref id="other"/>)"),
     kRender, "'other' is a shape"},
    {"RecursiveReference",
     sceneEdit(R"(<bsdf type="phong" id="ball">)",
               R"(<bsdf type="phong" id="ball"><ref id="ball"/>)"),
     kRender, "unknown element in <bsdf>"},
    {"RecursiveVariables",
     sceneEdit(
         R"(<scene version="0.6.0">)",
         R"(<scene version="0.6.0"><default name="a" value="$b"/><default name="b" value="$a"/>)"),
     kRender, "undefined variable '$b'"},
    {"SelfReferencingVariable",
     sceneEdit(R"(<scene version="0.6.0">)",
               R"(<scene version="0.6.0"><default name="a" value="x$a"/>)"),
     kRender, "undefined variable '$a'"},
    {"VariableExpansionBomb",
     [](const fs::path& d) {
         // Each default holds 16 of the one before: 16^8 * 8 characters if expanded.
         std::string defaults = R"(<default name="v0" value="12345678"/>)";
         for (int k = 1; k <= 8; ++k) {
             std::string value;
             for (int r = 0; r < 16; ++r) value += "$v" + std::to_string(k - 1);
             defaults += "<default name=\"v" + std::to_string(k) + "\" value=\"" + value + "\"/>";
         }
         writeText(
             d / "s.xml",
             scene({{R"(<scene version="0.6.0">)", R"(<scene version="0.6.0">)" + defaults}}));
     },
     kRender, "expand to over 1 MiB of text (allowed: up to 1048576 characters)"},
    {"UndefinedVariable", sceneEdit(kRadius, R"(<float name="radius" value="$r"/>)"), kRender,
     "undefined variable '$r'"},
    {"DuplicateId", sceneEdit(kShape, R"(<bsdf type="diffuse" id="ball"/>)" + kShape), kRender,
     "duplicate id 'ball'"},
    {"BadDefineName", [](const fs::path& d) { writeText(d / "s.xml", kScene); },
     with(kRender, {"-D", "a-b=3"}), "'a-b' is not a valid variable name"},
    // Meshes
    {"EmptyMesh", objScene("v 0 0 0\nv 1 0 0\nv 0 1 0\n"), kRender, "has no valid triangles"},
    {"CommentOnlyMesh", objScene("# nothing here\n"), kRender, "has no valid triangles"},
    {"MeshIndexOutOfRange", objScene("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 5\n"), kRender,
     "vertex index 5 is out of range"},
    {"MeshZeroNormal", objScene("v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 0\nf 1//1 2//1 3//1\n"), kRender,
     "normal 1 is zero or not finite"},
    {"MeshMissing",
     [](const fs::path& d) {
         writeText(d / "s.xml",
                   scene({{kShape, R"(<shape type="obj"><string name="filename" value="no.obj"/>)"},
                          {kRadius, ""}}));
     },
     kRender, "no.obj' does not exist or is not a file"},
    {"MeshTooLarge",
     [](const fs::path& d) {
         objScene("")(d);
         fs::resize_file(d / "m.obj", std::uintmax_t(600) << 20);  // sparse: no disk used
     },
     kRender, "is 600 MiB (allowed: up to 512 MiB)"},
    // Unreadable paths
    {"SceneFileTooLarge",
     [](const fs::path& d) {
         writeText(d / "s.xml", kScene);
         fs::resize_file(d / "s.xml", std::uintmax_t(100) << 20);  // sparse: no disk used
     },
     kRender, "is 100 MiB (allowed: up to 64 MiB)"},
    {"SceneIsADirectory", [](const fs::path& d) { fs::create_directory(d / "s.xml"); }, kRender,
     "it is a directory"},
    {"SceneUnderAFile",
     [](const fs::path& d) { writeText(d / "f", ""); },
     {"render", "{d}/f/s.xml", "-o", "{d}/out.exr"},
     "Not a directory"},
    {"SceneDanglingLink",
     [](const fs::path& d) { fs::create_symlink(d / "gone.xml", d / "s.xml"); }, kRender,
     "No such file or directory"},
    {"OutputDirectoryMissing",
     [](const fs::path& d) { writeText(d / "s.xml", kScene); },
     {"render", "{d}/s.xml", "-o", "{d}/no/such/out.exr"},
     "does not exist"},
    // An EXR under another format's name, which that format's readers (fit's PFM reader) refuse.
    {"OutputNamedAsAnotherFormat",
     [](const fs::path& d) { writeText(d / "s.xml", kScene); },
     {"render", "{d}/s.xml", "-o", "{d}/out.PFM"},
     "out.PFM': the image is written as OpenEXR, which a '.pfm' file would not hold; name it .exr"},
    {"OutputIsADirectory",
     [](const fs::path& d) {
         writeText(d / "s.xml", kScene);
         fs::create_directory(d / "out.exr");
     },
     {"render", "{d}/s.xml", "-o", "{d}/out.exr", "--quiet"},
     "out.exr"},
    // Images and masks of a fit
    {"ExrMissingChannel",
     [](const fs::path& d) {
         fitInputs(d);
         writeExrChannels(d / "i.exr", {"R", "G"}, kSize, kSize, 0.25f);
     },
     kFit, "has channels [G, R]; phongfit needs R, G and B"},
    {"ExrTruncated",
     [](const fs::path& d) {
         fitInputs(d);
         fs::resize_file(d / "i.exr", fs::file_size(d / "i.exr") / 2);
     },
     kFit, "cannot read EXR image"},
    {"ExrClaimsHugeSize",
     [](const fs::path& d) {
         fitInputs(d);
         writeExrClaimingSize(d / "i.exr", 100000);
     },
     kFit, "is 100000x100000 pixels (allowed: up to"},
    {"ExrWithNan",
     [](const fs::path& d) {
         fitInputs(d);
         writeExrChannels(d / "i.exr", {"R", "G", "B"}, kSize, kSize, 0.25f, true);
     },
     kFit, "pixel (3, 0) is not finite"},
    {"ImageOfWrongSize",
     [](const fs::path& d) {
         fitInputs(d);
         writeExrChannels(d / "i.exr", {"R", "G", "B"}, kSize + 1, kSize, 0.25f);
     },
     kFit, "image is 9x8 but the film"},
    {"ZeroSizePng",
     [](const fs::path& d) {
         fitInputs(d);
         writeZeroSizePng(d / "i.png");
     },
     fitView("{d}/s.xml:{d}/i.png", {}), "i.png"},
    {"GarbagePng",
     [](const fs::path& d) {
         fitInputs(d);
         writeText(d / "i.png", "this is not a picture");
     },
     fitView("{d}/s.xml:{d}/i.png", {}), "not a valid image file"},
    {"ImageUnknownExtension",
     [](const fs::path& d) {
         fitInputs(d);
         writeText(d / "i.bmp", "BM");
     },
     fitView("{d}/s.xml:{d}/i.bmp", {}), "unknown extension '.bmp'"},
    {"ImageIsADirectory",
     [](const fs::path& d) {
         fitInputs(d);
         fs::create_directory(d / "dir.exr");
     },
     fitView("{d}/s.xml:{d}/dir.exr", {}), "dir.exr': no such file"},
    {"Mask8BitWrongSize",
     [](const fs::path& d) {
         fitInputs(d);
         writeMask(d / "m.png", kSize, kSize / 2, CV_8U, 255);
     },
     with(kFit, {"--mask", "{d}/m.png"}), "is 8x4 but the image is 8x8"},
    {"Mask16BitWrongSize",
     [](const fs::path& d) {
         fitInputs(d);
         writeMask(d / "m.png", kSize / 2, kSize, CV_16U, 65535);
     },
     with(kFit, {"--mask", "{d}/m.png"}), "is 4x8 but the image is 8x8"},
    {"Mask16BitAllZero",
     [](const fs::path& d) {
         fitInputs(d);
         writeMask(d / "m.png", kSize, kSize, CV_16U, 0);
     },
     with(kFit, {"--mask", "{d}/m.png"}), "every pixel is masked"},
    {"MaskFloatTiffNamedPng",
     [](const fs::path& d) {
         fitInputs(d);
         writeMask(d / "m.tiff", kSize, kSize, CV_32F, 1);
         fs::rename(d / "m.tiff", d / "m.png");
     },
     with(kFit, {"--mask", "{d}/m.png"}), "allowed are 8- or 16-bit PNGs"},
    {"MaskNotPng",
     [](const fs::path& d) {
         fitInputs(d);
         writeMask(d / "m.jpg", kSize, kSize, CV_8U, 255);
     },
     with(kFit, {"--mask", "{d}/m.jpg"}), "masks must be PNG files"},
    {"FitSceneMissing", fitInputs, fitView("{d}/none.xml:{d}/i.exr", {}), "none.xml"},
    {"FitRecordingTooLarge",
     [](const fs::path& d) {
         // 2000x2000 pixels at 4096 paths each: hundreds of GB, refused before recording.
         writeText(d / "s.xml", scene({{kWidth, R"(<integer name="width" value="2000"/>)"},
                                       {R"(<integer name="height" value="8"/>)",
                                        R"(<integer name="height" value="2000"/>)"}}));
         writeExrChannels(d / "i.exr", {"R", "G", "B"}, 2000, 2000, 0.25f);
     },
     with(kFit, {"--spp", "4096", "--rounds", "1"}), "lower --spp"},
    // Photometric-stereo captures
    {"CaptureFileMissing",
     [](const fs::path& d) {
         capture()(d);
         fs::remove(d / "cap" / "light_intensities.txt");
     },
     kCapture, "light_intensities.txt' (a capture folder holds"},
    {"CaptureCountsDisagree", capture("light_directions.txt", "0 0 1\n0 0 1\n0 0 1\n"), kCapture,
     "the light counts disagree"},
    {"CaptureWordInNumbers", capture("light_directions.txt", "0 0 1\n0 zero 1\n"), kCapture,
     "light_directions.txt:2: '0 zero 1' is not three finite numbers"},
    {"CaptureNanDirection", capture("light_directions.txt", "nan 0 1\n0 0 1\n"), kCapture,
     "light_directions.txt:1: 'nan 0 1' is not three finite numbers"},
    {"CaptureDirectionNotUnit", capture("light_directions.txt", "0 0 1\n0 0 3\n"), kCapture,
     "has length 3"},
    {"CaptureZeroIntensity", capture("light_intensities.txt", "1 1 1\n0 1 1\n"), kCapture,
     "must be > 0 in every channel"},
    {"CaptureNormalNotUnit",
     [](const fs::path& d) {
         capture()(d);
         Image normals(kSize, kSize);
         for (int y = 0; y < kSize; ++y)
             for (int x = 0; x < kSize; ++x) normals.set(x, y, Color<float>(0, 0, 2));
         writeExr(normals, (d / "cap" / "normals.exr").string());
     },
     kCapture, "has length 2"},
    {"CaptureMaskWrongSize",
     [](const fs::path& d) {
         capture()(d);
         writeMask(d / "cap" / "mask.png", kSize, kSize / 2, CV_8U, 255);
     },
     kCapture, "is 8x4 but the image is 8x8"},
    {"CaptureBlackImage",
     [](const fs::path& d) {
         capture()(d);
         cv::imwrite((d / "cap" / "2.png").string(),
                     cv::Mat(kSize, kSize, CV_16UC3, cv::Scalar(0)));
     },
     kCapture, "is black everywhere inside the mask"},
    {"CaptureLightListBeyondCount", capture(), with(kCapture, {"--lights", "1-5"}),
     "light 5 does not exist"},
};

class MalformedInput : public ::testing::TestWithParam<Case> {
protected:
    void SetUp() override {
        dir_ = fs::temp_directory_path() / ("phongfit_malformed_" + std::to_string(getpid()) + "_" +
                                            std::to_string(std::random_device{}()));
        fs::create_directories(dir_);
    }
    void TearDown() override { fs::remove_all(dir_); }

    std::set<std::string> listing() const {
        std::set<std::string> names;
        for (const auto& e : fs::recursive_directory_iterator(dir_))
            names.insert(fs::relative(e.path(), dir_).string());
        return names;
    }

    fs::path dir_;
};

TEST_P(MalformedInput, RefusedWithOneLineAndNothingWritten) {
    const Case& c = GetParam();
    c.prepare(dir_);
    const std::set<std::string> before = listing();
    std::vector<std::string> args;
    for (std::string a : c.args) {
        for (std::size_t at; (at = a.find("{d}")) != std::string::npos;)
            a.replace(at, 3, dir_.string());
        args.push_back(a);
    }
    const test::ProcessResult r = test::runPhongfit(args);
    EXPECT_EQ(r.exitCode, c.exitCode) << r.err;
    EXPECT_NE(r.err.find(c.fragment), std::string::npos)
        << "expected '" << c.fragment << "' in: " << r.err;
    // One line from phongfit. libpng prints its own complaints before it (OpenCV installs no
    // handler for them); those are tolerated, nothing else is.
    std::istringstream lines(r.err);
    int ours = 0;
    for (std::string line; std::getline(lines, line);) ours += !line.starts_with("libpng ");
    EXPECT_EQ(ours, 1) << r.err;
    EXPECT_EQ(listing(), before) << "an output or temporary was left behind";
}

TEST(MalformedInputTable, HasAtLeastFortyCasesWithDistinctNames) {
    std::set<std::string> names;
    for (const Case& c : kCases) names.insert(c.name);
    EXPECT_EQ(names.size(), kCases.size());
    EXPECT_GE(kCases.size(), 40u);
}

INSTANTIATE_TEST_SUITE_P(Table, MalformedInput, ::testing::ValuesIn(kCases),
                         [](const ::testing::TestParamInfo<Case>& info) {
                             return info.param.name;
                         });

}  // namespace
}  // namespace phongfit
