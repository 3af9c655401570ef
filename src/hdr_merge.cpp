#include "hdr_merge.h"

#include <fmt/format.h>

#include <cmath>
#include <filesystem>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/photo.hpp>

#include "error.h"
#include "image_limits.h"

namespace phongfit {
namespace {

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

}  // namespace

Image mergeExposures(const std::vector<std::string>& images, const std::vector<double>& seconds) {
    if (images.size() < 2)
        throw Error(
            fmt::format("hdr-merge needs at least two exposures ({} given)", images.size()));
    if (seconds.size() != images.size())
        throw Error(
            fmt::format("--times has {} values for {} images (one exposure time per "
                        "image, in the same order)",
                        seconds.size(), images.size()));
    for (std::size_t i = 0; i < seconds.size(); ++i)
        if (!(seconds[i] > 0) || !std::isfinite(seconds[i]))
            throw Error(fmt::format("--times: {} (of image '{}') must be a finite number > 0",
                                    seconds[i], images[i]));
    std::vector<cv::Mat> exposures;
    for (const std::string& path : images) {
        exposures.push_back(readExposure(path));
        const cv::Mat& first = exposures.front();
        const cv::Mat& last = exposures.back();
        if (last.size() != first.size())
            throw Error(
                fmt::format("image '{}' is {}x{} but '{}' is {}x{} (exposures must be "
                            "the same size)",
                            path, last.cols, last.rows, images.front(), first.cols, first.rows));
    }
    const std::vector<float> times(seconds.begin(), seconds.end());
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
    return image;
}

}  // namespace phongfit
