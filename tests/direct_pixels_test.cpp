// The pixels a scene fit uses: those that see a fitted material directly, through their footprint
// (Renderer::bsdfSeen, leaveOutIndirectPixels in scene_fit.cpp), and recordings that trace no
// path in the pixels the fit leaves out (RecordOptions::recorded).
#include <gtest/gtest.h>
#include <unistd.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <numeric>
#include <opencv2/imgcodecs.hpp>
#include <string>
#include <tuple>

#include "error.h"
#include "error_of.h"
#include "image.h"
#include "render_to_exr.h"
#include "renderer.h"
#include "scene_fit.h"
#include "scene_parser.h"

namespace phongfit {
namespace {

const std::string kCornell = std::string(PHONGFIT_SCENES_DIR) + "/cornell_area.xml";

// The Cornell box's phong sphere (centre (-0.3, -0.6, 0.1), radius 0.4) seen from (0, 0, 3.9)
// towards the origin, fov 40 degrees, square film: whether the ray through a pixel's centre
// meets it, computed here from the scene's numbers.
bool centreRayMeetsTheSphere(int x, int y, int size) {
    const double t = std::tan(20.0 * M_PI / 180.0);
    const Eigen::Vector3d origin(0, 0, 3.9), centre(-0.3, -0.6, 0.1);
    const Eigen::Vector3d d =
        Eigen::Vector3d((2 * (x + 0.5) / size - 1) * t, (1 - 2 * (y + 0.5) / size) * t, -1)
            .normalized();
    const Eigen::Vector3d oc = origin - centre;
    const double b = d.dot(oc);
    return b * b - (oc.squaredNorm() - 0.16) > 0;
}

// A recording of the Cornell box's sphere at its scene parameters.
RecordOptions sphereRecording(const Renderer& renderer, int spp, int directSpp) {
    RecordOptions options;
    options.spp = spp;
    options.directSpp = directSpp;
    options.fittedBsdfs = {renderer.scene().findBsdf("sphere")};
    options.theta0 = {renderer.scene().bsdfs[std::size_t(options.fittedBsdfs[0])].params};
    return options;
}

TEST(BsdfSeen, IsTheRayThroughEachPixelsCentreMeetingTheMaterial) {
    const int size = 64;
    const Renderer renderer(
        loadScene(kCornell, {{"width", std::to_string(size)}, {"height", std::to_string(size)}}));
    const std::vector<int> bsdfs = renderer.bsdfSeen(2);
    const std::vector<std::uint8_t> seen = seesAny(bsdfs, {renderer.scene().findBsdf("sphere")});
    ASSERT_EQ(seen.size(), std::size_t(size * size));
    int count = 0, differ = 0;
    for (int y = 0; y < size; ++y)
        for (int x = 0; x < size; ++x) {
            count += seen[std::size_t(y * size + x)];
            differ += bool(seen[std::size_t(y * size + x)]) != centreRayMeetsTheSphere(x, y, size);
        }
    EXPECT_GT(count, 200);
    EXPECT_LE(differ, 2);  // a centre within rounding of the outline, at most
    // No bsdf: seen nowhere. Each pixel names a bsdf of the scene (or -1): the walls' too.
    const std::vector<std::uint8_t> none = seesAny(bsdfs, {});
    EXPECT_EQ(std::count(none.begin(), none.end(), 1), 0);
    for (int b : bsdfs) ASSERT_TRUE(b >= -1 && b < int(renderer.scene().bsdfs.size())) << b;
    for (const char* wall : {"white", "red", "green"})
        EXPECT_GT(std::count(bsdfs.begin(), bsdfs.end(), renderer.scene().findBsdf(wall)), 200)
            << wall;
}

// Pixel p of set a and pixel q of set b hold the same paths: background, terms and vertices,
// the first difference reported. Returns the number of terms compared.
std::uint32_t expectSamePixelPaths(const PathSet& a, std::size_t p, const PathSet& b,
                                   std::size_t q) {
    EXPECT_TRUE((a.background[p] == b.background[q]).all()) << "pixel " << p;
    const std::uint32_t terms = a.pixelStart[p + 1] - a.pixelStart[p];
    if (terms != b.pixelStart[q + 1] - b.pixelStart[q]) {
        ADD_FAILURE() << "pixel " << p << ": " << terms << " terms against "
                      << b.pixelStart[q + 1] - b.pixelStart[q];
        return 0;
    }
    for (std::uint32_t k = 0; k < terms; ++k) {
        const PathTerm &s = a.terms[a.pixelStart[p] + k], &t = b.terms[b.pixelStart[q] + k];
        bool same =
            (s.constant == t.constant).all() && t.pixel == q && s.vertexCount == t.vertexCount;
        for (std::uint32_t v = 0; same && v < s.vertexCount; ++v)
            same = a.vertices[s.firstVertex + v].logCos == b.vertices[t.firstVertex + v].logCos &&
                   a.vertices[s.firstVertex + v].slot == b.vertices[t.firstVertex + v].slot;
        if (!same) {
            ADD_FAILURE() << "pixel " << p << ", term " << k << " differs";
            return 0;
        }
    }
    return terms;
}

TEST(Recording, PixelsLeftOutRecordNoPathAndTheOthersTheSamePaths) {
    const Renderer renderer(loadScene(kCornell, {{"width", "24"}, {"height", "24"}}));
    RecordOptions options = sphereRecording(renderer, 3, 0);
    const PathSet all = renderer.record(options).paths;
    std::vector<std::uint8_t> recorded(24 * 24, 1);
    for (std::size_t p = 0; p < recorded.size(); p += 3) recorded[p] = 0;
    options.recorded = recorded;
    const PathSet some = renderer.record(options).paths;
    for (std::size_t p = 0; p < recorded.size(); ++p) {
        const std::uint32_t terms = some.pixelStart[p + 1] - some.pixelStart[p];
        if (!recorded[p]) {
            EXPECT_EQ(terms, 0u);
            EXPECT_TRUE((some.background[p] == 0.0f).all());
            EXPECT_EQ(some.pixelPaths.at(p), 0u);
            continue;
        }
        expectSamePixelPaths(all, p, some, p);
    }
    options.recorded = std::span(recorded).first(5);
    EXPECT_EQ(test::errorOf([&] { renderer.record(options); }),
              "record: 5 pixel flags given for a 24x24 film");
    options.recorded = {};
    options.extraPaths.assign(24 * 24 - 1, 1);
    EXPECT_EQ(test::errorOf([&] { renderer.record(options); }),
              "record: 575 extra path counts given for a 24x24 film, each >= 0");
    options.extraPaths.assign(24 * 24, 1);
    options.extraPaths[7] = -1;
    EXPECT_EQ(test::errorOf([&] { renderer.record(options); }),
              "record: 576 extra path counts given for a 24x24 film, each >= 0");
}

// directSpp's pixels, given (the fit's map from load time) or found by the recording itself: the
// same paths. A map of the wrong size is refused.
TEST(Recording, DirectPixelsGivenOrFoundRecordTheSamePaths) {
    const Renderer renderer(loadScene(kCornell, {{"width", "20"}, {"height", "20"}}));
    RecordOptions options = sphereRecording(renderer, 1, 5);
    const PathSet found = renderer.record(options).paths;
    const std::vector<std::uint8_t> direct = seesAny(renderer.bsdfSeen(1), options.fittedBsdfs);
    options.direct = direct;
    const PathSet given = renderer.record(options).paths;
    EXPECT_EQ(found.pixelPaths, given.pixelPaths);
    EXPECT_EQ(found.pixelStart, given.pixelStart);
    for (std::size_t p = 0; p < direct.size(); ++p)
        EXPECT_EQ(given.pixelPaths[p], direct[p] ? 5u : 1u) << "pixel " << p;
    EXPECT_GT(std::count(direct.begin(), direct.end(), 1), 10);
    options.direct = std::span(direct).first(7);
    EXPECT_EQ(test::errorOf([&] { renderer.record(options); }),
              "record: 7 direct-pixel flags given for a 20x20 film");
}

// A window of the film records, pixel for pixel, the paths the whole film records there; the
// set is the window's size. A window outside the film is refused.
TEST(Recording, AWindowRecordsTheWholeFilmsPathsInItsPixels) {
    const Renderer renderer(loadScene(kCornell, {{"width", "40"}, {"height", "36"}}));
    RecordOptions options = sphereRecording(renderer, 2, 6);
    const PathSet all = renderer.record(options).paths;
    const FilmWindow w{7, 5, 19, 23};
    options.window = w;
    const PathSet part = renderer.record(options).paths;
    ASSERT_EQ(part.width, w.width);
    ASSERT_EQ(part.height, w.height);
    ASSERT_EQ(part.pixelStart.size(), w.pixels() + 1);
    std::size_t terms = 0;
    for (int y = 0; y < w.height; ++y)
        for (int x = 0; x < w.width; ++x) {
            const std::size_t q = std::size_t(y * w.width + x),
                              p = std::size_t((y + w.y0) * 40 + x + w.x0);
            if (!all.pixelPaths.empty()) {
                EXPECT_EQ(part.pixelPaths.at(q), all.pixelPaths[p]);
            }
            terms += expectSamePixelPaths(all, p, part, q);
        }
    EXPECT_GT(terms, 500u);
    options.window = {30, 0, 11, 36};
    EXPECT_THROW(renderer.record(options), Error);
    options.window = {-1, 0, 10, 10};
    EXPECT_THROW(renderer.record(options), Error);
}

// The bounding window of a pixel mask, and crops of film-sized arrays.
TEST(FilmWindow, BoundsTheFlaggedPixelsAndCropsToThem) {
    std::vector<std::uint8_t> flags(6 * 5, 0);
    flags[1 * 6 + 2] = flags[3 * 6 + 4] = 1;
    const FilmWindow w = boundingWindow(flags, 6, 5);
    EXPECT_EQ(w.x0, 2);
    EXPECT_EQ(w.y0, 1);
    EXPECT_EQ(w.width, 3);
    EXPECT_EQ(w.height, 3);
    // The same pixels listed, in any order: the same window, and one pixel's own.
    const FilmWindow listed = boundingWindow(std::vector<std::uint32_t>{3 * 6 + 4, 1 * 6 + 2}, 6);
    EXPECT_EQ(std::tie(listed.x0, listed.y0, listed.width, listed.height),
              std::tie(w.x0, w.y0, w.width, w.height));
    const FilmWindow single = boundingWindow(std::vector<std::uint32_t>{4 * 6 + 5}, 6);
    EXPECT_EQ(std::tie(single.x0, single.y0, single.width, single.height),
              std::make_tuple(5, 4, 1, 1));
    const FilmWindow wide = widened(w, 2, 6, 5);  // clipped by the film on three sides
    EXPECT_EQ(wide.x0, 0);
    EXPECT_EQ(wide.y0, 0);
    EXPECT_EQ(wide.width, 6);
    EXPECT_EQ(wide.height, 5);
    const FilmWindow one = widened(w, 1, 6, 5);
    EXPECT_EQ(one.x0, 1);
    EXPECT_EQ(one.width, 5);
    EXPECT_EQ(one.height, 5);
    const FilmWindow none = boundingWindow(std::vector<std::uint8_t>(30, 0), 6, 5);
    EXPECT_EQ(none.width, 6);
    EXPECT_EQ(none.height, 5);
    std::vector<int> rgb(6 * 5 * 3);
    std::iota(rgb.begin(), rgb.end(), 0);
    const std::vector<int> c = cropped(rgb, 6, w, 3);
    ASSERT_EQ(c.size(), 27u);
    EXPECT_EQ(c[0], (1 * 6 + 2) * 3);
    EXPECT_EQ(c[26], (3 * 6 + 4) * 3 + 2);
}

class SceneFitPixels : public ::testing::Test {
protected:
    void SetUp() override {
        image_ = std::filesystem::temp_directory_path() /
                 ("phongfit_direct_pixels_" + std::to_string(::getpid()) + ".exr");
        test::renderToExr(kCornell, defines_, 2, image_.string());
    }
    void TearDown() override {
        std::filesystem::remove(image_);
        std::filesystem::remove(mask_);
    }
    SceneFitInputs inputs() const {
        SceneFitInputs in;
        in.views = {{kCornell, image_.string()}};
        in.materials = {"sphere"};
        in.defines = defines_;
        return in;
    }

    const std::map<std::string, std::string> defines_ = {{"width", "48"}, {"height", "48"}};
    std::filesystem::path image_,
        mask_ = std::filesystem::temp_directory_path() /
                ("phongfit_direct_mask_" + std::to_string(::getpid()) + ".png");
};

// Kept: the pixels within one pixel (the box filter's reach) of one whose centre sees the sphere.
TEST_F(SceneFitPixels, PixelsThatSeeTheMaterialOnlyIndirectlyAreLeftOut) {
    const SceneFitProblem problem = loadSceneFit(inputs());
    const SceneView& v = problem.views[0];
    const std::vector<std::uint8_t> seen = seesAny(v.renderer->bsdfSeen(1), v.fittedBsdfs);
    EXPECT_EQ(v.direct, seen);
    std::size_t kept = 0;
    for (int y = 0; y < 48; ++y)
        for (int x = 0; x < 48; ++x) {
            bool near = false;
            for (int dy = -1; dy <= 1; ++dy)
                for (int dx = -1; dx <= 1; ++dx)
                    near = near || (x + dx >= 0 && x + dx < 48 && y + dy >= 0 && y + dy < 48 &&
                                    seen[std::size_t((y + dy) * 48 + x + dx)]);
            EXPECT_EQ(bool(v.observation.valid[std::size_t(y * 48 + x)]), near) << x << ", " << y;
            kept += near;
        }
    EXPECT_GT(kept, 100u);
    EXPECT_EQ(v.offMaterials, 48u * 48u - kept);

    SceneFitInputs in = inputs();
    in.keepIndirect = true;
    const SceneFitProblem all = loadSceneFit(in);
    EXPECT_EQ(all.views[0].offMaterials, 0u);
    EXPECT_EQ(
        std::count(all.views[0].observation.valid.begin(), all.views[0].observation.valid.end(), 1),
        48 * 48);
}

// A fitted material seen directly by no pixel left in (here masked out): nothing else is left
// out, what the other pixels show of it is all there is.
TEST_F(SceneFitPixels, AMaterialSeenOnlyIndirectlyKeepsEveryPixel) {
    cv::Mat mask(48, 48, CV_8U, cv::Scalar(255));
    for (int y = 0; y < 48; ++y)
        for (int x = 0; x < 48; ++x)
            for (int dy = -1; dy <= 1; ++dy)
                for (int dx = -1; dx <= 1; ++dx)
                    if (centreRayMeetsTheSphere(x + dx, y + dy, 48))
                        mask.at<std::uint8_t>(y, x) = 0;
    ASSERT_TRUE(cv::imwrite(mask_.string(), mask));
    SceneFitInputs in = inputs();
    in.maskPath = mask_.string();
    const SceneFitProblem problem = loadSceneFit(in);
    EXPECT_EQ(problem.views[0].offMaterials, 0u);
    EXPECT_EQ(problem.views[0].masked, std::size_t(48 * 48 - cv::countNonZero(mask)));
}

}  // namespace
}  // namespace phongfit
