#include "color_option.h"

#include <fmt/format.h>

#include <algorithm>
#include <cstdlib>
#include <vector>

#include "error.h"

namespace phongfit {

Color3 parseColorOption(const std::string& text, const std::string& flag) {
    std::vector<double> values;
    std::size_t pos = 0;
    while (pos <= text.size()) {
        const std::size_t comma = std::min(text.find(',', pos), text.size());
        const std::string item = text.substr(pos, comma - pos);
        char* end = nullptr;
        const double v = std::strtod(item.c_str(), &end);
        if (item.empty() || end != item.c_str() + item.size())
            throw Error(fmt::format("{} '{}': '{}' is not a number (expected R,G,B or one value)",
                                    flag, text, item));
        values.push_back(v);
        pos = comma + 1;
    }
    if (values.size() == 1) return Color3::Constant(values[0]);
    if (values.size() == 3) return Color3(values[0], values[1], values[2]);
    throw Error(fmt::format("{} '{}': expected one value (grey) or three (R,G,B), got {}", flag,
                            text, values.size()));
}

}  // namespace phongfit
