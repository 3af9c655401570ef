#include "defines.h"

#include "error.h"

namespace phongfit {

std::map<std::string, std::string> parseDefines(const std::vector<std::string>& entries) {
    std::map<std::string, std::string> defines;
    for (const std::string& e : entries) {
        const auto eq = e.find('=');
        if (eq == std::string::npos || eq == 0) throw Error("-D '" + e + "': expected name=value");
        defines[e.substr(0, eq)] = e.substr(eq + 1);
    }
    return defines;
}

}  // namespace phongfit
