// phongfit hdr-merge IMAGES... --times T1,T2,... -o OUT.exr: a bracketed set of LDR photographs
// with an unknown camera response merged to one linear HDR image (Debevec & Malik 1997, through
// OpenCV's CalibrateDebevec and MergeDebevec), ready for `fit --capture`.
#include <fmt/format.h>

#include <cmath>
#include <filesystem>
#include <memory>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/photo.hpp>
#include <string>
#include <vector>

#include "commands.h"
#include "error.h"
#include "image.h"
#include "image_limits.h"

namespace phongfit {
namespace {

struct HdrMergeArgs {
    std::vector<std::string> images;
    std::vector<double> times;
    std::string output;
};

// An 8-bit exposure as 3-channel BGR, as CalibrateDebevec needs.
cv::Mat readExposure(const std::string& path) {
    std::error_code ec;
    if (!std::filesystem::is_regular_file(path, ec))
        throw Error(fmt::format("cannot read image '{}': no such file", path));
    requireLdrWithinLimits(path, "image");
    cv::Mat mat;
    try {
        mat = cv::imread(path, cv::IMREAD_UNCHANGED);
    } catch (const cv::Exception& e) {
        throw Error(fmt::format("cannot read image '{}': {}", path, e.what()));
    }
    if (mat.empty())
        throw Error(fmt::format("cannot read image '{}': not a valid image file", path));
    if (mat.depth() != CV_8U)
        throw Error(
            fmt::format("image '{}' is not 8-bit: hdr-merge calibrates the response of "
                        "8-bit (LDR) exposures; higher bit depths are usually linear "
                        "already",
                        path));
    cv::Mat bgr;
    if (mat.channels() == 1)
        cv::cvtColor(mat, bgr, cv::COLOR_GRAY2BGR);
    else if (mat.channels() == 4)
        cv::cvtColor(mat, bgr, cv::COLOR_BGRA2BGR);
    else
        bgr = mat;
    return bgr;
}

void runHdrMerge(const HdrMergeArgs& args) {
    if (args.images.size() < 2)
        throw Error(
            fmt::format("hdr-merge needs at least two exposures ({} given)", args.images.size()));
    if (args.times.size() != args.images.size())
        throw Error(
            fmt::format("--times has {} values for {} images (one exposure time per "
                        "image, in the same order)",
                        args.times.size(), args.images.size()));
    for (std::size_t i = 0; i < args.times.size(); ++i)
        if (!(args.times[i] > 0) || !std::isfinite(args.times[i]))
            throw Error(fmt::format("--times: {} (of image '{}') must be a finite number > 0",
                                    args.times[i], args.images[i]));
    if (std::filesystem::path(args.output).extension() != ".exr")
        throw Error(fmt::format("-o '{}': the merged image is written as EXR (.exr)", args.output));

    std::vector<cv::Mat> exposures;
    for (const std::string& path : args.images) {
        exposures.push_back(readExposure(path));
        const cv::Mat& first = exposures.front();
        const cv::Mat& last = exposures.back();
        if (last.size() != first.size())
            throw Error(fmt::format(
                "image '{}' is {}x{} but '{}' is {}x{} (exposures must be "
                "the same size)",
                path, last.cols, last.rows, args.images.front(), first.cols, first.rows));
    }
    std::vector<float> times(args.times.begin(), args.times.end());
    cv::Mat response, hdr;
    try {
        cv::createCalibrateDebevec()->process(exposures, response, times);
        cv::createMergeDebevec()->process(exposures, hdr, times, response);
    } catch (const cv::Exception& e) {
        throw Error(fmt::format("hdr-merge failed in OpenCV: {}", e.what()));
    }
    Image image(hdr.cols, hdr.rows);
    for (int y = 0; y < hdr.rows; ++y)
        for (int x = 0; x < hdr.cols; ++x) {
            const cv::Vec3f bgr = hdr.at<cv::Vec3f>(y, x);
            image.set(x, y, Color<float>(bgr[2], bgr[1], bgr[0]));
        }
    writeExr(image, args.output);
    fmt::print("merged {} exposures into {} ({}x{}, linear, up to one scale factor)\n",
               args.images.size(), args.output, image.width, image.height);
}

}  // namespace

void addHdrMergeCommand(CLI::App& app) {
    auto args = std::make_shared<HdrMergeArgs>();
    CLI::App* cmd = app.add_subcommand(
        "hdr-merge", "merge bracketed 8-bit exposures (unknown response) into a linear EXR");
    cmd->add_option("images", args->images, "the exposures, 8-bit PNG/JPEG/TIFF")->required();
    cmd->add_option("--times", args->times, "exposure times in seconds, T1,T2,... (one per image)")
        ->delimiter(',')
        ->required();
    cmd->add_option("-o,--output", args->output, "the merged image, .exr")->required();
    cmd->callback([args] { runHdrMerge(*args); });
}

}  // namespace phongfit
