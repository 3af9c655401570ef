// Line and scatter plots on linear or logarithmic axes, drawn with OpenCV (anti-aliased, drawn at
// twice the size and scaled down), for the figures of `phongfit bench`: panels side by side with
// decade-labelled log axes, a grid, and one legend for the figure.
#pragma once

#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace phongfit {

struct PlotSeries {
    std::string label;  // legend entry; series sharing a label share the entry
    cv::Scalar color;   // BGR
    bool dashed = false;
    bool line = true;                 // join the points in order
    bool markers = true;              // a dot at each point
    std::vector<cv::Point2d> points;  // data coordinates; points a log axis cannot show are skipped
};

struct PlotAxis {
    std::string label;
    bool log = false;
};

struct PlotPanel {
    std::string title;
    PlotAxis x, y;
    std::vector<PlotSeries> series;
    bool identityLine = false;  // the line y = x, over a range shared by both axes
};

// The i-th colour of a palette of ten that stay distinct on white.
cv::Scalar plotColor(int i);

// An 8-bit BGR image: `title` on top, the panels left to right (each about panelWidth x
// panelHeight pixels), the legend on the right.
cv::Mat drawFigure(const std::string& title, const std::vector<PlotPanel>& panels,
                   int panelWidth = 520, int panelHeight = 420);

}  // namespace phongfit
