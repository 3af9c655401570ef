// The contract of fit.json's stop reason "precision": every free parameter's reported standard
// error meets --precision (kd and ks relative to max(value, 0.1), n through log n; an n listed
// unconstrained is not asked), as the fit judges it (precision_target.h, meetsPrecision).
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <nlohmann/json.hpp>
#include <string>

namespace phongfit::test {

inline void expectPrecisionClaimHolds(const nlohmann::json& report, double precision) {
    if (report["stop_reason"] != "precision") return;
    for (const auto& [name, m] : report["materials"].items()) {
        for (const char* p : {"kd", "ks"})
            for (int c = 0; c < 3; ++c)
                EXPECT_LE(m[std::string(p) + "_std"][c].get<double>(),
                          precision * std::max(m[p][c].get<double>(), 0.1))
                    << name << " " << p << " reported past --precision " << precision;
        const auto& unconstrained = m["unconstrained"];
        if (std::find(unconstrained.begin(), unconstrained.end(), "n") == unconstrained.end()) {
            EXPECT_LE(m["log_n_std"].get<double>(), precision)
                << name << " n reported past --precision " << precision;
        }
    }
}

}  // namespace phongfit::test
