// Wavefront OBJ meshes (through tinyobjloader) for `shape type="obj"`.
#pragma once

#include <cstddef>
#include <cstdint>
#include <istream>
#include <string>

#include "scene.h"

namespace phongfit {

// Reads an OBJ file as triangles in object space; polygons are triangulated, materials and texture
// coordinates ignored. Normals are kept only when every face vertex has one. Throws Error starting
// with `context` (e.g. "scene.xml:12: shape type=\"obj\"") and naming the file when it is missing,
// malformed (bad index, non-finite number, zero normal), holds no face, or is larger than
// kMaxObjBytes or kMaxMeshTriangles.
TriangleMesh loadObjMesh(const std::string& path, const std::string& context);

// As loadObjMesh, from the file's text in `in`; `path` is what messages name. For tools and
// fuzzers that hold the text in memory.
TriangleMesh readObjMesh(std::istream& in, const std::string& path, const std::string& context);

// Limits that keep a hostile or mistaken file from exhausting memory (parsing takes several times
// the file's size).
constexpr std::uintmax_t kMaxObjBytes = std::uintmax_t(1) << 29;  // 512 MiB
constexpr std::size_t kMaxMeshTriangles = std::size_t(1) << 25;   // 33.5 million

}  // namespace phongfit
