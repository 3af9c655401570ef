// libFuzzer target: the OBJ loader as scenes use it (tinyobjloader plus phongfit's checks) on
// arbitrary text, from memory. A phongfit::Error is the expected answer to bad input; anything else
// escaping is a bug. A mesh that loads must hold only valid, finite triangles.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <sstream>
#include <string>

#include "error.h"
#include "fuzz_input.h"
#include "obj_mesh.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    // `mtllib` lines look in the scratch directory, which holds no .mtl file.
    static const std::string path = (phongfit::fuzz::scratch().path() / "fuzz.obj").string();
    std::istringstream in(std::string(reinterpret_cast<const char*>(data), size));
    try {
        const phongfit::TriangleMesh mesh = phongfit::readObjMesh(in, path, "fuzz");
        if (mesh.indices.empty() || mesh.indices.size() % 3 != 0) std::abort();
        if (!mesh.normals.empty() && mesh.normals.size() != mesh.positions.size()) std::abort();
        for (const std::uint32_t i : mesh.indices)
            if (i >= mesh.positions.size()) std::abort();
        for (const auto& p : mesh.positions)
            if (!p.allFinite()) std::abort();
        for (const auto& n : mesh.normals)
            if (!n.allFinite() || std::abs(n.norm() - 1) > 1e-3f) std::abort();
    } catch (const phongfit::Error&) {
    }
    return 0;
}
