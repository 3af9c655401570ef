// A colour in the reports' JSON: [r, g, b].
#pragma once

#include <fmt/format.h>

#include <nlohmann/json.hpp>
#include <string>

#include "error.h"
#include "math.h"

namespace phongfit {

inline nlohmann::json colorJson(const Color3& c) {
    return nlohmann::json::array({c[0], c[1], c[2]});
}

// colorJson's [r, g, b] read back from `file`'s `key`; anything else is an Error naming both.
inline Color3 colorFromJson(const nlohmann::json& j, const std::string& file,
                            const std::string& key) {
    if (!j.is_array() || j.size() != 3 || !j[0].is_number() || !j[1].is_number() ||
        !j[2].is_number())
        throw Error(fmt::format("{}: '{}' = {}: expected [r, g, b]", file, key, j.dump()));
    return Color3(j[0].get<double>(), j[1].get<double>(), j[2].get<double>());
}

}  // namespace phongfit
