// phongfit synth CONFIG.json -o DIR [--jobs J] [--threads T] [--shard I/N] [--quiet]
// phongfit synth --merge DIR
#include <fmt/format.h>

#include <filesystem>
#include <optional>

#include "commands.h"
#include "error.h"
#include "synth.h"
#include "synth_config.h"

namespace phongfit {
namespace {

struct SynthArgs {
    std::string config, merge;
    std::optional<std::string> shard;
    SynthOptions options;
};

// "synth: 4 samples (4 rendered, 0 already complete) in 1.20 s -> DIR/index.json", and for a shard
// how far the whole dataset is.
void printSummary(const SynthSummary& s, const std::string& dir, const Shard& shard) {
    const std::string index = (std::filesystem::path(dir) / "index.json").string();
    const std::string done =
        fmt::format("{}{} samples ({} rendered, {} already complete) in {:.2f} s",
                    shard.whole() ? "" : fmt::format("shard {}: ", shard.text()), s.total,
                    s.rendered, s.alreadyComplete, s.seconds);
    if (s.indexWritten)
        fmt::print("synth: {} -> {}\n", done, index);
    else
        fmt::print(
            "synth: {}; {} of the dataset's {} samples are complete: {} is written by the shard "
            "that completes them, or by phongfit synth --merge {}\n",
            done, s.datasetComplete, s.datasetTotal, index, dir);
}

void runSynthCommand(const SynthArgs& args) {
    if (!args.merge.empty()) {
        if (!args.config.empty() || !args.options.output.empty() || args.shard)
            throw Error(
                "--merge DIR takes no CONFIG, -o or --shard: it only writes DIR/index.json");
        printSummary(mergeSynth(args.merge), args.merge, Shard{});
        return;
    }
    if (args.config.empty() || args.options.output.empty())
        throw Error("synth needs CONFIG and -o DIR (or --merge DIR)");
    SynthOptions options = args.options;
    options.shard = chooseShard(args.shard);
    const SynthConfig config = loadSynthConfig(args.config);
    const SynthSummary s = runSynth(config, options);
    const std::string done =
        fmt::format("{} rendered, {} already complete", s.rendered, s.alreadyComplete);
    if (s.interrupted)
        throw Error(fmt::format(
            "interrupted: {} of {} samples{} complete in {} ({}); run the same command again to "
            "resume",
            s.rendered + s.alreadyComplete, s.total,
            options.shard.whole() ? "" : " of shard " + options.shard.text(), options.output,
            done));
    printSummary(s, options.output, options.shard);
}

}  // namespace

void addSynthCommand(CLI::App& app, bool parseOnly) {
    auto args = std::make_shared<SynthArgs>();
    CLI::App* cmd =
        app.add_subcommand("synth",
                           "render a synthetic dataset of Phong materials with known parameters "
                           "(datasets_synth/README.md); rerun to resume an interrupted run");
    cmd->add_option("config", args->config, "dataset config (JSON)");
    cmd->add_option("-o,--output", args->options.output, "dataset directory");
    cmd->add_option("--jobs", args->options.jobs,
                    "samples rendered at once (they share the threads)")
        ->check(CLI::Range(1, 256))
        ->capture_default_str();
    cmd->add_option("--threads", args->options.threads, "render threads in all (default: all)")
        ->check(CLI::Range(1, 1024));
    cmd->add_option("--shard", args->shard,
                    "render only shard I of N (from 0): the samples k with k mod N = I; default "
                    "from SLURM_ARRAY_TASK_ID and SLURM_ARRAY_TASK_COUNT in a Slurm array job");
    cmd->add_option("--merge", args->merge,
                    "write DIR/index.json once every shard's samples are complete");
    cmd->add_flag("--quiet", args->options.quiet, "no progress output");
    cmd->callback([args, parseOnly] {
        if (!parseOnly) runSynthCommand(*args);
    });
}

}  // namespace phongfit
