#include "bench_fit_row.h"

#include <fmt/format.h>

#include <cmath>
#include <limits>

#include "error.h"

namespace phongfit {
namespace {

using json = nlohmann::json;

double colourError(const Color3& x, const Color3& truth) {
    const double norm = truth.matrix().norm();
    return (x - truth).matrix().norm() / (norm > 0 ? norm : 1.0);
}

double exponentError(double n, double truth) {
    return std::abs(n - truth) / std::max(truth, 1e-12);
}

// JSON has no NaN or infinity: those are written as strings, so every value reads back exactly.
json number(double v) {
    if (std::isfinite(v)) return v;
    return std::isnan(v) ? "nan" : v > 0 ? "inf" : "-inf";
}

double numberFrom(const json& j) {
    if (j.is_number()) return j.get<double>();
    const std::string s = j.get<std::string>();
    if (s == "nan") return std::numeric_limits<double>::quiet_NaN();
    if (s == "inf" || s == "-inf")
        return (s == "inf" ? 1 : -1) * std::numeric_limits<double>::infinity();
    throw json::type_error::create(302, fmt::format("'{}' is not a number", s), &j);
}

json colour(const Color3& c) { return json::array({number(c[0]), number(c[1]), number(c[2])}); }

Color3 colourFrom(const json& j) {
    if (!j.is_array() || j.size() != 3)
        throw json::type_error::create(302, "expected [r, g, b]", &j);
    return Color3(numberFrom(j[0]), numberFrom(j[1]), numberFrom(j[2]));
}

json errorsJson(const Errors& e) {
    return {{"kd", number(e.kd)}, {"ks", number(e.ks)}, {"n", number(e.n)}};
}

Errors errorsFrom(const json& j) {
    return {numberFrom(j.at("kd")), numberFrom(j.at("ks")), numberFrom(j.at("n"))};
}

}  // namespace

Errors errorsOf(const MaterialFit& m, const PhongMaterial& truth) {
    return {colourError(m.kd, truth.kd), colourError(m.ks, truth.ks), exponentError(m.n, truth.n)};
}

Errors relativeStdOf(const MaterialFit& m, const PhongMaterial& truth) {
    const auto relative = [](const Color3& sd, const Color3& t) {
        const double norm = t.matrix().norm();
        return sd.matrix().norm() / (norm > 0 ? norm : 1.0);
    };
    return {relative(m.kdStd, truth.kd), relative(m.ksStd, truth.ks),
            m.nStd / std::max(truth.n, 1e-12)};
}

bool isFinite(const MaterialFit& m) {
    return m.kd.allFinite() && m.ks.allFinite() && std::isfinite(m.n);
}

json toJson(const FitRow& r, const std::string& run) {
    json history = json::array();
    for (const RoundPoint& p : r.history)
        history.push_back({{"seconds", number(p.seconds)},
                           {"errors", errorsJson(p.errors)},
                           {"stds", errorsJson(p.stds)}});
    return {{"run", run},
            {"sample", r.sample->name},
            {"spp_per_round", r.spp},
            {"returned", r.returned},
            {"fit",
             {{"kd", colour(r.fit.kd)},
              {"ks", colour(r.fit.ks)},
              {"n", number(r.fit.n)},
              {"kd_std", colour(r.fit.kdStd)},
              {"ks_std", colour(r.fit.ksStd)},
              {"n_std", number(r.fit.nStd)},
              {"unconstrained", r.fit.unconstrained}}},
            {"rounds", r.rounds},
            {"converged", r.converged},
            {"seconds", number(r.seconds)},
            {"rmse", number(r.rmse)},
            {"errors", errorsJson(r.errors)},
            {"within_3_std", r.withinErrors},
            {"within_tolerance", r.verdict.withinTolerance},
            {"pass", r.verdict.pass},
            {"failed", r.failed},
            {"error", r.error},
            {"history", history}};
}

FitRow fitRowFromJson(const json& j, const DatasetSample& sample, const std::string& file) {
    try {
        FitRow r;
        r.sample = &sample;
        r.spp = j.at("spp_per_round").get<int>();
        r.returned = j.at("returned").get<bool>();
        const json& f = j.at("fit");
        r.fit.kd = colourFrom(f.at("kd"));
        r.fit.ks = colourFrom(f.at("ks"));
        r.fit.n = numberFrom(f.at("n"));
        r.fit.kdStd = colourFrom(f.at("kd_std"));
        r.fit.ksStd = colourFrom(f.at("ks_std"));
        r.fit.nStd = numberFrom(f.at("n_std"));
        r.fit.unconstrained = f.at("unconstrained").get<std::vector<std::string>>();
        r.rounds = j.at("rounds").get<int>();
        r.converged = j.at("converged").get<bool>();
        r.seconds = numberFrom(j.at("seconds"));
        r.rmse = numberFrom(j.at("rmse"));
        r.errors = errorsFrom(j.at("errors"));
        r.withinErrors = j.at("within_3_std").get<bool>();
        r.verdict = {j.at("within_tolerance").get<bool>(), j.at("pass").get<bool>()};
        r.failed = j.at("failed").get<bool>();
        r.error = j.at("error").get<std::string>();
        for (const json& p : j.at("history"))
            r.history.push_back({numberFrom(p.at("seconds")), errorsFrom(p.at("errors")),
                                 errorsFrom(p.at("stds"))});
        return r;
    } catch (const json::exception& e) {
        throw Error(fmt::format("{}: not a bench fit row: {}", file, e.what()));
    }
}

}  // namespace phongfit
