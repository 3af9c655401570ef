// The message of the phongfit::Error that f throws, for tests of one-line errors.
#pragma once

#include <string>

#include "error.h"

namespace phongfit::test {

// "(no phongfit::Error)" when f throws none, so a message check fails on it.
template <typename F>
std::string errorOf(F&& f) {
    try {
        f();
    } catch (const Error& e) {
        return e.what();
    }
    return "(no phongfit::Error)";
}

}  // namespace phongfit::test
