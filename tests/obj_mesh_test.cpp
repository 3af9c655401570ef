// The OBJ loader's from-memory entry point (what the fuzzer drives) against the file one, and its
// limits.
#include "obj_mesh.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>

#include "error.h"

namespace phongfit {
namespace {

namespace fs = std::filesystem;

class ObjMesh : public ::testing::Test {
protected:
    void SetUp() override {
        dir_ = fs::temp_directory_path() / ("phongfit_obj_" + std::to_string(getpid()) + "_" +
                                            std::to_string(std::random_device{}()));
        fs::create_directories(dir_);
    }
    void TearDown() override { fs::remove_all(dir_); }

    // Error message of reading `text` from memory, or "" if it loaded.
    static std::string errorOf(const std::string& text) {
        std::istringstream in(text);
        try {
            readObjMesh(in, "mem.obj", "ctx");
        } catch (const Error& e) {
            return e.what();
        }
        return "";
    }

    fs::path dir_;
};

TEST_F(ObjMesh, FromMemoryAsFromFile) {
    const std::string text =
        "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvn 0 0 2\nf 1//1 2//1 3//1 4//1\nf -4//1 -2//1 "
        "-1//1\n";
    std::ofstream(dir_ / "m.obj") << text;
    const TriangleMesh fromFile = loadObjMesh((dir_ / "m.obj").string(), "ctx");
    std::istringstream in(text);
    const TriangleMesh fromMemory = readObjMesh(in, "m.obj", "ctx");
    EXPECT_EQ(fromMemory.indices, fromFile.indices);
    ASSERT_EQ(fromMemory.positions.size(), fromFile.positions.size());
    for (std::size_t i = 0; i < fromFile.positions.size(); ++i) {
        EXPECT_EQ(fromMemory.positions[i], fromFile.positions[i]);
        EXPECT_EQ(fromMemory.normals[i], fromFile.normals[i]);
        EXPECT_FLOAT_EQ(fromMemory.normals[i].norm(), 1.0f);
    }
    EXPECT_EQ(fromFile.indices.size(), 9u) << "a quad (two triangles) and a triangle";
}

TEST_F(ObjMesh, MalformedTextIsAnErrorNamingThePathGiven) {
    EXPECT_EQ(errorOf("v 0 0 0\n"),
              "ctx: OBJ file 'mem.obj' has no valid triangles (allowed: a mesh with at least one "
              "face 'f' of 3 or more vertices)");
    EXPECT_NE(
        errorOf("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n").find("vertex index 4 is out of range"),
        std::string::npos);
}

// Found by obj_mesh_fuzz: tinyobjloader converts a joint id beyond int to int (undefined
// behaviour in its parser); the weights are not used, the triangles load.
TEST_F(ObjMesh, SkinWeightsWithHugeJointIdsAreIgnored) {
    std::istringstream in("v 0 0 0\nv 1 0 0\nv 0 1 0\nvw 0 1e39 0.5\nf 1 2 3\n");
    const TriangleMesh mesh = readObjMesh(in, "w.obj", "ctx");
    EXPECT_EQ(mesh.indices.size(), 3u);
    EXPECT_EQ(mesh.positions.size(), 3u);
}

TEST_F(ObjMesh, FileBeyondTheSizeLimitIsRefusedBeforeReading) {
    std::ofstream(dir_ / "big.obj").close();
    fs::resize_file(dir_ / "big.obj", kMaxObjBytes + 1);  // sparse: nothing is written
    try {
        loadObjMesh((dir_ / "big.obj").string(), "ctx");
        FAIL() << "a file beyond the limit was parsed";
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find("(allowed: up to 512 MiB)"), std::string::npos)
            << e.what();
    }
}

}  // namespace
}  // namespace phongfit
