#include "shard.h"

#include <fmt/format.h>

#include <charconv>
#include <cstdlib>

#include "error.h"

namespace phongfit {
namespace {

std::optional<long> parseInteger(const std::string& s) {
    long v = 0;
    const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
    if (ec != std::errc() || end != s.data() + s.size() || s.empty()) return std::nullopt;
    return v;
}

std::optional<long> environmentInteger(const char* name) {
    const char* value = std::getenv(name);
    if (!value) return std::nullopt;
    const std::optional<long> v = parseInteger(value);
    if (!v) throw Error(fmt::format("${} = '{}': expected an integer", name, value));
    return v;
}

}  // namespace

std::string Shard::text() const { return fmt::format("{}/{}", index, count); }

Shard parseShard(const std::string& text, const std::string& option) {
    const std::size_t slash = text.find('/');
    const std::optional<long> i =
        slash == std::string::npos ? std::nullopt : parseInteger(text.substr(0, slash));
    const std::optional<long> n =
        slash == std::string::npos ? std::nullopt : parseInteger(text.substr(slash + 1));
    if (!i || !n || *n < 1 || *n > kMaxShards || *i < 0 || *i >= *n)
        throw Error(fmt::format(
            "{} '{}': expected I/N with 1 <= N <= {} and 0 <= I < N (shard I of N, from 0)", option,
            text, kMaxShards));
    return {int(*i), int(*n)};
}

std::optional<Shard> shardFromSlurmEnvironment() {
    const std::optional<long> id = environmentInteger("SLURM_ARRAY_TASK_ID");
    const std::optional<long> count = environmentInteger("SLURM_ARRAY_TASK_COUNT");
    if (!id) return std::nullopt;
    // Without the count every task would do the whole run, into the same folder.
    if (!count)
        throw Error(fmt::format(
            "$SLURM_ARRAY_TASK_ID = {} but $SLURM_ARRAY_TASK_COUNT is not set: pass --shard I/N",
            *id));
    const long min = environmentInteger("SLURM_ARRAY_TASK_MIN").value_or(0);
    const long step = environmentInteger("SLURM_ARRAY_TASK_STEP").value_or(1);
    if (step < 1 || (*id - min) % step != 0)
        throw Error(
            fmt::format("Slurm array task {} (min {}, step {}): not a task of a regular array; "
                        "pass --shard I/N",
                        *id, min, step));
    return parseShard(fmt::format("{}/{}", (*id - min) / step, *count),
                      "the Slurm array task (SLURM_ARRAY_TASK_ID - MIN) / STEP of COUNT,");
}

Shard chooseShard(const std::optional<std::string>& option) {
    if (option) return parseShard(*option);
    return shardFromSlurmEnvironment().value_or(Shard{});
}

}  // namespace phongfit
