// The fit's memory (docs/design/fitter.md, "Memory"): beyond the images and the recorded paths, at
// most kStateBytesPerPixel a used pixel. Counted exactly: this executable replaces operator new
// and delete with ones that keep the bytes allocated and their peak.
#include <gtest/gtest.h>
#include <malloc.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <new>
#include <sstream>
#include <string>

#include "image.h"
#include "memory_info.h"
#include "memory_plan.h"
#include "render_to_exr.h"
#include "renderer.h"
#include "round_paths.h"
#include "scene_fit.h"
#include "scene_parser.h"

// AddressSanitizer's build: gcc says so with __SANITIZE_ADDRESS__, clang with __has_feature.
#if defined(__SANITIZE_ADDRESS__)
#define PHONGFIT_ADDRESS_SANITIZER 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define PHONGFIT_ADDRESS_SANITIZER 1
#endif
#endif

namespace {

std::atomic<std::int64_t> allocated{0}, peak{0};

void* counted(void* p) {
    if (p == nullptr) throw std::bad_alloc();
    const std::int64_t now = allocated.fetch_add(std::int64_t(malloc_usable_size(p))) +
                             std::int64_t(malloc_usable_size(p));
    std::int64_t seen = peak.load();
    while (now > seen && !peak.compare_exchange_weak(seen, now)) {
    }
    return p;
}

void released(void* p) {
    if (p == nullptr) return;
    allocated.fetch_sub(std::int64_t(malloc_usable_size(p)));
    std::free(p);
}

std::size_t aligned(std::size_t n, std::align_val_t a) {
    const std::size_t align = std::size_t(a);
    return (std::max<std::size_t>(n, 1) + align - 1) / align * align;
}

}  // namespace

void* operator new(std::size_t n) { return counted(std::malloc(std::max<std::size_t>(n, 1))); }
void* operator new[](std::size_t n) { return counted(std::malloc(std::max<std::size_t>(n, 1))); }
void* operator new(std::size_t n, std::align_val_t a) {
    return counted(std::aligned_alloc(std::size_t(a), aligned(n, a)));
}
void* operator new[](std::size_t n, std::align_val_t a) {
    return counted(std::aligned_alloc(std::size_t(a), aligned(n, a)));
}
// The nothrow forms too (std::stable_partition's temporary buffer): every form allocates here,
// so every delete frees what this file allocated.
void* operator new(std::size_t n, const std::nothrow_t&) noexcept {
    try {
        return operator new(n);
    } catch (...) {
        return nullptr;
    }
}
void* operator new[](std::size_t n, const std::nothrow_t&) noexcept {
    try {
        return operator new[](n);
    } catch (...) {
        return nullptr;
    }
}
void* operator new(std::size_t n, std::align_val_t a, const std::nothrow_t&) noexcept {
    try {
        return operator new(n, a);
    } catch (...) {
        return nullptr;
    }
}
void* operator new[](std::size_t n, std::align_val_t a, const std::nothrow_t&) noexcept {
    try {
        return operator new[](n, a);
    } catch (...) {
        return nullptr;
    }
}
void operator delete(void* p, const std::nothrow_t&) noexcept { released(p); }
void operator delete[](void* p, const std::nothrow_t&) noexcept { released(p); }
void operator delete(void* p, std::align_val_t, const std::nothrow_t&) noexcept { released(p); }
void operator delete[](void* p, std::align_val_t, const std::nothrow_t&) noexcept { released(p); }
void operator delete(void* p) noexcept { released(p); }
void operator delete[](void* p) noexcept { released(p); }
void operator delete(void* p, std::size_t) noexcept { released(p); }
void operator delete[](void* p, std::size_t) noexcept { released(p); }
void operator delete(void* p, std::align_val_t) noexcept { released(p); }
void operator delete[](void* p, std::align_val_t) noexcept { released(p); }
void operator delete(void* p, std::size_t, std::align_val_t) noexcept { released(p); }
void operator delete[](void* p, std::size_t, std::align_val_t) noexcept { released(p); }

namespace phongfit {
namespace {

const std::string kCornell = std::string(PHONGFIT_SCENES_DIR) + "/cornell_phong.xml";
const std::string kSpherePoint = std::string(PHONGFIT_SCENES_DIR) + "/sphere_point.xml";

struct FitState {
    double perUsedPixel;  // bytes the fit allocated at its peak beyond the problem and its paths
    std::size_t pixelsUsed;
};

// `scene` rendered at 16 paths a pixel with `defines`, fitted from kd 0.25, ks 0.45 and n `startN`
// for two rounds: what the fit allocates beyond the problem it was given and the paths of one
// round. With `imageSpp` -1 the fit knows the image's 16 paths and renders anew the pixels that
// hold a parameter (FitOptions::renderedNoise); 0 tells it the image has no noise.
FitState fitState(const std::string& scene, std::map<std::string, std::string> defines,
                  double startN, bool keepIndirect, int imageSpp = -1) {
    defines["spp"] = "16";
    const std::filesystem::path image =
        std::filesystem::temp_directory_path() /
        ("phongfit_fit_memory_" + std::to_string(::getpid()) + ".exr");
    test::renderToExr(scene, defines, 16, image.string());
    SceneFitInputs inputs;
    inputs.views = {{scene, image.string()}};
    inputs.materials = {"sphere"};
    inputs.defines = defines;
    inputs.kd = Color3::Constant(0.25);
    inputs.ks = Color3::Constant(0.45);
    inputs.n = startN;
    inputs.keepIndirect = keepIndirect;
    const SceneFitProblem problem = loadSceneFit(inputs);
    SceneRecording recording;
    recording.spp = 4;
    recording.imageSpp = imageSpp;
    FitOptions options;
    options.maxRounds = 2;
    const std::int64_t before = allocated.load();
    peak.store(before);
    const FitResult result = fitScene(problem, recording, options);
    const std::int64_t most = peak.load() - before;
    std::filesystem::remove(image);

    EXPECT_EQ(result.rounds.size(), 2u);
    std::size_t recorded = 0;
    for (const FitRound& r : result.rounds) recorded = std::max(recorded, r.recordedBytes);
    const double perPixel = double(most - std::int64_t(recorded)) / double(result.pixelsUsed);
    std::cout << "fit state: " << perPixel << " bytes a used pixel (" << result.pixelsUsed
              << " used) beyond " << recorded << " bytes of paths\n";
    return {perPixel, result.pixelsUsed};
}

// The Cornell demo at 320x320 from the demo's start.
FitState cornellFitState(bool keepIndirect) {
    return fitState(kCornell, {{"width", "320"}, {"height", "320"}}, 300, keepIndirect);
}

// Every pixel sees the sphere through some bounce: with the walls' pixels kept, all are used.
// 159.7 bytes a used pixel since the instruments are smoothed in place and released once a solve
// has read them (179.7 before, as each fit below was 20 higher): each fit's second bound fails if
// the solve holds a third array of instruments again.
TEST(FitMemory, StateBeyondImagesAndPathsIsAtMostTheBoundPerUsedPixel) {
    const FitState s = cornellFitState(true);
    EXPECT_GT(s.pixelsUsed, 80000u);
    EXPECT_LE(s.perUsedPixel, double(kStateBytesPerPixel));
    EXPECT_LE(s.perUsedPixel, 170.0);
}

// The walls' pixels left out (the default), the sphere's are a tenth of the film: the bound still
// holds per used pixel, as what the fit and its recordings hold per pixel covers the box around
// them (film_window.h), not the film: 170.5 bytes a used pixel beyond 2.9 MB of paths (190.5
// counted on session 70's and 71's builds). Over the whole film: 806 beyond 6.6 MB (the two sets'
// per-pixel arrays counted with the paths).
TEST(FitMemory, StateStaysWithinTheBoundWhenMostPixelsAreLeftOut) {
    const FitState s = cornellFitState(false);
    EXPECT_LT(s.pixelsUsed, 20000u);
    EXPECT_LE(s.perUsedPixel, double(kStateBytesPerPixel));
    EXPECT_LE(s.perUsedPixel, 180.0);
}

// A highlight smaller than a pixel (the point-lit sphere at n 30000, 160x160): a pixel or two hold
// ks and n, and the second round renders them anew 16 times. Each pixel is rendered alone, by the
// view's renderer, so the renders add nothing to the fit's peak: 201.8 bytes a used pixel beyond
// the paths with them and without (the image taken as noise-free, no pixel rendered anew). When
// each render copied the scene and filled a film of the view's size, the fit held 457.6 with them.
// 194.3 since the recording's spent importance is freed before the solve (200.4 with it held);
// 174.3 with the instruments smoothed in place.
TEST(FitMemory, PixelsRenderedAnewAddNothingToThePeak) {
    const std::map<std::string, std::string> defines = {
        {"width", "160"}, {"height", "160"}, {"n", "30000"}, {"ks", "0.1"}};
    const FitState rendered = fitState(kSpherePoint, defines, 3000, false);
    const FitState noiseless = fitState(kSpherePoint, defines, 3000, false, 0);
    EXPECT_GT(rendered.pixelsUsed, 5000u);
    EXPECT_EQ(rendered.pixelsUsed, noiseless.pixelsUsed);
    EXPECT_LE(rendered.perUsedPixel, noiseless.perUsedPixel + 1);
    EXPECT_LE(rendered.perUsedPixel, double(kStateBytesPerPixel));
    EXPECT_LE(rendered.perUsedPixel, 184.0);
}

// A recording's peak on the resident set (memory_info.h) stays near one copy of its paths: the set
// is filled tile by tile into pages not yet written (DefaultInitAllocator) while the tiles'
// records are handed back. Before, the set was zeroed whole while every record was held: 2.2
// times; then 1.4, the records' growth slack while tracing.
// How far the resident set rose while recording the Cornell box's sphere, in units of the paths
// recorded.
// A recording of `renderer` with `options`, and how far the resident set rose while it was made.
struct MeasuredRecording {
    std::vector<PathSet> sets;  // the one set, as recordedBytes takes them
    double rise;
};
MeasuredRecording measuredRecording(const Renderer& renderer, const RecordOptions& options) {
    mapLargeBuffers();  // as main: freed big buffers leave the resident set
    malloc_trim(0);
    const std::size_t before = residentBytes();
    resetPeakResident();
    RecordResult r = renderer.record(options);
    const double rise = double(peakResidentBytes() - before);
    MeasuredRecording out{{}, rise};
    out.sets.push_back(std::move(r.paths));
    return out;
}

double recordingPeak(int size, int spp) {
    const Renderer renderer(
        loadScene(kCornell, {{"width", std::to_string(size)}, {"height", std::to_string(size)}}));
    RecordOptions options;
    options.spp = spp;
    options.fittedBsdfs = {renderer.scene().findBsdf("sphere")};
    options.theta0 = {renderer.scene().bsdfs[std::size_t(options.fittedBsdfs[0])].params};
    const MeasuredRecording m = measuredRecording(renderer, options);
    const PathSet& set = m.sets[0];
    const std::size_t bytes =
        set.terms.size() * sizeof(PathTerm) + set.vertices.size() * sizeof(PathVertex);
    EXPECT_GT(bytes, std::size_t(20) << 20);
    std::cout << size << "x" << size << " at " << spp << " paths a pixel: the recording's peak "
              << m.rise / double(bytes) << " times its " << bytes << " bytes of paths\n";
    return m.rise / double(bytes);
}

// Few tiles with big records (40x40 film, 9 tiles): 2.22 times the paths before the set was
// filled in tile order, 1.39-1.44 after, 1.16 with records in blocks copied and handed back block
// by block (block_array.h): a vector's doubling and a tile held twice while copied are gone. 1.02
// with each record copied pixel by pixel (PathSetFilm::copyRecord), no longer a partly written page
// of the set open for each of a tile's pixels.
TEST(RecordingMemory, PeakIsAboutOneCopyOfThePaths) {
#if defined(PHONGFIT_ADDRESS_SANITIZER)
    GTEST_SKIP() << "AddressSanitizer keeps freed memory in quarantine: the resident set measures "
                    "its allocator, not the recording";
#endif
    EXPECT_LT(recordingPeak(40, 2048), 1.06);
}

// Many tiles with small records growing side by side (256x256, 256 tiles): 1.42 times the paths
// while the records came from the heap, 1.11 mapped (mapped_allocator.h), 1.12 in blocks, 1.08
// copied pixel by pixel; most of what is left is the film's per-pixel arrays (60 bytes a pixel).
TEST(RecordingMemory, ManySmallTileRecordsLeaveNoSlack) {
#if defined(PHONGFIT_ADDRESS_SANITIZER)
    GTEST_SKIP() << "AddressSanitizer keeps freed memory in quarantine: the resident set measures "
                    "its allocator, not the recording";
#endif
    EXPECT_LT(recordingPeak(256, 128), 1.10);
}

// How far the resident set rose while a ringed recording was made (sphere_quad.xml at 256x256:
// direct light alone, the quad light by rings, every pixel taking paths beyond those ringed),
// beyond its path set, per pixel that takes paths: every pixel of the film, or its left half
// alone (`recorded`).
double ringedFilmBytes(bool leftHalf) {
    const Renderer renderer(loadScene(std::string(PHONGFIT_SCENES_DIR) + "/sphere_quad.xml",
                                      {{"width", "256"}, {"height", "256"}}));
    const std::size_t pixels = 256 * 256;
    std::vector<std::uint8_t> recorded(pixels, 1);
    if (leftHalf)
        for (std::size_t p = 0; p < pixels; ++p) recorded[p] = p % 256 < 128;
    RecordOptions options;
    options.spp = 4;
    options.extraPaths.assign(pixels, 4);
    options.recorded = recorded;
    options.fittedBsdfs = {renderer.scene().findBsdf("sphere")};
    options.theta0 = {renderer.scene().bsdfs[std::size_t(options.fittedBsdfs[0])].params};
    const MeasuredRecording m = measuredRecording(renderer, options);
    EXPECT_FALSE(m.sets[0].groups.empty());  // ringed and sampled paths weighted
    const double setBytes = double(recordedBytes(m.sets));
    const double perPixel = (m.rise - setBytes) / (leftHalf ? double(pixels) / 2 : double(pixels));
    std::cout << (leftHalf ? "left half" : "whole film") << ": " << perPixel
              << " bytes a traced pixel beyond the " << setBytes << " bytes of the set\n";
    return perPixel;
}

// A fit's window holds pixels it does not record (left out, or around the ones it uses): the
// ringed film's sums are kept for the traced pixels alone, and handed back row by row as the
// weights are made (PathSetFilm::weigh). Before, the film held 80 bytes of ringed sums, 24 of
// background and 16 of factors for every pixel of the window at once: 150-151 bytes a traced pixel
// over the whole film, 275-280 over its left half; then 117-125 and 108-111; with the ringed sums
// packed in 72 bytes (path_set_film.h), 116-119 and 101-107. (In fits: the sphere cells under
// area lights peaked at 207-209 bytes a used pixel beyond their paths, the quad-light
// sphere at 256-266; now 178-179 and 185-186.)
TEST(RecordingMemory, RingedFilmHoldsItsSumsForTracedPixelsAlone) {
#if defined(PHONGFIT_ADDRESS_SANITIZER)
    GTEST_SKIP() << "AddressSanitizer keeps freed memory in quarantine: the resident set measures "
                    "its allocator, not the recording";
#endif
    const double whole = ringedFilmBytes(false), half = ringedFilmBytes(true);
    EXPECT_LT(whole, 135.0);
    EXPECT_LT(half, 1.5 * whole);
}

// The program's own pages made resident before a fit measures its start (residentProgram): before,
// the demo's first round counted 1.2-1.4 MB of code it first ran against the fit (421 bytes a used
// pixel where its data took 158). Every readable mapping of the executable is then resident whole.
TEST(ResidentSet, TheProgramsOwnPagesAreResidentWhenAsked) {
    residentProgram();
    const std::string exe = std::filesystem::read_symlink("/proc/self/exe").string();
    std::ifstream smaps("/proc/self/smaps");
    std::string line, path;
    std::size_t mappings = 0, size = 0;
    bool readable = false;
    while (std::getline(smaps, line)) {
        std::istringstream fields(line);
        std::string first, second;
        fields >> first >> second;
        if (first.find('-') != std::string::npos && first.back() != ':') {  // a mapping's header
            std::string offset, device, inode;
            fields >> offset >> device >> inode;
            path.clear();  // an anonymous mapping names no file
            std::getline(fields >> std::ws, path);
            readable = second.size() == 4 && second[0] == 'r';
        } else if (first == "Size:" && path == exe && readable) {
            size = std::stoull(second);
        } else if (first == "Rss:" && path == exe && readable) {
            EXPECT_EQ(std::stoull(second), size) << exe << " has pages not resident";
            ++mappings;
        }
    }
    EXPECT_GE(mappings, 2u);  // its code and its constant data at least
}

}  // namespace
}  // namespace phongfit
