// `-D name=value` command-line overrides of a scene's `default` parameters.
#pragma once

#include <map>
#include <string>
#include <vector>

namespace phongfit {

// Throws Error for an entry without '=' or with an empty name.
std::map<std::string, std::string> parseDefines(const std::vector<std::string>& entries);

}  // namespace phongfit
