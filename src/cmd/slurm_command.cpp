// phongfit slurm synth|bench-fit [--tasks N] [--partition P] [--time T] [--mem M]
//   [--cpus-per-task C] [--wait] [--dry-run] ARGUMENTS...
// ARGUMENTS are those of `phongfit synth` or `phongfit bench fit`, checked here by their own
// parser before anything is submitted.
#include <fmt/format.h>

#include <algorithm>
#include <filesystem>

#include "atomic_file.h"
#include "bench_fit.h"
#include "commands.h"
#include "error.h"
#include "slurm_job.h"
#include "synth.h"
#include "synth_config.h"
#include "synth_dataset.h"

namespace phongfit {
namespace {

namespace fs = std::filesystem;

struct SlurmArgs {
    SlurmJob job;
    bool wait = false, dryRun = false;
};

// Parses the job's arguments with the command's own parser (parse only), fills job.output and
// checks the config or dataset they name.
void checkArguments(SlurmJob& job) {
    CLI::App probe;
    CLI::App* command = nullptr;
    std::vector<std::string> words;
    if (job.command == "synth") {
        addSynthCommand(probe, true);
        command = probe.get_subcommand("synth");
        words = {"synth"};
    } else {
        addBenchCommand(probe, true);
        command = probe.get_subcommand("bench")->get_subcommand("fit");
        words = {"bench", "fit"};
    }
    words.insert(words.end(), job.arguments.begin(), job.arguments.end());
    std::reverse(words.begin(), words.end());  // CLI11 takes a vector last word first
    try {
        probe.parse(words);
    } catch (const CLI::ParseError& e) {
        throw Error(fmt::format("{}: {}", job.command, e.what()));
    }
    for (const char* option : {"--shard", "--merge"})
        if (command->count(option) > 0)
            throw Error(
                fmt::format("{} is set by phongfit slurm (one shard per array task)", option));
    const std::string input = job.command == "synth" ? "config" : "dataset";
    if (command->count(input) == 0 || command->count("--output") == 0)
        throw Error(fmt::format("slurm {} needs {} and -o DIR", job.command,
                                job.command == "synth" ? "CONFIG" : "DATASET"));
    job.output = command->get_option("--output")->as<std::string>();
    requireOutputDirectory(job.output);
    const std::string path = command->get_option(input)->as<std::string>();
    if (job.command == "synth")
        loadSynthConfig(path);
    else
        readDataset(path);
}

void runSlurmCommand(SlurmArgs& args) {
    checkArguments(args.job);
    const std::string script = sbatchScript(args.job, fs::read_symlink("/proc/self/exe").string(),
                                            fs::current_path().string());
    if (args.dryRun) {
        fmt::print("{}", script);
        return;
    }
    const std::string logs = (fs::path(slurmFolder(args.job)) / "logs").string();
    const SlurmSubmission s =
        submitSlurmJob(args.job, script, args.wait, [&](const std::string& id) {
            fmt::print("slurm: submitted job {} ({} tasks) from {}; logs in {}{}\n", id,
                       args.job.tasks, slurmScriptPath(args.job), logs,
                       args.wait ? "; waiting" : "");
            std::fflush(stdout);
        });
    if (!args.wait) {
        fmt::print(
            "slurm: the last task to finish writes the merged results into {} (or run "
            "phongfit {} --merge {})\n",
            args.job.output, args.job.command == "synth" ? "synth" : "bench fit", args.job.output);
        return;
    }
    if (s.exitCode != 0)
        throw Error(fmt::format(
            "Slurm job {}: a task failed or was cancelled (sbatch --wait exit {}): see {}; "
            "submit again with sbatch {} (finished work is kept)",
            s.jobId, s.exitCode, logs, slurmScriptPath(args.job)));
    // Every task succeeded: the merged results exist, or are made now.
    if (args.job.command == "synth") {
        const SynthSummary m = mergeSynth(args.job.output);
        fmt::print("slurm: job {} done: {} samples -> {}\n", s.jobId, m.datasetTotal,
                   (fs::path(args.job.output) / "index.json").string());
    } else {
        mergeBenchFit(args.job.output, args.job.cpusPerTask);
        fmt::print("slurm: job {} done\n", s.jobId);
    }
}

void addSlurmSubcommand(CLI::App* slurm, const std::string& name, const std::string& what) {
    auto args = std::make_shared<SlurmArgs>();
    args->job.command = name;
    CLI::App* cmd = slurm->add_subcommand(
        name, fmt::format("{} as a Slurm job array: every option not listed here is {}'s", what,
                          name == "synth" ? "synth" : "bench fit"));
    cmd->allow_extras();
    cmd->add_option("--tasks", args->job.tasks, "array tasks: shard I of N runs as task I")
        ->check(CLI::Range(1, kMaxShards))
        ->required();
    cmd->add_option("--partition", args->job.partition, "sbatch --partition");
    cmd->add_option("--time", args->job.time, "sbatch --time (per task), e.g. 1:00:00");
    cmd->add_option("--mem", args->job.memory, "sbatch --mem (per task), e.g. 4G");
    cmd->add_option("--cpus-per-task", args->job.cpusPerTask,
                    "sbatch --cpus-per-task, and the command's --threads")
        ->check(CLI::Range(1, 1024));
    cmd->add_flag("--wait", args->wait,
                  "wait for every task (sbatch --wait), then merge and print the results");
    cmd->add_flag("--dry-run", args->dryRun, "print the sbatch script; submit nothing");
    cmd->callback([cmd, args] {
        args->job.arguments = cmd->remaining();
        runSlurmCommand(*args);
    });
}

}  // namespace

void addSlurmCommand(CLI::App& app) {
    CLI::App* slurm = app.add_subcommand(
        "slurm",
        "run synth or bench fit as a Slurm job array (sbatch script written beside the output)");
    slurm->require_subcommand(1);
    addSlurmSubcommand(slurm, "synth", "render a synthetic dataset");
    addSlurmSubcommand(slurm, "bench-fit", "fit every sample of a dataset (bench fit)");
}

}  // namespace phongfit
