// Wavefront OBJ meshes (through tinyobjloader) for `shape type="obj"`.
#pragma once

#include <string>

#include "scene.h"

namespace phongfit {

// Reads an OBJ file as triangles in object space; polygons are triangulated, materials and texture
// coordinates ignored. Normals are kept only when every face vertex has one. Throws Error starting
// with `context` (e.g. "scene.xml:12: shape type=\"obj\"") and naming the file when it is missing,
// malformed (bad index, non-finite number, zero normal) or holds no face.
TriangleMesh loadObjMesh(const std::string& path, const std::string& context);

}  // namespace phongfit
