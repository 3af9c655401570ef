#include "lobe_plot.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>

#include "phong_brdf.h"

namespace phongfit {
namespace {

constexpr int kWidth = 800, kHeight = 600;
const cv::Point2d kCenter(400, 535);
constexpr double kRadius = 360;  // of the rim, in pixels

const cv::Scalar kBlack(0, 0, 0), kGrid(215, 215, 215), kLabel(90, 90, 90), kWhite(255, 255, 255);
constexpr int kFont = cv::FONT_HERSHEY_SIMPLEX;

// Matplotlib's tab10, in BGR.
const cv::Scalar kPalette[] = {{180, 119, 31},  {14, 127, 255}, {44, 160, 44},   {40, 39, 214},
                               {189, 103, 148}, {75, 86, 140},  {194, 119, 227}, {127, 127, 127},
                               {34, 189, 188},  {207, 190, 23}};

double luminance(const Color3& c) { return 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]; }

// Integers below 1e5 in full, else three significant digits with a short exponent: "0.25",
// "1000", "6.37e5", "1e-4".
std::string compact(double v) {
    if (v == std::round(v) && std::abs(v) < 1e5) return fmt::format("{:.0f}", v);
    std::string s = fmt::format("{:.3g}", v);
    const std::size_t e = s.find('e');
    if (e == std::string::npos) return s;
    std::string exponent = s.substr(e + 1);
    const bool negative = exponent[0] == '-';
    exponent.erase(0, exponent.find_first_not_of("+-0"));
    return s.substr(0, e + 1) + (negative ? "-" : "") + exponent;
}

// "0.5" for grey, "(0.5, 0.4, 0.3)" for colour.
std::string colorText(const Color3& c) {
    if (c[0] == c[1] && c[1] == c[2]) return fmt::format("{:g}", c[0]);
    return fmt::format("({:g}, {:g}, {:g})", c[0], c[1], c[2]);
}

// Angles (degrees) to evaluate a curve at: a uniform grid, refined geometrically around the mirror
// direction, where a lobe of n = 1e6 is only a few hundredths of a degree wide.
std::vector<double> curveAngles(double mirrorDeg) {
    std::vector<double> angles;
    for (int i = 0; i <= 720; ++i) angles.push_back(-90 + 0.25 * i);
    for (int i = 0; i <= 120; ++i) {
        const double offset = std::pow(10.0, -5 + 6.0 * i / 120);  // 1e-5 to 10 degrees
        for (double a : {mirrorDeg - offset, mirrorDeg + offset})
            if (a > -90 && a < 90) angles.push_back(a);
    }
    angles.push_back(mirrorDeg);
    std::sort(angles.begin(), angles.end());
    return angles;
}

// Smallest 1, 2, 2.5 or 5 times a power of ten that is >= x.
double niceCeil(double x) {
    const double decade = std::pow(10.0, std::floor(std::log10(x)));
    for (double m : {1.0, 2.0, 2.5, 5.0})
        if (m * decade >= x * (1 - 1e-12)) return m * decade;
    return 10 * decade;
}

// Maps a value to a radius in pixels, the peak just inside the rim, and lists the labelled grid
// circles inside the rim at round values.
class RadialScale {
public:
    RadialScale(double maxValue, double diffuseValue, bool log) : log_(log) {
        if (!(maxValue > 0)) maxValue = 1;  // an all-black material: any scale will do
        top_ = 1.06 * maxValue;
        if (log_) {
            hi_ = std::log10(top_);
            // Show the diffuse lobe down to ~80 degrees, within 2 to 8 decades below the peak.
            const double lowest = diffuseValue > 0 ? std::log10(diffuseValue * 0.15) : hi_ - 4;
            lo_ = std::clamp(std::floor(lowest), std::floor(hi_) - 8, std::floor(hi_) - 2);
            for (double e = lo_ + 1; e < hi_; ++e) circles_.push_back(std::pow(10.0, e));
        } else {
            const double step = niceCeil(top_ / 5);
            for (int k = 1; k * step < top_ * 0.97; ++k) circles_.push_back(k * step);
        }
    }

    double radius(double value) const {
        if (!log_) return kRadius * value / top_;
        if (!(value > 0)) return 0;
        return kRadius * std::max(0.0, (std::log10(value) - lo_) / (hi_ - lo_));
    }

    const std::vector<double>& circles() const { return circles_; }

private:
    bool log_;
    double top_ = 1, lo_ = 0, hi_ = 0;  // rim value; log10 of the centre and rim values
    std::vector<double> circles_;
};

cv::Point2d polar(double thetaDeg, double r) {
    const double t = thetaDeg * kPi / 180;
    return kCenter + cv::Point2d(r * std::sin(t), -r * std::cos(t));
}

cv::Point toPixel(cv::Point2d p) { return cv::Point(int(std::lround(p.x)), int(std::lround(p.y))); }

// Text anchored at `at`; ax, ay in [0, 1] place the anchor within the text box, 0 = left / top.
void text(cv::Mat& img, const std::string& s, cv::Point2d at, double scale, cv::Scalar color,
          double ax = 0, double ay = 1, int thickness = 1) {
    int baseline = 0;
    const cv::Size size = cv::getTextSize(s, kFont, scale, thickness, &baseline);
    const cv::Point2d origin(at.x - ax * size.width, at.y + (1 - ay) * size.height);
    cv::putText(img, s, toPixel(origin), kFont, scale, color, thickness, cv::LINE_AA);
}

void dashedLine(cv::Mat& img, cv::Point2d a, cv::Point2d b, cv::Scalar color, double dash = 8) {
    const double length = cv::norm(b - a);
    for (double s = 0; s < length; s += 2 * dash) {
        const double e = std::min(length, s + dash);
        cv::line(img, toPixel(a + (b - a) * (s / length)), toPixel(a + (b - a) * (e / length)),
                 color, 1, cv::LINE_AA);
    }
}

void semicircle(cv::Mat& img, double r, cv::Scalar color) {
    const int radius = int(std::lround(r));
    cv::ellipse(img, toPixel(kCenter), cv::Size(radius, radius), 0, 180, 360, color, 1,
                cv::LINE_AA);
}

void drawGrid(cv::Mat& img, const RadialScale& scale) {
    // Spokes every 15 degrees, labelled every 30.
    for (int deg = -75; deg <= 75; deg += 15) {
        cv::line(img, toPixel(kCenter), toPixel(polar(deg, kRadius)), kGrid, 1, cv::LINE_AA);
        if (deg % 30 == 0)
            text(img, deg == 0 ? "0 (normal)" : fmt::format("{}", deg), polar(deg, kRadius + 14),
                 0.42, kLabel, 0.5, 0.5);
    }
    for (double v : scale.circles()) {
        semicircle(img, scale.radius(v), kGrid);
        text(img, compact(v), kCenter + cv::Point2d(scale.radius(v), 8), 0.4, kLabel, 0.5, 0);
    }
    semicircle(img, kRadius, kLabel);
}

void drawSurfaceAndDirections(cv::Mat& img, double thetaODeg) {
    const cv::Point2d left = kCenter - cv::Point2d(kRadius + 25, 0);
    const cv::Point2d right = kCenter + cv::Point2d(kRadius + 25, 0);
    for (double x = left.x + 6; x <= right.x; x += 10)  // hatching below the surface
        cv::line(img, toPixel({x, kCenter.y}), toPixel({x - 7, kCenter.y + 7}), kLabel, 1,
                 cv::LINE_AA);
    cv::line(img, toPixel(left), toPixel(right), kBlack, 2, cv::LINE_AA);

    cv::arrowedLine(img, toPixel(kCenter), toPixel(polar(0, 0.25 * kRadius)),
                    cv::Scalar(60, 60, 60), 2, cv::LINE_AA, 0, 0.15);

    const cv::Point2d woTip = polar(-thetaODeg, 0.55 * kRadius);
    cv::arrowedLine(img, toPixel(kCenter), toPixel(woTip), kBlack, 2, cv::LINE_AA, 0, 0.08);
    text(img, "wo", woTip + cv::Point2d(-8, -4), 0.55, kBlack, 1, 1);

    dashedLine(img, kCenter, polar(thetaODeg, kRadius), kBlack);  // labelled in the legend
}

// Top right, on a box in case many entries reach down into the plot: one entry per curve, in
// palette order, then the mirror direction.
void drawLegend(cv::Mat& img, const std::vector<std::string>& curveLabels) {
    std::vector<std::string> labels = curveLabels;
    labels.push_back("mirror of wo");
    int textWidth = 0;
    for (const std::string& label : labels)
        textWidth = std::max(textWidth, cv::getTextSize(label, kFont, 0.45, 1, nullptr).width);
    const auto entry = [](std::size_t row) { return cv::Point2d(570, 82 + 22 * double(row)); };
    cv::rectangle(img, toPixel(entry(0) + cv::Point2d(-8, -13)),
                  toPixel(entry(labels.size() - 1) + cv::Point2d(34 + textWidth + 8, 13)), kWhite,
                  cv::FILLED);
    for (std::size_t k = 0; k < labels.size(); ++k) {
        const cv::Point2d sample = entry(k);
        if (k < curveLabels.size())
            cv::line(img, toPixel(sample), toPixel(sample + cv::Point2d(26, 0)),
                     kPalette[k % std::size(kPalette)], 2, cv::LINE_AA);
        else
            dashedLine(img, sample, sample + cv::Point2d(26, 0), kBlack, 5);
        text(img, labels[k], sample + cv::Point2d(34, 0), 0.45, kBlack, 0, 0.5);
    }
}

}  // namespace

Vec3d planeOfIncidenceDirection(double thetaDeg) {
    const double t = thetaDeg * kPi / 180;
    // cos(pi / 2) rounds to 6e-17: put +-90 degrees exactly on the horizon.
    return Vec3d(std::sin(t), 0, std::abs(thetaDeg) == 90 ? 0.0 : std::cos(t));
}

cv::Mat plotLobes(const LobePlotOptions& options) {
    const Vec3d wo = planeOfIncidenceDirection(-options.thetaODeg);
    const std::vector<double> angles = curveAngles(options.thetaODeg);

    // f cos(theta_i) (luminance) per exponent and angle.
    std::vector<std::vector<double>> curves;
    double maxValue = 0;
    for (double n : options.exponents) {
        const PhongMaterial m{options.kd, options.ks, n};
        std::vector<double>& values = curves.emplace_back();
        for (double a : angles) {
            const Vec3d wi = planeOfIncidenceDirection(a);
            values.push_back(luminance(phongEval(m, wi, wo)) * std::max(0.0, wi.z()));
            maxValue = std::max(maxValue, values.back());
        }
    }
    const RadialScale scale(maxValue, luminance(options.kd) * kInvPi, options.logRadius);

    cv::Mat img(kHeight, kWidth, CV_8UC3, kWhite);
    drawGrid(img, scale);
    drawSurfaceAndDirections(img, options.thetaODeg);

    std::vector<std::string> labels;
    for (std::size_t k = 0; k < curves.size(); ++k) {
        std::vector<cv::Point> points;
        for (std::size_t i = 0; i < angles.size(); ++i)
            points.push_back(toPixel(polar(angles[i], scale.radius(curves[k][i]))));
        cv::polylines(img, points, false, kPalette[k % std::size(kPalette)], 2, cv::LINE_AA);
        labels.push_back("n = " + compact(options.exponents[k]) + "  (peak " +
                         compact(*std::max_element(curves[k].begin(), curves[k].end())) + ")");
    }
    drawLegend(img, labels);
    text(img, "Modified Phong lobe in the plane of incidence", {kWidth / 2.0, 14}, 0.7, kBlack, 0.5,
         0, 2);
    text(img,
         fmt::format("kd = {}   ks = {}   theta_o = {:g} deg", colorText(options.kd),
                     colorText(options.ks), options.thetaODeg),
         {kWidth / 2.0, 44}, 0.55, kBlack, 0.5, 0);
    text(img, "angle: theta_i in degrees,", {14, 82}, 0.45, kLabel, 0, 0.5);
    text(img, "negative on the side of wo", {14, 102}, 0.45, kLabel, 0, 0.5);
    text(img,
         fmt::format("radius: f(wi, wo) cos(theta_i), luminance, {} scale",
                     options.logRadius ? "log" : "linear"),
         {14, 122}, 0.45, kLabel, 0, 0.5);
    return img;
}

}  // namespace phongfit
