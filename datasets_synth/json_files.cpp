#include "json_files.h"

#include <fmt/format.h>

#include <fstream>
#include <sstream>

#include "atomic_file.h"
#include "error.h"

namespace phongfit {

namespace fs = std::filesystem;

std::string readTextFile(const fs::path& path, const std::string& missingHint) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw Error(fmt::format("cannot read '{}'{}", path.string(), missingHint));
    std::stringstream s;
    s << in.rdbuf();
    return s.str();
}

nlohmann::json readJsonFile(const fs::path& path, const std::string& missingHint) {
    const std::string text = readTextFile(path, missingHint);
    try {
        return nlohmann::json::parse(text);
    } catch (const nlohmann::json::exception& e) {
        throw Error(fmt::format("{}: not valid JSON: {}", path.string(), e.what()));
    }
}

void writeTextAtomically(const fs::path& path, const std::string& text) {
    writeAtomically(path, [&](const fs::path& tmp) {
        std::ofstream out(tmp, std::ios::binary);
        out << text;
        out.close();
        if (!out) throw Error(fmt::format("cannot write '{}'", tmp.string()));
    });
}

void writeJsonAtomically(const fs::path& path, const nlohmann::json& j) {
    writeTextAtomically(path, j.dump(2) + "\n");
}

std::string textDigest(const std::string& text) {
    std::uint64_t h = 0xcbf29ce484222325ULL;
    for (const unsigned char c : text) h = (h ^ c) * 0x100000001b3ULL;
    return fmt::format("{:016x}", h);
}

}  // namespace phongfit
