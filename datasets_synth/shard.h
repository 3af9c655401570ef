// Which part of a run one process does (`--shard I/N`, or a Slurm array task): item k of a run
// (a synth sample index, a bench fit's (spp, sample) pair in order) belongs to shard k mod N.
// Round-robin rather than blocks, so that each shard gets a share of every group and exponent.
#pragma once

#include <optional>
#include <string>

namespace phongfit {

struct Shard {
    int index = 0, count = 1;  // 0 <= index < count

    bool contains(int item) const { return item % count == index; }
    bool whole() const { return count == 1; }
    std::string text() const;  // "I/N"
};

// "I/N" with 0 <= I < N <= kMaxShards; throws Error naming `option` and what is allowed.
Shard parseShard(const std::string& text, const std::string& option = "--shard");

// The shard of a Slurm array task: I = (SLURM_ARRAY_TASK_ID - SLURM_ARRAY_TASK_MIN) /
// SLURM_ARRAY_TASK_STEP (MIN 0 and STEP 1 when unset), N = SLURM_ARRAY_TASK_COUNT; nothing outside
// an array job. Throws Error when the variables are malformed or missing (an ID without a COUNT)
// or I is not below N.
std::optional<Shard> shardFromSlurmEnvironment();

// `--shard` when given, else the Slurm array task's, else the whole run.
Shard chooseShard(const std::optional<std::string>& option);

constexpr int kMaxShards = 1000000;

}  // namespace phongfit
