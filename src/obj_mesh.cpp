#include "obj_mesh.h"

#include <fmt/format.h>
#include <tiny_obj_loader.h>

#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <utility>

#include "error.h"

namespace phongfit {
namespace {

std::string firstLine(const std::string& s) {
    const std::size_t end = s.find('\n');
    return s.substr(0, end);
}

}  // namespace

TriangleMesh loadObjMesh(const std::string& path, const std::string& context) {
    std::error_code ec;
    if (!std::filesystem::is_regular_file(path, ec))
        throw Error(
            fmt::format("{}: OBJ file '{}' does not exist or is not a file", context, path));
    const std::uintmax_t bytes = std::filesystem::file_size(path, ec);
    if (!ec && bytes > kMaxObjBytes)
        throw Error(fmt::format("{}: OBJ file '{}' is {} MiB (allowed: up to {} MiB)", context,
                                path, bytes >> 20, kMaxObjBytes >> 20));
    std::ifstream in(path);
    if (!in)
        throw Error(
            fmt::format("{}: cannot open OBJ file '{}': {}", context, path, std::strerror(errno)));
    return readObjMesh(in, path, context);
}

TriangleMesh readObjMesh(std::istream& in, const std::string& path, const std::string& context) {
    tinyobj::attrib_t attrib;
    std::vector<tinyobj::shape_t> shapes;
    std::vector<tinyobj::material_t> materials;
    std::string warn, err;
    // No material reader: materials are ignored, and `mtllib` could name any file (/dev/zero).
    if (!tinyobj::LoadObj(&attrib, &shapes, &materials, &warn, &err, &in, /*readMatFn=*/nullptr,
                          /*triangulate=*/true))
        throw Error(
            fmt::format("{}: cannot read OBJ file '{}': {}", context, path, firstLine(err)));

    const auto malformed = [&](const std::string& what) {
        return Error(fmt::format("{}: OBJ file '{}' is malformed: {}", context, path, what));
    };
    const int vertexCount = int(attrib.vertices.size() / 3);
    const int normalCount = int(attrib.normals.size() / 3);
    for (const tinyobj::real_t x : attrib.vertices)
        if (!std::isfinite(x)) throw malformed("a vertex coordinate is not finite");

    // tinyobjloader only warns about out-of-range indices (and drops some such faces silently).
    bool allNormals = true;
    std::size_t cornerCount = 0;
    for (const tinyobj::shape_t& shape : shapes) {
        for (const unsigned char n : shape.mesh.num_face_vertices)
            if (n != 3)
                throw malformed(fmt::format("a face has {} vertices after triangulation", n));
        for (const tinyobj::index_t& idx : shape.mesh.indices) {
            if (idx.vertex_index < 0 || idx.vertex_index >= vertexCount)
                throw malformed(
                    fmt::format("vertex index {} is out of range (the file has {} "
                                "vertices)",
                                idx.vertex_index + 1, vertexCount));
            if (idx.normal_index >= normalCount)
                throw malformed(
                    fmt::format("normal index {} is out of range (the file has {} "
                                "normals)",
                                idx.normal_index + 1, normalCount));
            allNormals = allNormals && idx.normal_index >= 0;
        }
        cornerCount += shape.mesh.indices.size();
    }
    if (warn.find("invalid vertex index") != std::string::npos)
        throw malformed("a polygon has an out-of-range vertex index");
    if (cornerCount / 3 > kMaxMeshTriangles)
        throw Error(fmt::format("{}: OBJ file '{}' has {} triangles (allowed: up to {})", context,
                                path, cornerCount / 3, kMaxMeshTriangles));
    if (cornerCount == 0)
        throw Error(
            fmt::format("{}: OBJ file '{}' has no valid triangles (allowed: a mesh with at "
                        "least one face 'f' of 3 or more vertices)",
                        context, path));

    TriangleMesh mesh;
    mesh.indices.reserve(cornerCount);
    // One output vertex per distinct (position, normal) pair.
    std::map<std::pair<int, int>, std::uint32_t> remap;
    for (const tinyobj::shape_t& shape : shapes) {
        for (const tinyobj::index_t& idx : shape.mesh.indices) {
            const int ni = allNormals ? idx.normal_index : -1;
            const auto [it, inserted] =
                remap.try_emplace({idx.vertex_index, ni}, std::uint32_t(mesh.positions.size()));
            if (inserted) {
                const tinyobj::real_t* v = &attrib.vertices[3 * std::size_t(idx.vertex_index)];
                mesh.positions.emplace_back(v[0], v[1], v[2]);
                if (allNormals) {
                    const tinyobj::real_t* n = &attrib.normals[3 * std::size_t(ni)];
                    // In double: a float's square overflows above 1.8e19 (the normal became 0)
                    // and underflows below 5e-23.
                    const Eigen::Vector3d normal{n[0], n[1], n[2]};
                    const double length = normal.norm();
                    if (!std::isfinite(length) || length == 0)
                        throw malformed(fmt::format("normal {} is zero or not finite", ni + 1));
                    mesh.normals.push_back((normal / length).cast<float>());
                }
            }
            mesh.indices.push_back(it->second);
        }
    }
    return mesh;
}

}  // namespace phongfit
