// `phongfit slurm synth|bench-fit`: a Slurm job array whose task I runs the command as shard I of
// N (datasets_synth/shard.h). The sbatch script is written beside the output (OUTPUT.slurm/) for
// users to read, edit and resubmit; a resubmitted array redoes only what is not complete.
#pragma once

#include <functional>
#include <string>
#include <vector>

namespace phongfit {

struct SlurmJob {
    std::string command;                 // "synth" or "bench fit"
    std::vector<std::string> arguments;  // the command's own, as given (no --shard)
    std::string output;                  // the command's -o
    int tasks = 1;
    std::string partition, time, memory;  // sbatch --partition, --time, --mem; empty: Slurm's
    int cpusPerTask = 0;                  // 0: Slurm's default; else also the command's --threads
};

// OUTPUT.slurm: the script, <command>.sbatch, and the tasks' logs, logs/<job>_<task>.out.
std::string slurmFolder(const SlurmJob& job);
std::string slurmScriptPath(const SlurmJob& job);

// The sbatch script: #SBATCH lines, then `executable COMMAND ARGUMENTS --shard $TASK/N` run in
// `workingDirectory` (where relative paths in the arguments were meant). Throws Error for a
// partition, time or memory that is not a plain Slurm value.
std::string sbatchScript(const SlurmJob& job, const std::string& executable,
                         const std::string& workingDirectory);

struct SlurmSubmission {
    std::string jobId;
    int exitCode = 0;  // of sbatch; with wait, non-zero when a task failed
};

// Writes the script and the logs folder and runs `sbatch [--wait] --parsable SCRIPT`, calling
// `submitted(jobId)` as soon as Slurm has the job (before waiting). Throws Error when sbatch cannot
// be run or refuses the job.
SlurmSubmission submitSlurmJob(const SlurmJob& job, const std::string& script, bool wait,
                               const std::function<void(const std::string&)>& submitted);

}  // namespace phongfit
