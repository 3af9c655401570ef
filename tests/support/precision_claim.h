// The contract of fit.json's stop reason "precision": every free parameter's reported standard
// error meets --precision (kd and ks relative to max(value, 0.1), n through log n; an n listed
// unconstrained is not asked, and where it is and no ks channel shows a lobe, at least 0.01 and
// 3 standard errors, ks is relative to max(kd + ks, 0.1)), as the fit judges it
// (precision_target.h, meetsPrecision).
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <nlohmann/json.hpp>
#include <string>

namespace phongfit::test {

inline void expectPrecisionClaimHolds(const nlohmann::json& report, double precision) {
    if (report["stop_reason"] != "precision") return;
    for (const auto& [name, m] : report["materials"].items()) {
        const auto& unconstrained = m["unconstrained"];
        const bool nListed =
            std::find(unconstrained.begin(), unconstrained.end(), "n") != unconstrained.end();
        bool lobe = false;
        for (int c = 0; c < 3; ++c) {
            const double ks = m["ks"][c].get<double>();
            lobe = lobe || (ks >= 0.01 && ks > 3 * m["ks_std"][c].get<double>());
        }
        for (int c = 0; c < 3; ++c) {
            const double kd = m["kd"][c].get<double>(), ks = m["ks"][c].get<double>();
            EXPECT_LE(m["kd_std"][c].get<double>(), precision * std::max(kd, 0.1))
                << name << " kd reported past --precision " << precision;
            EXPECT_LE(m["ks_std"][c].get<double>(),
                      precision * std::max(nListed && !lobe ? kd + ks : ks, 0.1))
                << name << " ks reported past --precision " << precision;
        }
        if (!nListed) {
            EXPECT_LE(m["log_n_std"].get<double>(), precision)
                << name << " n reported past --precision " << precision;
        }
    }
}

}  // namespace phongfit::test
