// Outputs are written to a temporary file next to the target and renamed over it only once
// complete, so a failure (exception, full disk, Ctrl-C) never leaves a half-written or truncated
// file behind.
#pragma once

#include <filesystem>
#include <functional>
#include <string>

namespace phongfit {

// Calls `write(temporary)` and renames `temporary` to `target`. The temporary is in the target's
// directory (rename is atomic only within one file system) and keeps its extension, so writers that
// choose the format by extension work. On any exception the temporary is removed, the old target
// (if any) is left untouched, and the exception is rethrown. Throws Error if the target's directory
// does not exist, or if `write` returns without creating the temporary.
void writeAtomically(const std::filesystem::path& target,
                     const std::function<void(const std::filesystem::path& temporary)>& write);

// Throws Error, before any work is done, when the output directory `dir` could not be created
// later: it exists and is not a directory, or its parent directory does not exist.
void requireOutputDirectory(const std::string& dir);

}  // namespace phongfit
