// A colour in the reports' JSON: [r, g, b].
#pragma once

#include <nlohmann/json.hpp>

#include "math.h"

namespace phongfit {

inline nlohmann::json colorJson(const Color3& c) {
    return nlohmann::json::array({c[0], c[1], c[2]});
}

}  // namespace phongfit
