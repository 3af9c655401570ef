// The one exception type users see. Its message is complete and actionable on its own (file, line,
// value, what is allowed); main prints it on one line and exits non-zero.
#pragma once

#include <stdexcept>
#include <string>

namespace phongfit {

class Error : public std::runtime_error {
public:
    explicit Error(const std::string& message) : std::runtime_error(message) {}
};

}  // namespace phongfit
