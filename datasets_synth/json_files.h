// Reading and writing the small JSON and text files of datasets and benchmark folders: read whole,
// written atomically (src/atomic_file.h), so that concurrent shards and interrupted runs never see
// a half-written file.
#pragma once

#include <cstdint>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>

namespace phongfit {

// Throws Error "cannot read 'path'<missingHint>".
std::string readTextFile(const std::filesystem::path& path, const std::string& missingHint = "");

// Throws Error naming the file when it is missing or not valid JSON.
nlohmann::json readJsonFile(const std::filesystem::path& path, const std::string& missingHint = "");

void writeTextAtomically(const std::filesystem::path& path, const std::string& text);
void writeJsonAtomically(const std::filesystem::path& path, const nlohmann::json& j);

// 64-bit FNV-1a of `text` as 16 hex digits: a digest telling files and runs apart (not secure).
std::string textDigest(const std::string& text);

}  // namespace phongfit
