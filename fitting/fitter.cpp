#include "fitter.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>

#include "error.h"
#include "fit_input.h"
#include "material_params.h"
#include "rounds.h"

namespace phongfit {

LossKind parseLoss(const std::string& name) {
    if (name == "l2") return LossKind::L2;
    if (name == "huber") return LossKind::Huber;
    if (name == "cauchy") return LossKind::Cauchy;
    throw Error(fmt::format("loss '{}' is unknown (allowed: l2, huber, cauchy)", name));
}

PhongMaterial MaterialFit::material() const {
    PhongMaterial m;
    m.kd = kd;
    m.ks = ks;
    m.n = n;
    return m;
}

std::vector<PhongMaterial> FitResult::fittedMaterials() const {
    std::vector<PhongMaterial> out;
    for (const MaterialFit& m : materials) out.push_back(m.material());
    return out;
}

bool MaterialFit::isUnconstrained(const std::string& name) const {
    return std::find(unconstrained.begin(), unconstrained.end(), name) != unconstrained.end();
}

bool MaterialFit::channelUnconstrained(const std::string& name, int c) const {
    return isUnconstrained(name) || isUnconstrained(name + '.' + "rgb"[c]);
}

bool MaterialFit::ksUnconstrained() const {
    return std::any_of(unconstrained.begin(), unconstrained.end(),
                       [](const std::string& name) { return name.starts_with("ks"); });
}

namespace {

FitResult fit(const std::vector<Observation>& observations, const RecordAll& recordAll,
              const std::vector<PhongMaterial>& start, const FitOptions& options, int maxRounds,
              bool rerecords) {
    if (observations.empty()) throw Error("the fit needs at least one view");
    if (start.empty()) throw Error("the fit needs at least one material");
    if (maxRounds < 1 || options.maxIterations < 1 || !(options.tolerance > 0) ||
        !(options.stdTolerance >= 0) || !(options.lossScale > 0))
        throw Error(
            fmt::format("fit options: rounds {} and iterations {} must be >= 1, tolerance "
                        "{} and loss scale {} > 0, std tolerance {} >= 0",
                        maxRounds, options.maxIterations, options.tolerance, options.lossScale,
                        options.stdTolerance));
    if (!(options.precision >= 0 && options.precision < 1))
        throw Error(fmt::format("fit options: precision {} must be in [0, 1) (0: no target)",
                                options.precision));
    for (std::size_t s = 0; s < start.size(); ++s)
        validatePhong(start[s], fmt::format("start value of material {}", s));
    for (std::size_t v = 0; v < observations.size(); ++v) checkObservation(observations[v], int(v));
    return options.grey ? runRounds<kGreyBlock>(observations, recordAll, start, options, maxRounds,
                                                rerecords)
                        : runRounds<kRgbBlock>(observations, recordAll, start, options, maxRounds,
                                               rerecords);
}

}  // namespace

FitResult fitMaterials(const std::vector<Observation>& observations, const PathRecorder& record,
                       const std::vector<PhongMaterial>& start, const FitOptions& options) {
    std::array<std::vector<PathSet>, 2> paths;
    const RecordAll recordAll = [&](const std::vector<PhongMaterial>& theta, int round,
                                    const std::vector<std::vector<float>>& importance,
                                    double pathFactor) {
        static const std::vector<float> none;
        for (int k = 0; k < 2; ++k) {
            paths[k].clear();
            for (std::size_t v = 0; v < observations.size(); ++v)
                paths[k].push_back(record(int(v), theta, 2 * round + k,
                                          importance.empty() ? none : importance[v], pathFactor));
        }
        return RoundSets{&paths[0], &paths[1]};
    };
    return fit(observations, recordAll, start, options, options.maxRounds, true);
}

FitResult fitPathSets(const std::vector<Observation>& observations,
                      const std::vector<PathSet>& first, const std::vector<PathSet>& second,
                      const std::vector<PhongMaterial>& start, const FitOptions& options,
                      int rounds) {
    const RecordAll recordAll = [&](const std::vector<PhongMaterial>&, int,
                                    const std::vector<std::vector<float>>&, double) {
        return RoundSets{&first, &second};
    };
    return fit(observations, recordAll, start, options, rounds, false);
}

}  // namespace phongfit
