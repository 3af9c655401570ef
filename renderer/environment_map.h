// Mitsuba 0.6's `envmap` emitter: radiance arriving from every direction, read from a lat-long map
// (+y up in the emitter's frame; the direction (x, y, z) is at u = atan2(x, -z) / 2pi, wrapped to
// [0, 1), and v = acos(y) / pi, v = 0 at the top row), bilinearly interpolated between texel
// centres (wrapping in u, clamped in v), times a scale, turned by a rotation. The interpolant is a
// sum of tents, one per texel, so it is sampled exactly: a texel with probability proportional to
// its luminance times sin(theta), then a point of its tent; the pdf is the same interpolation of
// the texels' probabilities (docs/design/sampling.md).
#pragma once

#include <Eigen/Core>
#include <memory>
#include <optional>

#include "distribution_2d.h"
#include "image.h"

namespace phongfit {

class EnvironmentMap {
public:
    // map: finite and nonnegative (scene_parser checks it), shared with the scene; toWorld: a
    // rotation.
    EnvironmentMap(std::shared_ptr<const Image> map, const Color3& scale,
                   const Eigen::Matrix3d& toWorld);

    struct Lookup {
        Color3 radiance;
        double pdf;  // solid angle, with which sample() returns the direction
    };
    // Radiance arriving from the unit world direction `dir` (towards where it comes from), and
    // the density of sampling it.
    Lookup lookup(const Vec3d& dir) const;

    struct DirectionSample {
        Vec3d wi;  // unit, world
        Color3 radiance;
        double pdf;  // solid angle
    };
    std::optional<DirectionSample> sample(const Vec2d& u) const;

    // The map's (u, v) of a unit direction in the emitter's frame, and back.
    static Vec2d directionToUv(const Vec3d& local);
    static Vec3d uvToDirection(const Vec2d& uv);

private:
    // The four texels around uv and their bilinear weights.
    struct Footprint {
        int x0, x1, y0, y1;
        double tx, ty;
    };
    Footprint footprint(const Vec2d& uv) const;
    Color3 radianceAt(const Footprint& f) const;
    double pdfUvAt(const Footprint& f) const;

    std::shared_ptr<const Image> map_;
    Color3 scale_;
    Eigen::Matrix3d toWorld_;
    Distribution2D distribution_;
    std::vector<double> density_;  // per texel: its probability times width x height
};

}  // namespace phongfit
