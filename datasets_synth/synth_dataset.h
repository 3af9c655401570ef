// Reading back a dataset `phongfit synth` wrote, for `phongfit bench fit`.
#pragma once

#include <string>
#include <vector>

#include "phong_brdf.h"

namespace phongfit {

struct DatasetSample {
    std::string name, group;
    std::string scenePath, imagePath;  // usable as they are (the dataset folder prepended)
    std::string material;              // id of the bsdf with the true values
    PhongMaterial truth;
    bool grey = false;  // kd and ks were drawn grey
};

// The samples listed in DIR/index.json, each from its truth.json. Throws Error if the dataset is
// incomplete (no index.json: rerun synth to finish it) or a file is missing or malformed.
std::vector<DatasetSample> readDataset(const std::string& dir);

}  // namespace phongfit
