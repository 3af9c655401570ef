#include "atomic_file.h"

#include <fmt/format.h>
#include <unistd.h>

#include <atomic>
#include <system_error>

#include "error.h"

namespace phongfit {
namespace {

// Unique among concurrent writers: the process id tells processes apart, the counter threads.
std::filesystem::path temporaryName(const std::filesystem::path& target) {
    static std::atomic<unsigned> counter{0};
    const std::string name = fmt::format(".{}.{}-{}.tmp{}", target.filename().string(), ::getpid(),
                                         counter++, target.extension().string());
    return target.parent_path() / name;
}

}  // namespace

void writeAtomically(const std::filesystem::path& target,
                     const std::function<void(const std::filesystem::path& temporary)>& write) {
    namespace fs = std::filesystem;
    if (target.filename().empty())
        throw Error(fmt::format("cannot write '{}': not a file name", target.string()));
    const fs::path directory = target.parent_path().empty() ? fs::path(".") : target.parent_path();
    std::error_code ec;
    if (!fs::is_directory(directory, ec))
        throw Error(fmt::format("cannot write '{}': directory '{}' does not exist", target.string(),
                                directory.string()));
    const fs::path temporary = temporaryName(target);
    try {
        write(temporary);
        if (!fs::exists(temporary, ec))
            throw Error(
                fmt::format("cannot write '{}': the writer created no file", target.string()));
        fs::rename(temporary, target, ec);
        if (ec)
            throw Error(fmt::format("cannot write '{}': renaming '{}' failed: {}", target.string(),
                                    temporary.string(), ec.message()));
    } catch (...) {
        fs::remove(temporary, ec);  // best effort; the original exception is what the user needs
        throw;
    }
}

void requireOutputDirectory(const std::string& dir) {
    namespace fs = std::filesystem;
    if (fs::exists(dir) && !fs::is_directory(dir))
        throw Error(fmt::format("-o '{}': exists and is not a directory", dir));
    if (!fs::is_directory(fs::absolute(dir).parent_path()))
        throw Error(fmt::format("-o '{}': directory '{}' does not exist", dir,
                                fs::absolute(dir).parent_path().string()));
}

}  // namespace phongfit
