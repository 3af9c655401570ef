// phongfit hdr-merge IMAGES... --times T1,T2,... -o OUT.exr: a bracketed set of LDR photographs
// with an unknown camera response merged to one linear HDR image (Debevec & Malik 1997, through
// OpenCV's CalibrateDebevec and MergeDebevec), ready for `fit --capture`.
#include <fmt/format.h>

#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "commands.h"
#include "error.h"
#include "hdr_merge.h"
#include "image.h"

namespace phongfit {
namespace {

struct HdrMergeArgs {
    std::vector<std::string> images;
    std::vector<double> times;
    std::string output;
};

void runHdrMerge(const HdrMergeArgs& args) {
    if (std::filesystem::path(args.output).extension() != ".exr")
        throw Error(fmt::format("-o '{}': the merged image is written as EXR (.exr)", args.output));
    const Image image = mergeExposures(args.images, args.times);
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
