// Mitsuba's perspective camera: looks along camera +z, +y up, camera +x to the viewer's left, so
// the image's +x is the viewer's right; row 0 is the top.
#pragma once

#include "embree_scene.h"

namespace phongfit {

class Camera {
public:
    explicit Camera(const SensorDesc& sensor);

    // Primary ray through film position (x, y) in pixels, (0, 0) the top-left corner.
    Ray generateRay(double x, double y) const;

    int width() const { return width_; }
    int height() const { return height_; }

private:
    Eigen::Affine3d toWorld_;
    int width_, height_;
    double tanHalfX_, tanHalfY_;
};

}  // namespace phongfit
