#include "memory_info.h"

#include <fcntl.h>
#include <malloc.h>
#include <sys/mman.h>
#include <unistd.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>
#include <string>

namespace phongfit {

namespace {

// The first number of a one-line file ("max" and unreadable files give nothing).
bool readNumber(const char* path, std::size_t& value) {
    std::ifstream in(path);
    std::string word;
    if (!(in >> word) || word.empty() || word.find_first_not_of("0123456789") != std::string::npos)
        return false;
    value = std::stoull(word);
    return true;
}

// A "key: N kB" line of /proc/self/status, in bytes; 0 where it cannot be read.
std::size_t statusBytes(const char* wanted) {
    std::ifstream status("/proc/self/status");
    std::string key;
    while (status >> key) {
        if (key == wanted) {
            std::size_t kb = 0;
            return status >> kb ? kb * 1024 : 0;
        }
        status.ignore(std::numeric_limits<std::streamsize>::max(), '\n');
    }
    return 0;
}

}  // namespace

std::size_t residentBytes() {
    const int statm = ::open("/proc/self/statm", O_RDONLY | O_CLOEXEC);
    const std::size_t bytes = residentBytes(statm);
    if (statm >= 0) ::close(statm);
    return bytes;
}

std::size_t residentBytes(int statm) {
    // Into a buffer of its own: a reading allocates nothing.
    char text[128];
    const ssize_t length = statm < 0 ? -1 : ::pread(statm, text, sizeof(text) - 1, 0);
    if (length <= 0) return 0;
    text[length] = '\0';
    unsigned long size = 0, resident = 0;
    if (std::sscanf(text, "%lu %lu", &size, &resident) != 2) return 0;
    return std::size_t(resident) * std::size_t(sysconf(_SC_PAGESIZE));
}

void mapLargeBuffers() { mallopt(M_MMAP_THRESHOLD, 1 << 16); }

void residentProgram() {
    std::error_code error;
    const std::filesystem::path exe = std::filesystem::read_symlink("/proc/self/exe", error);
    if (error) return;
    std::ifstream maps("/proc/self/maps");
    std::string line;
    while (std::getline(maps, line)) {
        // "begin-end perms offset device inode path"
        std::istringstream fields(line);
        std::string range, perms, offset, device, inode, path;
        fields >> range >> perms >> offset >> device >> inode;
        std::getline(fields >> std::ws, path);
        if (path != exe.string() || perms.empty() || perms[0] != 'r') continue;
        const std::size_t dash = range.find('-');
        const auto begin = std::uintptr_t(std::stoull(range.substr(0, dash), nullptr, 16));
        const auto end = std::uintptr_t(std::stoull(range.substr(dash + 1), nullptr, 16));
        // Maps its pages as reads would, with an error rather than a signal past the file's end
        // (Linux 5.14 on; before it the pages stay as they are).
        madvise(reinterpret_cast<void*>(begin), end - begin, MADV_POPULATE_READ);
    }
}

std::size_t peakResidentBytes() { return statusBytes("VmHWM:"); }

std::size_t fileResidentBytes() { return statusBytes("RssFile:"); }

void resetPeakResident() {
    std::ofstream clear("/proc/self/clear_refs");
    clear << "5";
}

std::size_t availableBytes() {
    std::size_t available = std::numeric_limits<std::size_t>::max();
    std::ifstream meminfo("/proc/meminfo");
    std::string key;
    std::size_t kb = 0;
    std::string unit;
    while (meminfo >> key >> kb >> unit)
        if (key == "MemAvailable:") available = kb * 1024;
    std::size_t max = 0, current = 0;
    if (readNumber("/sys/fs/cgroup/memory.max", max) &&
        readNumber("/sys/fs/cgroup/memory.current", current))
        available = std::min(available, max > current ? max - current : 0);
    return available == std::numeric_limits<std::size_t>::max() ? 0 : available;
}

}  // namespace phongfit
