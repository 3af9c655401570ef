// A polar plot of the Modified Phong lobe in the plane of incidence, for `phongfit brdf`.
#pragma once

#include <opencv2/core.hpp>
#include <vector>

#include "math.h"

namespace phongfit {

// The unit direction in the plane of incidence (x-z) at the signed angle `thetaDeg` from the
// normal, exactly on the horizon at +-90. wo lies at negative angles, its mirror direction at
// positive ones.
Vec3d planeOfIncidenceDirection(double thetaDeg);

struct LobePlotOptions {
    Color3 kd = Color3::Zero(), ks = Color3::Zero();
    std::vector<double> exponents;  // one curve each
    double thetaODeg = 30;
    // Radius on a log scale spanning several decades, so the diffuse part of a sharp lobe stays
    // visible next to its peak.
    bool logRadius = false;
};

// An 800x600 BGR plot of the luminance of f(wi, wo) cos(theta_i) over wi in the plane of incidence:
// grid circles with their values, the surface, the normal, wo and its mirror direction, one curve
// per exponent with a legend, and a title with kd, ks and theta_o.
cv::Mat plotLobes(const LobePlotOptions& options);

}  // namespace phongfit
