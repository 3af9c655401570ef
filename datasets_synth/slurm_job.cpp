#include "slurm_job.h"

#include <fmt/format.h>
#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <regex>

#include "error.h"
#include "json_files.h"

namespace phongfit {
namespace {

namespace fs = std::filesystem;

std::string shellQuote(const std::string& s) {
    if (!s.empty() && std::regex_match(s, std::regex("[A-Za-z0-9_./=:,+@%-]+"))) return s;
    std::string quoted = "'";
    for (const char c : s) quoted += c == '\'' ? std::string("'\\''") : std::string(1, c);
    return quoted + "'";
}

// A value for an #SBATCH line: what Slurm's partition names, times and sizes are made of.
std::string sbatchValue(const std::string& value, const char* option) {
    if (!std::regex_match(value, std::regex("[A-Za-z0-9_.:,+-]+")))
        throw Error(fmt::format(
            "{} '{}': expected a plain Slurm value (letters, digits, _ . : , + -)", option, value));
    return value;
}

std::string commandWords(const SlurmJob& job) {
    return job.command == "synth" ? "synth" : "bench fit";
}

}  // namespace

std::string slurmFolder(const SlurmJob& job) {
    fs::path out = fs::absolute(job.output).lexically_normal();
    if (out.filename().empty()) out = out.parent_path();
    return out.string() + ".slurm";
}

std::string slurmScriptPath(const SlurmJob& job) {
    return (fs::path(slurmFolder(job)) /
            (job.command == "synth" ? "synth.sbatch" : "bench-fit.sbatch"))
        .string();
}

std::string sbatchScript(const SlurmJob& job, const std::string& executable,
                         const std::string& workingDirectory) {
    std::string words = shellQuote(executable) + " " + commandWords(job);
    for (const std::string& a : job.arguments) words += fmt::format(" {}", shellQuote(a));
    bool hasThreads = false;
    for (const std::string& a : job.arguments)
        hasThreads = hasThreads || a.rfind("--threads", 0) == 0;
    if (job.cpusPerTask > 0 && !hasThreads) words += fmt::format(" --threads {}", job.cpusPerTask);
    std::string s = fmt::format(
        "#!/bin/bash\n"
        "# Written by phongfit slurm: task I of this array runs `phongfit {}` as shard I of {}.\n"
        "# Submit it again to finish what a failed or cancelled task left (finished work is\n"
        "# kept): sbatch {}\n"
        "# The last task to finish writes the merged results, or: phongfit {} --merge {}\n"
        "#SBATCH --job-name=phongfit-{}\n"
        "#SBATCH --array=0-{}\n"
        "#SBATCH --output={}/logs/%A_%a.out\n"
        "#SBATCH --chdir={}\n",
        commandWords(job), job.tasks, shellQuote(slurmScriptPath(job)), commandWords(job),
        shellQuote(job.output), job.command, job.tasks - 1, slurmFolder(job), workingDirectory);
    if (!job.partition.empty())
        s += fmt::format("#SBATCH --partition={}\n", sbatchValue(job.partition, "--partition"));
    if (!job.time.empty()) s += fmt::format("#SBATCH --time={}\n", sbatchValue(job.time, "--time"));
    if (!job.memory.empty())
        s += fmt::format("#SBATCH --mem={}\n", sbatchValue(job.memory, "--mem"));
    if (job.cpusPerTask > 0) s += fmt::format("#SBATCH --cpus-per-task={}\n", job.cpusPerTask);
    s += fmt::format("set -euo pipefail\nexec {} --shard \"${{SLURM_ARRAY_TASK_ID}}/{}\"\n", words,
                     job.tasks);
    return s;
}

SlurmSubmission submitSlurmJob(const SlurmJob& job, const std::string& script, bool wait,
                               const std::function<void(const std::string&)>& submitted) {
    fs::create_directories(fs::path(slurmFolder(job)) / "logs");
    const std::string path = slurmScriptPath(job);
    writeTextAtomically(path, script);
    fs::permissions(path, fs::perms::owner_exec | fs::perms::group_exec, fs::perm_options::add);
    const std::string command =
        fmt::format("sbatch --parsable{} {} 2>&1", wait ? " --wait" : "", shellQuote(path));
    std::fflush(stdout);
    FILE* pipe = ::popen(command.c_str(), "r");
    if (!pipe) throw Error(fmt::format("cannot run '{}'", command));
    SlurmSubmission result;
    std::string said;
    std::array<char, 512> buffer{};
    const std::regex idLine("([0-9]+)(;.*)?\\s*");
    while (std::fgets(buffer.data(), int(buffer.size()), pipe)) {
        const std::string line = buffer.data();
        std::smatch id;
        if (result.jobId.empty() && std::regex_match(line, id, idLine)) {
            result.jobId = id[1];
            submitted(result.jobId);
        } else {
            said += line;
        }
    }
    const int status = ::pclose(pipe);
    result.exitCode = WIFEXITED(status) ? WEXITSTATUS(status) : 128;
    if (result.jobId.empty()) {
        if (result.exitCode == 127)
            throw Error(
                "sbatch not found: install Slurm's client (slurm-client) and set SLURM_CONF");
        throw Error(fmt::format("sbatch refused {} (exit {}): {}", path, result.exitCode,
                                std::regex_replace(said, std::regex("\\s+"), " ")));
    }
    return result;
}

}  // namespace phongfit
