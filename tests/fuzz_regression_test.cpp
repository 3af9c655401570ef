// Inputs found by the fuzzers of fuzz/ (scripts/fuzz.sh) that crashed phongfit, kept as regular
// cases once fixed. Each case names the target that found it.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <opencv2/imgcodecs.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "error.h"
#include "error_of.h"
#include "image.h"
#include "obj_mesh.h"
#include "subprocess.h"
#include "temp_dir.h"

namespace phongfit {
namespace {

using test::errorOf;

// png_fuzz: a file named .png holding a broken PNG header, and "DICM" at byte 128. OpenCV picks
// its decoder by content, chose GDCM (DICOM), and GDCM's reader failed an assertion: the process
// aborted. Now only PNG, JPEG and TIFF content reaches OpenCV (only PNG for masks).
const std::string kDicomNamedPng = [] {
    const unsigned char bytes[] = {
        0xff, 0x4f, 0x89, 0x50, 0x4e, 0x47, 0x0d, 0x49, 0x48, 0x44, 0x52, 0x00, 0x00, 0x00, 0x03,
        0x00, 0x00, 0x00, 0x02, 0x10, 0x02, 0x00, 0x00, 0x00, 0x42, 0x86, 0x2d, 0x0e, 0x00, 0x00,
        0x00, 0x1f, 0xff, 0x51, 0x22, 0x49, 0x44, 0x54, 0x41, 0x60, 0x60, 0x9c, 0x78, 0x63, 0x60,
        0x7e, 0xc1, 0x7e, 0x81, 0x7b, 0x07, 0xff, 0x5d, 0xe1, 0x0e, 0xf1, 0x02, 0xe9, 0x08, 0x79,
        0x07, 0x86, 0xff, 0x18, 0x0a, 0x1a, 0x0a, 0x00, 0x00, 0x00, 0x0d, 0x49, 0x48, 0x44, 0x52,
        0x00, 0x00, 0x00, 0x07, 0x00, 0x00, 0x00, 0x02, 0x10, 0x02, 0x00, 0x00, 0x00, 0x00, 0x42,
        0x86, 0x2d, 0x0e, 0x00, 0x00, 0x00, 0x1f, 0x49, 0x44, 0x41, 0x54, 0x78, 0x9c, 0x63, 0x60,
        0xe7, 0xe7, 0xe7, 0x00, 0x00, 0x60, 0x60, 0x7e, 0xc1, 0x02, 0x00, 0x00, 0x00, 0x42, 0x86,
        0x2d, 0x0e, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x44, 0x49, 0x43, 0x4d, 0x41};
    return std::string(reinterpret_cast<const char*>(bytes), sizeof bytes);
}();

TEST(PngFuzz, DicomContentNamedPngIsAnErrorNotAnAbort) {
    const test::TempDir dir("fuzz_regression");
    const std::string path = dir.write("dicm.png", kDicomNamedPng).string();
    const std::string image = errorOf([&] { readImage(path); });
    EXPECT_NE(image.find("cannot read image '" + path + "': not a valid image file"),
              std::string::npos)
        << image;
    EXPECT_NE(image.find("PNG, JPEG or TIFF"), std::string::npos) << image;
    const std::string mask = errorOf([&] { readMask(path, 3, 2); });
    EXPECT_NE(mask.find("cannot read mask '" + path + "'"), std::string::npos) << mask;
    EXPECT_NE(mask.find("allowed are 8- or 16-bit PNGs"), std::string::npos) << mask;
}

// The same file given to hdr-merge, which reads its exposures with OpenCV too: one line, exit 1.
TEST(PngFuzz, DicomContentIsRefusedByHdrMerge) {
    const test::TempDir dir("fuzz_regression");
    const std::string good = dir.at("good.png");
    ASSERT_TRUE(cv::imwrite(good, cv::Mat(2, 3, CV_8UC3, cv::Scalar(10, 20, 30))));
    const std::string bad = dir.write("dicm.png", kDicomNamedPng).string();
    const test::ProcessResult r =
        test::runPhongfit({"hdr-merge", good, bad, "--times", "1,2", "-o", dir.at("merged.exr")});
    EXPECT_EQ(r.signal, 0) << r.err;
    EXPECT_EQ(r.exitCode, 1) << r.err;
    EXPECT_NE(r.err.find("'" + bad + "': not a valid image file"), std::string::npos) << r.err;
    EXPECT_FALSE(std::filesystem::exists(dir.at("merged.exr")));
}

// The check that keeps other decoders away must still let every format readImage promises in,
// whatever the name says (OpenCV decodes by content): PNG, JPEG and TIFF.
TEST(PngFuzz, PngJpegAndTiffContentAreStillRead) {
    const test::TempDir dir("fuzz_regression");
    const cv::Mat grey(2, 3, CV_8UC3, cv::Scalar(128, 128, 128));
    for (const std::string name : {"a.png", "a.jpg", "a.tiff"}) {
        ASSERT_TRUE(cv::imwrite(dir.at(name), grey)) << name;
        const Image image = readImage(dir.at(name));
        EXPECT_EQ(image.width, 3) << name;
        EXPECT_EQ(image.height, 2) << name;
    }
    // A PNG named .jpg is still a PNG to OpenCV; a TIFF named .png is no mask.
    std::filesystem::copy_file(dir.at("a.png"), dir.at("png.jpg"));
    EXPECT_EQ(readImage(dir.at("png.jpg")).width, 3);
    std::filesystem::copy_file(dir.at("a.tiff"), dir.at("tiff.png"));
    EXPECT_NE(
        errorOf([&] { readMask(dir.at("tiff.png"), 3, 2); }).find("allowed are 8- or 16-bit PNGs"),
        std::string::npos);
    EXPECT_EQ(readMask(dir.at("a.png"), 3, 2).size(), 6u);
}

// obj_mesh_fuzz: a normal of finite floats near 1e37. Its squared length, in float, overflowed to
// infinity and normalising gave a zero normal. Lengths are taken in double now, which also keeps
// normals near 1e-30, whose float square was 0 and which were refused as zero.
TEST(ObjMeshFuzz, HugeAndTinyNormalsAreNormalised) {
    for (const char* normal : {"vn 0 7.7e37 -1", "vn 1e-30 2e-30 0"}) {
        std::istringstream in(std::string("v 0 0 0\nv 1 0 0\nv 0 1 0\n") + normal +
                              "\nf 1//1 2//1 3//1\n");
        const TriangleMesh mesh = readObjMesh(in, "fuzz.obj", "test");
        ASSERT_EQ(mesh.normals.size(), 3u) << normal;
        for (const auto& n : mesh.normals) {
            EXPECT_TRUE(n.allFinite()) << normal;
            EXPECT_NEAR(n.norm(), 1, 1e-6) << normal;
        }
    }
    std::istringstream zero("v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 0\nf 1//1 2//1 3//1\n");
    EXPECT_NE(errorOf([&] { readObjMesh(zero, "fuzz.obj", "test"); }).find("normal 1 is zero"),
              std::string::npos);
}

// scene_render_fuzz: the camera of cornell_point.xml moved to z = 4.4e19. Finite in float and
// inside the old limit (1e30), but Embree asserts that a ray's origin lies within 1.8e18: the
// render aborted. Cameras and shapes must now stay within 1e15.
TEST(SceneRenderFuzz, CameraBeyondEmbreeRangeIsAnErrorNotAnAbort) {
    const test::TempDir dir("fuzz_regression");
    const std::string scene = dir.write("far.xml", R"(<scene version="0.6.0">
    <sensor type="perspective">
        <float name="fov" value="40"/>
        <transform name="toWorld">
            <lookat origin="0, 0, 44444444444444444443.9" target="0, 0, 0" up="0, 1, 0"/>
        </transform>
        <film type="hdrfilm">
            <integer name="width" value="4"/>
            <integer name="height" value="4"/>
        </film>
    </sensor>
    <emitter type="point">
        <point name="position" x="0.3" y="0.5" z="0.6"/>
    </emitter>
    <shape type="rectangle"/>
</scene>)")
                                  .string();
    const test::ProcessResult r =
        test::runPhongfit({"render", scene, "--spp", "1", "-o", dir.at("far.exr")});
    EXPECT_EQ(r.signal, 0) << r.err;
    EXPECT_EQ(r.exitCode, 1) << r.err;
    EXPECT_NE(r.err.find("the camera is placed beyond +-1e+15"), std::string::npos) << r.err;
    EXPECT_FALSE(std::filesystem::exists(dir.at("far.exr")));
}

// Found by the fuzzers once the header limits (image_limits.h) were in; the inputs are kept in
// tests/data/fuzz/ and as fuzz seeds.
std::string fuzzInput(const std::string& name) {
    return std::string(PHONGFIT_TEST_DATA_DIR) + "/fuzz/" + name;
}

// scene_render_fuzz (session 76): the Cornell box with its right wall turned by 91 degrees and
// its light moved down. Embree's high-quality build (spatial splits) asserted on the bounds of a
// split of these ten triangles, and the render aborted; scenes are built at medium quality now.
TEST(SceneRenderFuzz, WallsEmbreesSpatialSplitsAssertedOnRender) {
    const test::TempDir dir("fuzz_regression");
    const test::ProcessResult r = test::runPhongfit(
        {"render", fuzzInput("scene_spatial_split.xml"), "--spp", "1", "-o", dir.at("walls.exr")});
    EXPECT_EQ(r.signal, 0) << r.err;
    EXPECT_EQ(r.exitCode, 0) << r.err;
    const Image image = readImage(dir.at("walls.exr"));
    EXPECT_EQ(image.width, 4);
    EXPECT_TRUE(std::all_of(image.rgb.begin(), image.rgb.end(),
                            [](float v) { return std::isfinite(v) && v >= 0; }));
}

// exr_fuzz (a 10 s timeout under ASan, 1.2 GB resident without): dataWindow declared 59 bytes
// long. OpenEXRCore complained and read a 64 x 64 window; OpenEXR's InputFile read 16 of the 59
// bytes as a window of a million by five pixels and allocated for that. Any complaint of
// OpenEXRCore now refuses the file, and the two libraries' windows must agree.
TEST(ExrFuzz, AttributeOfTheWrongSizeIsRefusedBeforeOpenExrAllocates) {
    const std::string path = fuzzInput("exr_attribute_size_mismatch.exr");
    const std::string e = errorOf([&] { readImage(path); });
    EXPECT_NE(e.find("cannot read EXR image '" + path + "'"), std::string::npos) << e;
    EXPECT_NE(e.find("dataWindow"), std::string::npos) << e;
}

// png_fuzz (UBSan: signed overflow): a BigTIFF whose first directory offset is near 2^64.
TEST(PngFuzz, TiffDirectoryOffsetNearTwoToThe64IsRefused) {
    const std::string path = fuzzInput("tiff_offset_overflow.tif");
    const std::string e = errorOf([&] { readImage(path); });
    EXPECT_NE(e.find("a TIFF's first directory lies within the file"), std::string::npos) << e;
}

// png_fuzz (out of memory: 3.9 GB asked for): a 65532 x 3 LZW TIFF declaring 14851 rows per
// strip, for which OpenCV allocates a strip of 14851 rows at 4 bytes a pixel.
TEST(PngFuzz, TiffStripLongerThanItsImageIsRefusedBeforeOpenCvAllocates) {
    const std::string path = fuzzInput("tiff_rows_per_strip.tif");
    const std::string e = errorOf([&] { readImage(path); });
    EXPECT_NE(e.find("one strip decodes to"), std::string::npos) << e;
}

// png_fuzz in CI (out of memory: 3.9 GB asked for): the same strip, but the directory lists the
// width twice, 65532 and then 1; libtiff kept the first, the limit check read the last.
TEST(PngFuzz, TiffTagListedTwiceCountsAtItsLargest) {
    const std::string path = fuzzInput("tiff_duplicate_width.tif");
    const std::string e = errorOf([&] { readImage(path); });
    EXPECT_NE(e.find("one strip decodes to"), std::string::npos) << e;
}

// png_fuzz in CI (out of memory: 3.9 GB asked for): the same strip once more, its RowsPerStrip
// (14851) a signed short, a type the limit check skipped and libtiff reads.
TEST(PngFuzz, TiffTagOfASignedTypeIsRead) {
    const std::string path = fuzzInput("tiff_signed_rows_per_strip.tif");
    const std::string e = errorOf([&] { readImage(path); });
    EXPECT_NE(e.find("one strip decodes to"), std::string::npos) << e;
}

// exr_fuzz, an hour's run (timeouts under ASan; 1.2 to 1.7 GB asked for in release): a channel
// list whose entries run past its declared size. InputFile reads a channel list by its entries,
// OpenEXRCore by its size, so the two read the rest of the header differently (a data window of
// a million pixels, an attribute of 1.7 GB). Self-delimited attributes must now fill their size.
TEST(ExrFuzz, ChannelListRunningPastItsSizeIsRefused) {
    const std::string path = fuzzInput("exr_chlist_overrun.exr");
    const std::string e = errorOf([&] { readImage(path); });
    EXPECT_NE(e.find("an attribute's size disagrees with its contents"), std::string::npos) << e;
}

// exr_fuzz: a ZIP-compressed 33281 x 383 image in 437 bytes (260 MB allocated before the first
// chunk failed). Deflate cannot pack that many pixels into so few bytes.
TEST(ExrFuzz, ZipImageDenserThanDeflateCanPackIsRefused) {
    const std::string path = fuzzInput("exr_zip_dense.exr");
    const std::string e = errorOf([&] { readImage(path); });
    EXPECT_NE(e.find("is 33281x383 pixels in a file of 437 bytes (allowed: up to 1032 pixels a "
                     "byte"),
              std::string::npos)
        << e;
}

// png_fuzz: a Huffman-coded JPEG declaring 250 x 62979 pixels in 528 bytes (300 MB decoded from
// garbage; a timeout under ASan). Huffman coding takes a bit at least per 8 x 8 block.
TEST(PngFuzz, JpegDenserThanHuffmanCodingCanPackIsRefused) {
    const std::string path = fuzzInput("jpeg_dense.jpg");
    const std::string e = errorOf([&] { readImage(path); });
    EXPECT_NE(e.find("is 250x62979 pixels in a file of 528 bytes"), std::string::npos) << e;
}

}  // namespace
}  // namespace phongfit
