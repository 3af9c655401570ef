#include "synth_dataset.h"

#include <fmt/format.h>

#include <filesystem>
#include <nlohmann/json.hpp>

#include "color_json.h"
#include "error.h"
#include "json_files.h"

namespace phongfit {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

}  // namespace

std::vector<DatasetSample> readDataset(const std::string& dir) {
    const json index =
        readJsonFile(fs::path(dir) / "index.json",
                     " (not a complete synth dataset: run phongfit synth to finish it)");
    if (!index.contains("samples") || !index["samples"].is_array())
        throw Error(fmt::format("{}/index.json: no list 'samples'", dir));
    std::vector<DatasetSample> samples;
    for (const json& entry : index["samples"]) {
        if (!entry.contains("name") || !entry["name"].is_string())
            throw Error(fmt::format("{}/index.json: a sample without a 'name'", dir));
        const fs::path sampleDir = fs::path(dir) / entry["name"].get<std::string>();
        const fs::path file = sampleDir / "truth.json";
        const json t = readJsonFile(file, "");
        try {
            DatasetSample s;
            s.name = t.at("name").get<std::string>();
            s.group = t.at("group").get<std::string>();
            s.scenePath = (sampleDir / t.at("scene").get<std::string>()).string();
            s.imagePath = (sampleDir / t.at("image").get<std::string>()).string();
            s.material = t.at("material").get<std::string>();
            s.truth.kd = colorFromJson(t.at("kd"), file.string(), "kd");
            s.truth.ks = colorFromJson(t.at("ks"), file.string(), "ks");
            s.truth.n = t.at("n").get<double>();
            s.grey = t.at("grey").get<bool>();
            validatePhong(s.truth, file.string());
            samples.push_back(std::move(s));
        } catch (const json::exception& e) {
            throw Error(fmt::format("{}: {}", file.string(), e.what()));
        }
    }
    if (samples.empty()) throw Error(fmt::format("{}/index.json: no samples", dir));
    return samples;
}

}  // namespace phongfit
