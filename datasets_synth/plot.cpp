#include "plot.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/imgproc.hpp>

namespace phongfit {
namespace {

constexpr int kSupersample = 2;  // drawn at twice the size, then scaled down: smoother
constexpr int kFont = cv::FONT_HERSHEY_SIMPLEX;
const cv::Scalar kText(40, 40, 40), kAxisColor(90, 90, 90), kGrid(222, 222, 222),
    kMinorGrid(242, 242, 242), kWhite(255, 255, 255);

int px(double v) { return int(std::lround(v * kSupersample)); }

cv::Size textSize(const std::string& text, double scale, int thickness) {
    int baseline = 0;
    return cv::getTextSize(text, kFont, scale * kSupersample, thickness * kSupersample, &baseline);
}

// `org` is the left end of the baseline, in output pixels (before supersampling).
void text(cv::Mat& img, const std::string& s, cv::Point2d org, double scale, int thickness = 1,
          const cv::Scalar& color = kText) {
    cv::putText(img, s, cv::Point(px(org.x), px(org.y)), kFont, scale * kSupersample, color,
                thickness * kSupersample, cv::LINE_AA);
}

double textWidth(const std::string& s, double scale, int thickness = 1) {
    return double(textSize(s, scale, thickness).width) / kSupersample;
}

// "10" with a raised, smaller exponent; returns its width. `org` as for text().
double powerOfTen(cv::Mat& img, int exponent, cv::Point2d org, double scale, bool draw = true) {
    const std::string e = std::to_string(exponent);
    const double w10 = textWidth("10", scale), we = textWidth(e, 0.7 * scale);
    if (draw) {
        text(img, "10", org, scale);
        text(img, e,
             org + cv::Point2d(w10 + 1, -0.45 * textSize("10", scale, 1).height / kSupersample),
             0.7 * scale);
    }
    return w10 + 1 + we;
}

// Text turned 90 degrees counter-clockwise, centred on `centre` (output pixels).
void verticalText(cv::Mat& img, const std::string& s, cv::Point2d centre, double scale) {
    const cv::Size size = textSize(s, scale, 1);
    cv::Mat patch(size.height * 2, size.width + 4, img.type(), kWhite);
    cv::putText(patch, s, cv::Point(2, size.height + size.height / 2), kFont, scale * kSupersample,
                kText, kSupersample, cv::LINE_AA);
    cv::rotate(patch, patch, cv::ROTATE_90_COUNTERCLOCKWISE);
    const cv::Rect target(px(centre.x) - patch.cols / 2, px(centre.y) - patch.rows / 2, patch.cols,
                          patch.rows);
    const cv::Rect clipped = target & cv::Rect(0, 0, img.cols, img.rows);
    cv::Mat roi = img(clipped);
    cv::min(roi, patch(cv::Rect(clipped.tl() - target.tl(), clipped.size())), roi);
}

// One axis: data range (exponents of ten on a log axis), ticks and the map to pixels.
struct Scale {
    bool log = false;
    double lo = 0, hi = 1;             // log: log10 of the range's ends
    double p0 = 0, p1 = 1;             // pixels at lo and hi
    std::vector<double> major, minor;  // tick values in data units

    bool shows(double v) const { return std::isfinite(v) && (!log || v > 0); }
    double pixel(double v) const {
        const double t = ((log ? std::log10(v) : v) - lo) / (hi - lo);
        return p0 + t * (p1 - p0);
    }
};

double niceStep(double span) {
    const double raw = span / 5, magnitude = std::pow(10, std::floor(std::log10(raw)));
    for (const double m : {1.0, 2.0, 5.0})
        if (m * magnitude >= raw) return m * magnitude;
    return 10 * magnitude;
}

Scale makeScale(bool log, double min, double max) {
    Scale s;
    s.log = log;
    if (!(min <= max)) {  // no data: a placeholder range
        min = log ? 0.1 : 0;
        max = log ? 10 : 1;
    }
    if (log) {
        s.lo = std::floor(std::log10(min) + 1e-9);
        s.hi = std::ceil(std::log10(max) - 1e-9);
        if (s.hi <= s.lo) s.hi = s.lo + 1;
        const int every = int(std::ceil((s.hi - s.lo) / 8));  // at most ~8 labelled decades
        for (int e = int(s.lo); e <= int(s.hi); ++e) {
            if ((e - int(s.lo)) % every == 0) s.major.push_back(std::pow(10.0, e));
            if (s.hi - s.lo <= 6 && e < int(s.hi))
                for (int m = 2; m <= 9; ++m) s.minor.push_back(m * std::pow(10.0, e));
        }
    } else {
        if (max - min < 1e-12 * std::max(1.0, std::abs(max))) {
            const double pad = min != 0 ? 0.1 * std::abs(min) : 1;
            min -= pad;
            max += pad;
        }
        const double step = niceStep(max - min);
        s.lo = std::floor(min / step + 1e-9) * step;
        s.hi = std::ceil(max / step - 1e-9) * step;
        for (double v = s.lo; v <= s.hi + step * 1e-6; v += step)
            s.major.push_back(std::abs(v) < step * 1e-9 ? 0 : v);
    }
    return s;
}

void dataRange(const PlotPanel& panel, bool xAxis, double& min, double& max) {
    const bool log = xAxis ? panel.x.log : panel.y.log;
    min = std::numeric_limits<double>::infinity();
    max = -min;
    for (const PlotSeries& s : panel.series)
        for (const cv::Point2d& p : s.points) {
            const double v = xAxis ? p.x : p.y;
            if (!std::isfinite(v) || (log && v <= 0)) continue;
            min = std::min(min, v);
            max = std::max(max, v);
        }
}

// A polyline, dashed or solid, in output pixels.
void polyline(cv::Mat& img, const std::vector<cv::Point2d>& pts, const cv::Scalar& color,
              bool dashed, double width) {
    const double dash = 9, gap = 5;
    double phase = 0;  // distance along the current dash or gap
    bool on = true;
    for (std::size_t i = 1; i < pts.size(); ++i) {
        const cv::Point2d a = pts[i - 1], b = pts[i];
        const double length = cv::norm(b - a);
        if (!dashed) {
            cv::line(img, cv::Point(px(a.x), px(a.y)), cv::Point(px(b.x), px(b.y)), color,
                     px(width), cv::LINE_AA);
            continue;
        }
        double t = 0;
        while (t < length) {
            const double step = std::min(length - t, (on ? dash : gap) - phase);
            if (on) {
                const cv::Point2d p = a + (b - a) * (t / length),
                                  q = a + (b - a) * ((t + step) / length);
                cv::line(img, cv::Point(px(p.x), px(p.y)), cv::Point(px(q.x), px(q.y)), color,
                         px(width), cv::LINE_AA);
            }
            t += step;
            phase += step;
            if (phase >= (on ? dash : gap) - 1e-9) {
                on = !on;
                phase = 0;
            }
        }
    }
}

std::string linearLabel(double v) { return fmt::format("{:g}", v); }

void drawPanel(cv::Mat& img, const PlotPanel& panel, cv::Rect2d box) {
    constexpr double kTick = 0.5;  // font scales
    const double left = box.x + 78, right = box.x + box.width - 16;
    const double top = box.y + 34, bottom = box.y + box.height - 58;

    double xmin, xmax, ymin, ymax;
    dataRange(panel, true, xmin, xmax);
    dataRange(panel, false, ymin, ymax);
    if (panel.identityLine && panel.x.log == panel.y.log) {
        xmin = ymin = std::min(xmin, ymin);
        xmax = ymax = std::max(xmax, ymax);
    }
    Scale x = makeScale(panel.x.log, xmin, xmax), y = makeScale(panel.y.log, ymin, ymax);
    x.p0 = left;
    x.p1 = right;
    y.p0 = bottom;  // y grows upwards
    y.p1 = top;

    const cv::Scalar frameColor = kAxisColor;
    auto hline = [&](double py, const cv::Scalar& c, double w) {
        cv::line(img, cv::Point(px(left), px(py)), cv::Point(px(right), px(py)), c, px(w),
                 cv::LINE_AA);
    };
    auto vline = [&](double pxv, const cv::Scalar& c, double w) {
        cv::line(img, cv::Point(px(pxv), px(top)), cv::Point(px(pxv), px(bottom)), c, px(w),
                 cv::LINE_AA);
    };
    for (const double v : x.minor) vline(x.pixel(v), kMinorGrid, 1);
    for (const double v : y.minor) hline(y.pixel(v), kMinorGrid, 1);
    for (const double v : x.major) vline(x.pixel(v), kGrid, 1);
    for (const double v : y.major) hline(y.pixel(v), kGrid, 1);
    cv::rectangle(img, cv::Point(px(left), px(top)), cv::Point(px(right), px(bottom)), frameColor,
                  px(1), cv::LINE_AA);

    // Tick labels.
    const double labelHeight = double(textSize("10", kTick, 1).height) / kSupersample;
    for (const double v : x.major) {
        const double p = x.pixel(v);
        cv::line(img, cv::Point(px(p), px(bottom)), cv::Point(px(p), px(bottom + 5)), frameColor,
                 px(1), cv::LINE_AA);
        if (x.log) {
            const int e = int(std::lround(std::log10(v)));
            const double w = powerOfTen(img, e, {}, kTick, false);
            powerOfTen(img, e, {p - w / 2, bottom + 10 + 1.4 * labelHeight}, kTick);
        } else {
            const std::string s = linearLabel(v);
            text(img, s, {p - textWidth(s, kTick) / 2, bottom + 10 + labelHeight}, kTick);
        }
    }
    for (const double v : y.major) {
        const double p = y.pixel(v);
        cv::line(img, cv::Point(px(left - 5), px(p)), cv::Point(px(left), px(p)), frameColor, px(1),
                 cv::LINE_AA);
        if (y.log) {
            const int e = int(std::lround(std::log10(v)));
            const double w = powerOfTen(img, e, {}, kTick, false);
            powerOfTen(img, e, {left - 9 - w, p + labelHeight / 2}, kTick);
        } else {
            const std::string s = linearLabel(v);
            text(img, s, {left - 9 - textWidth(s, kTick), p + labelHeight / 2}, kTick);
        }
    }
    text(img, panel.x.label, {(left + right) / 2 - textWidth(panel.x.label, 0.55) / 2, bottom + 48},
         0.55);
    verticalText(img, panel.y.label, {box.x + 16, (top + bottom) / 2}, 0.55);
    text(img, panel.title, {(left + right) / 2 - textWidth(panel.title, 0.6, 2) / 2, top - 12}, 0.6,
         2);

    // Data, clipped to the frame.
    cv::Mat clip = img(cv::Rect(px(left), px(top), px(right - left), px(bottom - top)));
    const cv::Point2d origin(left, top);
    auto toClip = [&](cv::Point2d p) { return cv::Point2d(x.pixel(p.x), y.pixel(p.y)) - origin; };
    if (panel.identityLine) {
        const double lo = std::pow(10.0, x.lo), hi = std::pow(10.0, x.hi);
        const cv::Point2d a = x.log ? cv::Point2d(lo, lo) : cv::Point2d(x.lo, x.lo);
        const cv::Point2d b = x.log ? cv::Point2d(hi, hi) : cv::Point2d(x.hi, x.hi);
        polyline(clip, {toClip(a), toClip(b)}, cv::Scalar(150, 150, 150), true, 1.2);
    }
    for (const PlotSeries& s : panel.series) {
        std::vector<cv::Point2d> run;  // a stretch of drawable points
        auto flush = [&] {
            if (s.line) polyline(clip, run, s.color, s.dashed, 1.8);
            run.clear();
        };
        for (const cv::Point2d& p : s.points) {
            if (!x.shows(p.x) || !y.shows(p.y)) {
                flush();
                continue;
            }
            run.push_back(toClip(p));
        }
        flush();
        if (s.markers)
            for (const cv::Point2d& p : s.points)
                if (x.shows(p.x) && y.shows(p.y)) {
                    const cv::Point2d q = toClip(p);
                    cv::circle(clip, cv::Point(px(q.x), px(q.y)), px(s.line ? 2.8 : 2.4), s.color,
                               cv::FILLED, cv::LINE_AA);
                }
    }
}

}  // namespace

cv::Scalar plotColor(int i) {
    static const cv::Scalar palette[] = {
        {180, 119, 31}, {14, 127, 255},  {44, 160, 44},   {40, 39, 214},  {189, 103, 148},
        {75, 86, 140},  {194, 119, 227}, {127, 127, 127}, {34, 189, 188}, {207, 190, 23}};
    return palette[i % 10];
}

cv::Mat drawFigure(const std::string& title, const std::vector<PlotPanel>& panels, int panelWidth,
                   int panelHeight) {
    // Legend entries: each label once, in order of appearance.
    std::vector<const PlotSeries*> entries;
    for (const PlotPanel& p : panels)
        for (const PlotSeries& s : p.series)
            if (!s.label.empty() &&
                std::none_of(entries.begin(), entries.end(),
                             [&](const PlotSeries* e) { return e->label == s.label; }))
                entries.push_back(&s);
    double legendWidth = 0;
    for (const PlotSeries* e : entries)
        legendWidth = std::max(legendWidth, textWidth(e->label, 0.5));
    if (!entries.empty()) legendWidth += 70;

    const double titleHeight = title.empty() ? 8 : 40;
    const int width = int(panels.size()) * panelWidth + int(legendWidth) + 10;
    const int height = int(titleHeight) + panelHeight;
    cv::Mat img(height * kSupersample, width * kSupersample, CV_8UC3, kWhite);
    if (!title.empty()) text(img, title, {width / 2.0 - textWidth(title, 0.7, 2) / 2, 28}, 0.7, 2);
    for (std::size_t i = 0; i < panels.size(); ++i)
        drawPanel(img, panels[i],
                  cv::Rect2d(double(i) * panelWidth, titleHeight, panelWidth, panelHeight));

    const double x0 = double(panels.size()) * panelWidth + 8;
    double y = titleHeight + 40;
    for (const PlotSeries* e : entries) {
        if (e->line) polyline(img, {{x0, y - 5}, {x0 + 40, y - 5}}, e->color, e->dashed, 1.8);
        if (e->markers)
            cv::circle(img, cv::Point(px(x0 + 20), px(y - 5)), px(2.8), e->color, cv::FILLED,
                       cv::LINE_AA);
        text(img, e->label, {x0 + 50, y}, 0.5);
        y += 22;
    }
    cv::Mat out;
    cv::resize(img, out, cv::Size(width, height), 0, 0, cv::INTER_AREA);
    return out;
}

}  // namespace phongfit
