// compare.png of both fit commands: rows of observed | predicted | signed error.
#pragma once

#include <cstdint>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "math.h"

namespace phongfit {

enum class ComparePixel : std::uint8_t {
    Outside,  // black in every column (outside a capture's mask)
    LeftOut,  // observed shown, grey in the other columns (masked, clipped, not fitted)
    Compared,
};

struct ComparisonPanels {
    int width = 0, height = 0;
    std::vector<Color3> observed;  // width * height, row-major, shared by every row
    std::vector<ComparePixel> state;
    std::vector<std::vector<Color3>> predicted;  // per row, width * height
    // The observed luminance at this percentile of the shown pixels is white, in every panel:
    // 100 keeps a small highlight's shape, 99 keeps a visible light source from darkening a scene.
    double whitePercentile = 99;
};

// The error column shows the mean over channels of predicted - observed: red where the prediction
// is brighter, blue where darker, full colour at the 99th percentile of its magnitude over all rows
// (a few outliers do not wash out the rest).
cv::Mat comparisonImage(const ComparisonPanels& panels);

// "(r, g, b) ± (sr, sg, sb)", or "v ± s" for grey fits: how the commands print kd and ks.
std::string formatColor(const Color3& c, const Color3& s, bool grey);

}  // namespace phongfit
