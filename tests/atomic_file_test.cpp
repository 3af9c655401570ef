#include "atomic_file.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <fstream>
#include <random>
#include <sstream>
#include <stdexcept>

#include "error.h"
#include "temp_dir.h"

namespace phongfit {
namespace {

namespace fs = std::filesystem;

class AtomicFileTest : public ::testing::Test {
protected:
    static std::string read(const fs::path& path) {
        std::ifstream in(path);
        std::stringstream s;
        s << in.rdbuf();
        return s.str();
    }
    static void put(const fs::path& path, const std::string& text) { std::ofstream(path) << text; }
    std::vector<std::string> entries() const {
        std::vector<std::string> names;
        for (const auto& e : fs::directory_iterator(dir_)) names.push_back(e.path().filename());
        return names;
    }

    const test::TempDir temp_{"atomic"};
    const fs::path& dir_ = temp_.path();
};

TEST_F(AtomicFileTest, WritesThroughATemporaryInTheSameDirectoryWithTheSameExtension) {
    const fs::path target = dir_ / "out.png";
    fs::path seen;
    writeAtomically(target, [&](const fs::path& temporary) {
        seen = temporary;
        EXPECT_FALSE(fs::exists(target));  // nothing visible until complete
        put(temporary, "new");
    });
    EXPECT_EQ(seen.parent_path(), target.parent_path());
    EXPECT_EQ(seen.extension(), ".png");
    EXPECT_NE(seen.filename(), target.filename());
    EXPECT_EQ(read(target), "new");
    EXPECT_EQ(entries(), std::vector<std::string>{"out.png"});
}

TEST_F(AtomicFileTest, ReplacesAnExistingTarget) {
    const fs::path target = dir_ / "out.txt";
    put(target, "old");
    writeAtomically(target, [&](const fs::path& temporary) { put(temporary, "new"); });
    EXPECT_EQ(read(target), "new");
    EXPECT_EQ(entries(), std::vector<std::string>{"out.txt"});
}

TEST_F(AtomicFileTest, ExceptionKeepsOldTargetRemovesTemporaryAndIsRethrown) {
    const fs::path target = dir_ / "out.txt";
    put(target, "old");
    EXPECT_THROW(writeAtomically(target,
                                 [&](const fs::path& temporary) {
                                     put(temporary, "half-writ");
                                     throw std::runtime_error("disk full");
                                 }),
                 std::runtime_error);
    EXPECT_EQ(read(target), "old");
    EXPECT_EQ(entries(), std::vector<std::string>{"out.txt"});
}

TEST_F(AtomicFileTest, ExceptionWithoutOldTargetLeavesNothing) {
    EXPECT_THROW(writeAtomically(dir_ / "out.txt",
                                 [&](const fs::path& temporary) {
                                     put(temporary, "half");
                                     throw Error("encoder failed");
                                 }),
                 Error);
    EXPECT_TRUE(entries().empty());
}

TEST_F(AtomicFileTest, MissingDirectoryIsAnErrorNamingIt) {
    const fs::path target = dir_ / "no_such_dir" / "out.txt";
    bool called = false;
    try {
        writeAtomically(target, [&](const fs::path&) { called = true; });
        FAIL() << "expected Error";
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find("no_such_dir"), std::string::npos) << e.what();
    }
    EXPECT_FALSE(called);
}

TEST_F(AtomicFileTest, WriterThatCreatesNoFileIsAnError) {
    const fs::path target = dir_ / "out.txt";
    put(target, "old");
    EXPECT_THROW(writeAtomically(target, [](const fs::path&) {}), Error);
    EXPECT_EQ(read(target), "old");
}

}  // namespace
}  // namespace phongfit
