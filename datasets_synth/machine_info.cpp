#include "machine_info.h"

#include <fstream>
#include <set>
#include <string>
#include <thread>
#include <utility>

#include "build_commit.h"

namespace phongfit {
namespace {

std::string compiler() {
#if defined(__clang__)
    return "clang " __clang_version__;
#elif defined(__GNUC__)
    return "GCC " __VERSION__;
#else
    return "unknown";
#endif
}

}  // namespace

nlohmann::json machineInfo(int threadsUsed) {
    const int hardwareThreads = int(std::max(1u, std::thread::hardware_concurrency()));
    // Physical cores are the distinct (physical id, core id) pairs of /proc/cpuinfo.
    std::set<std::pair<std::string, std::string>> cores;
    std::string cpu = "unknown", physical, line;
    std::ifstream in("/proc/cpuinfo");
    while (std::getline(in, line)) {
        const auto colon = line.find(':');
        if (colon == std::string::npos) continue;
        std::string key = line.substr(0, colon);
        key.erase(key.find_last_not_of(" \t") + 1);
        const std::string value = colon + 2 <= line.size() ? line.substr(colon + 2) : "";
        if (key == "model name") cpu = value;
        if (key == "physical id") physical = value;
        if (key == "core id") cores.emplace(physical, value);
    }
    return {{"cpu", cpu},
            {"cores", cores.empty() ? hardwareThreads : int(cores.size())},
            {"hardware_threads", hardwareThreads},
            {"threads_used", threadsUsed > 0 ? threadsUsed : hardwareThreads},
            {"build_type", PHONGFIT_BUILD_TYPE},
            {"compiler", compiler()},
            {"commit", PHONGFIT_GIT_COMMIT}};
}

}  // namespace phongfit
