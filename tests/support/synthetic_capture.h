// A synthetic photometric-stereo capture in the DiLiGenT layout, for the capture tests.
#pragma once

#include <fmt/format.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <opencv2/imgcodecs.hpp>
#include <random>
#include <string>
#include <vector>

#include "capture.h"
#include "phong_brdf.h"

namespace phongfit::test {

// A sphere under distant lights, rendered with the project's BRDF on the known normals, with
// Gaussian noise, written as linear 16-bit PNGs (so the brightest highlights clip at 65535).
struct Synthetic {
    static constexpr int kSize = 48;
    static constexpr int kLights = 30;
    static constexpr double kNoise = 0.002;  // in 16-bit linear units, before quantisation
    PhongMaterial truth;
    // If set, the diffuse albedo at pixel (x, y) instead of truth.kd: a textured object.
    std::function<Color3(int x, int y)> albedo;
    // If set, the whole material at pixel (x, y): an object of several materials.
    std::function<PhongMaterial(int x, int y)> materialAt;
    int lights = kLights;  // DiLiGenT has 96
    // > 0: every light has this intensity, and light_intensities.txt says kWrittenIntensity for
    // each (intensities known only up to a common factor); in the images' units kd and ks are then
    // commonIntensity / kWrittenIntensity times the truth.
    double commonIntensity = 0;
    static constexpr double kWrittenIntensity = 0.1;

    Synthetic() {
        truth.kd = Color3(0.4, 0.3, 0.2);
        truth.ks = Color3(0.2, 0.25, 0.3);
        truth.n = 60;
    }

    static Vec3d lightDirection(int i, int count = kLights) {
        // Rings of lights at 10 to 50 degrees from the view, as in a photometric-stereo dome.
        const double theta = (10 + 40 * double(i % 5) / 4) * kPi / 180;
        const double phi = 2 * kPi * i / count + i % 5;
        return Vec3d(std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi),
                     std::cos(theta));
    }

    static std::optional<Vec3d> normal(int x, int y) {
        const double r = 0.45 * kSize;
        const double nx = (x + 0.5 - kSize / 2.0) / r, ny = (kSize / 2.0 - y - 0.5) / r;
        const double z2 = 1 - nx * nx - ny * ny;
        if (z2 <= 0.01) return std::nullopt;
        return Vec3d(nx, ny, std::sqrt(z2));
    }

    void write(const std::filesystem::path& dir) const {
        std::mt19937 rng(7);
        std::normal_distribution<double> noise(0, kNoise);
        std::uniform_real_distribution<double> intensity(0.25, 0.45);
        Image normals(kSize, kSize);
        cv::Mat mask(kSize, kSize, CV_8U, cv::Scalar(0));
        for (int y = 0; y < kSize; ++y)
            for (int x = 0; x < kSize; ++x)
                if (const auto n = normal(x, y)) {
                    normals.set(x, y, n->cast<float>().array());
                    mask.at<uchar>(y, x) = 255;
                }
        writeExr(normals, (dir / "normals.exr").string());
        cv::imwrite((dir / "mask.png").string(), mask);
        std::ofstream names(dir / "filenames.txt"), directions(dir / "light_directions.txt"),
            intensities(dir / "light_intensities.txt");
        for (int i = 0; i < lights; ++i) {
            const Vec3d l = lightDirection(i, lights);
            const Color3 e = commonIntensity > 0
                                 ? Color3::Constant(commonIntensity)
                                 : Color3(intensity(rng), intensity(rng), intensity(rng));
            const std::string name = fmt::format("{:03d}.png", i + 1);
            names << name << "\n";
            directions << fmt::format("{} {} {}\n", l.x(), l.y(), l.z());
            const Color3 written = commonIntensity > 0 ? Color3::Constant(kWrittenIntensity) : e;
            intensities << fmt::format("{} {} {}\n", written[0], written[1], written[2]);
            cv::Mat image(kSize, kSize, CV_16UC3, cv::Scalar(0, 0, 0));
            for (int y = 0; y < kSize; ++y)
                for (int x = 0; x < kSize; ++x) {
                    const auto n = normal(x, y);
                    if (!n) continue;
                    const Frame<double> frame(*n);
                    const Vec3d wi = frame.toLocal(l), wo = frame.toLocal(Vec3d(0, 0, 1));
                    PhongMaterial m = truth;
                    if (albedo) m.kd = albedo(x, y);
                    if (materialAt) m = materialAt(x, y);
                    const Color3 f = phongEval(m, wi, wo);
                    for (int c = 0; c < 3; ++c) {
                        const double v = e[c] * std::max(wi.z(), 0.0) * f[c] + noise(rng);
                        image.at<cv::Vec3w>(y, x)[2 - c] =
                            cv::saturate_cast<ushort>(std::lround(65535 * std::clamp(v, 0.0, 1.0)));
                    }
                }
            cv::imwrite((dir / name).string(), image);
        }
    }
};

inline std::vector<int> range(int first, int last, int step = 1) {
    std::vector<int> v;
    for (int i = first; i <= last; i += step) v.push_back(i);
    return v;
}

}  // namespace phongfit::test
