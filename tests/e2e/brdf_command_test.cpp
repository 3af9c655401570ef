// `phongfit brdf` end to end, through the built executable.
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <opencv2/imgcodecs.hpp>
#include <random>
#include <sstream>

#include "phong_brdf.h"
#include "temp_dir.h"

namespace phongfit {
namespace {

namespace fs = std::filesystem;

class BrdfCommandTest : public ::testing::Test {
protected:
    // Runs phongfit with `args`; returns its exit code, stdout and stderr in out_ and err_.
    int run(const std::string& args) {
        const std::string command =
            fmt::format("'{}' {} >'{}' 2>'{}'", PHONGFIT_EXE, args, (dir_ / "stdout").string(),
                        (dir_ / "stderr").string());
        const int status = std::system(command.c_str());
        out_ = slurp(dir_ / "stdout");
        err_ = slurp(dir_ / "stderr");
        return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    }

    static std::string slurp(const fs::path& path) {
        std::ifstream in(path);
        std::stringstream s;
        s << in.rdbuf();
        return s.str();
    }
    std::string path(const std::string& name) const { return (dir_ / name).string(); }

    const test::TempDir temp_{"brdf"};
    const fs::path& dir_ = temp_.path();
    std::string out_, err_;
};

struct CsvTable {
    std::vector<std::string> header;
    std::vector<std::vector<double>> rows;
};

CsvTable readCsv(const std::string& path) {
    CsvTable table;
    std::ifstream in(path);
    std::string line;
    std::getline(in, line);
    std::stringstream headerStream(line);
    for (std::string cell; std::getline(headerStream, cell, ',');) table.header.push_back(cell);
    while (std::getline(in, line)) {
        std::vector<double>& row = table.rows.emplace_back();
        std::stringstream rowStream(line);
        for (std::string cell; std::getline(rowStream, cell, ',');) row.push_back(std::stod(cell));
    }
    return table;
}

TEST_F(BrdfCommandTest, WritesPlotAndTableMatchingTheBrdf) {
    ASSERT_EQ(run("brdf --kd 0.5,0.4,0.3 --ks 0.3 --n 20 --n 200 --theta-o 30 -o '" +
                  path("lobe.png") + "' --csv '" + path("lobe.csv") + "'"),
              0)
        << err_;
    EXPECT_NE(out_.find("lobe.png"), std::string::npos) << out_;
    EXPECT_NE(out_.find("lobe.csv"), std::string::npos) << out_;

    const cv::Mat plot = cv::imread(path("lobe.png"));
    ASSERT_FALSE(plot.empty());
    EXPECT_EQ(plot.cols, 800);
    EXPECT_EQ(plot.rows, 600);
    // The first curve is drawn in the first palette colour (BGR 180, 119, 31).
    int blue = 0;
    for (int y = 0; y < plot.rows; ++y)
        for (int x = 0; x < plot.cols; ++x)
            blue += cv::norm(plot.at<cv::Vec3b>(y, x) - cv::Vec3b(180, 119, 31)) < 10;
    EXPECT_GT(blue, 300);

    const CsvTable table = readCsv(path("lobe.csv"));
    EXPECT_EQ(table.header,
              (std::vector<std::string>{"theta_i_deg", "n", "f_r", "f_g", "f_b", "pdf_lafortune",
                                        "pdf_mixture", "pdf_cap", "pdf_cosine", "pdf_uniform"}));
    ASSERT_EQ(table.rows.size(), 2u * 361u);
    const Vec3d wo(-std::sin(kPi / 6), 0, std::cos(kPi / 6));
    int checked = 0;
    for (const std::vector<double>& row : table.rows) {
        ASSERT_EQ(row.size(), 10u);
        const double theta = row[0] * kPi / 180;
        const Vec3d wi(std::sin(theta), 0, std::cos(theta));
        if (row[0] == 30) {  // the mirror direction: the peak of the lobe
            const Color3 f = phongEval(
                PhongMaterial{Color3(0.5, 0.4, 0.3), Color3::Constant(0.3), row[1]}, wi, wo);
            for (int c = 0; c < 3; ++c) EXPECT_NEAR(row[2 + c], f[c], 1e-12 * f[c]);
            EXPECT_NEAR(row[2], 0.5 / kPi + 0.3 * (row[1] + 2) / (2 * kPi), 1e-9);
            ++checked;
        }
        if (std::abs(row[0]) < 90) {
            EXPECT_NEAR(row[8], std::cos(theta) / kPi, 1e-12);  // cosine
            EXPECT_NEAR(row[9], 0.5 / kPi, 1e-12);              // uniform
        } else {
            for (int k = 2; k < 10; ++k) EXPECT_EQ(row[k], 0);  // on the horizon
        }
    }
    EXPECT_EQ(checked, 2);
}

TEST_F(BrdfCommandTest, LogRadiusAndSharpLobe) {
    ASSERT_EQ(run("brdf --kd 0.2 --ks 0.8 --n 1e6 --log -o '" + path("sharp.png") + "'"), 0)
        << err_;
    const cv::Mat plot = cv::imread(path("sharp.png"));
    EXPECT_EQ(plot.size(), cv::Size(800, 600));
}

TEST_F(BrdfCommandTest, RejectsKdPlusKsAboveOneWithoutWritingAnything) {
    EXPECT_NE(run("brdf --kd 0.6 --ks 0.5 --n 10 -o '" + path("bad.png") + "' --csv '" +
                  path("bad.csv") + "'"),
              0);
    EXPECT_NE(err_.find("exceeds 1"), std::string::npos) << err_;
    EXPECT_FALSE(fs::exists(path("bad.png")));
    EXPECT_FALSE(fs::exists(path("bad.csv")));
}

TEST_F(BrdfCommandTest, RejectsMalformedColoursAndNegativeExponents) {
    EXPECT_NE(run("brdf --kd 0.1,0.2 --ks 0.3 --n 10 -o '" + path("a.png") + "'"), 0);
    EXPECT_NE(err_.find("--kd"), std::string::npos) << err_;
    EXPECT_NE(run("brdf --kd 0.1 --ks 0.3 --n=-1 -o '" + path("a.png") + "'"), 0);
    EXPECT_NE(err_.find("exponent n = -1"), std::string::npos) << err_;
    EXPECT_NE(run("brdf --kd nan --ks 0.3 --n 1 -o '" + path("a.png") + "'"), 0);
    EXPECT_NE(err_.find("kd = nan"), std::string::npos) << err_;
    EXPECT_FALSE(fs::exists(path("a.png")));
}

}  // namespace
}  // namespace phongfit
