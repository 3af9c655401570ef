// Shared by the libFuzzer targets: the input as a file the tool's readers can open (they take
// paths, as the command line does), in a per-process temporary directory removed at exit.
#pragma once

#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <string>

#include "error.h"
#include "image.h"

namespace phongfit::fuzz {

class ScratchDir {
public:
    ScratchDir()
        : path_(std::filesystem::temp_directory_path() /
                ("phongfit_fuzz_" + std::to_string(getpid()))) {
        std::filesystem::create_directories(path_);
    }
    ~ScratchDir() {
        std::error_code ec;
        std::filesystem::remove_all(path_, ec);
    }
    const std::filesystem::path& path() const { return path_; }

    // Writes `data` to `name` in the directory and returns its path.
    std::string write(const std::string& name, const std::uint8_t* data, std::size_t size) const {
        const std::filesystem::path file = path_ / name;
        std::ofstream(file, std::ios::binary | std::ios::trunc)
            .write(reinterpret_cast<const char*>(data), std::streamsize(size));
        return file.string();
    }

private:
    std::filesystem::path path_;
};

inline const ScratchDir& scratch() {
    static const ScratchDir dir;
    return dir;
}

// readImage on the input written as `name`, whose extension picks the reader, with each of
// `options`: a phongfit::Error is the expected answer to a bad file; an image of the wrong shape
// is a bug.
inline void readImageOrError(const std::uint8_t* data, std::size_t size, const std::string& name,
                             std::initializer_list<ReadOptions> options = {ReadOptions{}}) {
    const std::string path = scratch().write(name, data, size);
    for (const ReadOptions& o : options) {
        try {
            const Image image = readImage(path, o);
            if (image.width <= 0 || image.height <= 0 ||
                image.rgb.size() != 3 * image.pixelCount() ||
                (!image.noData.empty() && image.noData.size() != image.pixelCount()))
                std::abort();
        } catch (const Error&) {
        }
    }
}

// The directory scene inputs resolve relative names in: the scratch directory, holding one small
// mesh, `mesh.obj`, so that obj shapes are reached too.
inline const std::string& sceneBaseDir() {
    static const std::string dir = [] {
        const std::string mesh = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 3 4\n";
        scratch().write("mesh.obj", reinterpret_cast<const std::uint8_t*>(mesh.data()),
                        mesh.size());
        return scratch().path().string();
    }();
    return dir;
}

}  // namespace phongfit::fuzz
