// Command-line colours: "R,G,B" or one number for all three channels.
#pragma once

#include <string>

#include "math.h"

namespace phongfit {

// Throws Error naming `flag` and the text unless it is one number or three separated by commas.
Color3 parseColorOption(const std::string& text, const std::string& flag);

}  // namespace phongfit
