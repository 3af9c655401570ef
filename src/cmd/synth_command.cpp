// phongfit synth CONFIG.json -o DIR [--jobs J] [--quiet]
#include <fmt/format.h>

#include <filesystem>

#include "commands.h"
#include "error.h"
#include "synth.h"
#include "synth_config.h"

namespace phongfit {
namespace {

struct SynthArgs {
    std::string config;
    SynthOptions options;
};

void runSynthCommand(const SynthArgs& args) {
    const SynthConfig config = loadSynthConfig(args.config);
    const SynthSummary s = runSynth(config, args.options);
    const std::string done =
        fmt::format("{} rendered, {} already complete", s.rendered, s.alreadyComplete);
    if (s.interrupted)
        throw Error(
            fmt::format("interrupted: {} of {} samples complete in {} ({}); run the same "
                        "command again to resume",
                        s.rendered + s.alreadyComplete, s.total, args.options.output, done));
    fmt::print("synth: {} samples ({}) in {:.2f} s -> {}\n", s.total, done, s.seconds,
               (std::filesystem::path(args.options.output) / "index.json").string());
}

}  // namespace

void addSynthCommand(CLI::App& app) {
    auto args = std::make_shared<SynthArgs>();
    CLI::App* cmd =
        app.add_subcommand("synth",
                           "render a synthetic dataset of Phong materials with known parameters "
                           "(datasets_synth/README.md); rerun to resume an interrupted run");
    cmd->add_option("config", args->config, "dataset config (JSON)")->required();
    cmd->add_option("-o,--output", args->options.output, "dataset directory")->required();
    cmd->add_option("--jobs", args->options.jobs,
                    "samples rendered at once (they share the hardware threads)")
        ->check(CLI::Range(1, 256))
        ->capture_default_str();
    cmd->add_flag("--quiet", args->options.quiet, "no progress output");
    cmd->callback([args] { runSynthCommand(*args); });
}

}  // namespace phongfit
