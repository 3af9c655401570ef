// What a benchmark ran on and with, so its numbers can be compared: the machine (CPU, cores,
// hardware threads, threads used), the build type, the compiler and the git commit.
#pragma once

#include <nlohmann/json.hpp>

namespace phongfit {

// {"cpu", "cores", "hardware_threads", "threads_used", "build_type", "compiler", "commit"}.
// `threadsUsed` 0 means all hardware threads. The commit is the one CMake was configured at
// ("unknown" outside a git checkout).
nlohmann::json machineInfo(int threadsUsed);

}  // namespace phongfit
