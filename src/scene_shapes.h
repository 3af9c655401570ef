// Built-in shapes as meshes, and where a shape reaches in world space. Internal to the scene
// parser.
#pragma once

#include <Eigen/Geometry>

#include "scene.h"

namespace phongfit::scene_xml {

// Mitsuba's rectangle: [-1, 1]^2 in the z = 0 plane, facing +z.
TriangleMesh unitRectangle();
// Mitsuba's cube: [-1, 1]^3, faces wound counter-clockwise seen from outside.
TriangleMesh unitCube();
// Positions by toWorld, normals by its inverse transpose; a mirror would turn the winding
// inside out, so it is undone.
TriangleMesh transformed(TriangleMesh mesh, const Eigen::Affine3d& toWorld);
// The largest absolute world-space coordinate the shape reaches (infinity if any is not finite).
double worldExtent(const ShapeDesc& shape);

}  // namespace phongfit::scene_xml
