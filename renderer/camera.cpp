#include "camera.h"

#include <cmath>

namespace phongfit {

Camera::Camera(const SensorDesc& sensor)
    : toWorld_(sensor.toWorld), width_(sensor.width), height_(sensor.height) {
    const double aspect = double(width_) / height_;
    const double tanHalf = std::tan(sensor.fovDegrees * kPi / 360);
    bool alongX = true;
    switch (sensor.fovAxis) {
        case SensorDesc::FovAxis::X:
            alongX = true;
            break;
        case SensorDesc::FovAxis::Y:
            alongX = false;
            break;
        case SensorDesc::FovAxis::Smaller:
            alongX = width_ <= height_;
            break;
        case SensorDesc::FovAxis::Larger:
            alongX = width_ >= height_;
            break;
    }
    tanHalfX_ = alongX ? tanHalf : tanHalf * aspect;
    tanHalfY_ = alongX ? tanHalf / aspect : tanHalf;
}

Ray Camera::generateRay(double x, double y) const {
    const double sx = 2 * x / width_ - 1;   // -1 left .. 1 right
    const double sy = 1 - 2 * y / height_;  // 1 top .. -1 bottom
    const Vec3d local(-sx * tanHalfX_, sy * tanHalfY_, 1);
    Ray ray;
    ray.origin = toWorld_.translation();
    ray.dir = (toWorld_.linear() * local).normalized();
    return ray;
}

}  // namespace phongfit
