// Light sampling checked against closed forms: the irradiance a spherical light gives a point
// facing it, E = L pi sin^2(theta_max), and the density MIS uses for a direction that reaches the
// light by BRDF sampling.
#include "lights.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "chi_square.h"
#include "scene_shapes.h"

namespace phongfit {
namespace {

// One black sphere of radius r emitting L = 1 at (0, 0, d), seen from the origin (normal +z).
Scene sphereLightScene(double d, double r) {
    Scene scene;
    scene.bsdfs.push_back(BsdfDesc{"black", "diffuse", PhongMaterial{}, {}});
    ShapeDesc light;
    light.type = ShapeDesc::Type::Sphere;
    light.center = Vec3d(0, 0, d);
    light.radius = r;
    light.bsdf = 0;
    light.areaRadiance = Color3::Ones();
    scene.shapes.push_back(light);
    return scene;
}

struct IrradianceEstimate {
    double mean = 0, relativeStd = 0;
};

// Monte Carlo estimate of the irradiance at the origin (normal +z) from light 0, one sample per
// draw; also checks every sample: on the sphere, on the side facing the origin, and a density
// that pdfArea gives again for the point where the sampled direction meets the sphere.
IrradianceEstimate irradiance(const Scene& scene, int samples) {
    const EmbreeScene geometry(scene);
    const LightSet lights(scene, geometry);
    const ShapeDesc& sphere = scene.shapes[0];
    std::mt19937_64 rng(7);
    std::uniform_real_distribution<double> uniform(0, 1);
    double sum = 0, squares = 0;
    for (int i = 0; i < samples; ++i) {
        const Vec2d u(uniform(rng), uniform(rng));
        const std::optional<LightSample> s = lights.sample(0, Vec3d::Zero(), u);
        double value = 0;
        if (s) {
            const Vec3d q = s->distance * s->wi;
            EXPECT_NEAR((q - sphere.center).norm(), sphere.radius, 1e-9 * sphere.center.norm());
            const std::optional<Hit> hit = geometry.intersect(Ray{Vec3d::Zero(), s->wi});
            EXPECT_TRUE(hit) << "the sampled direction meets the light";
            if (hit) {
                EXPECT_NEAR(hit->t, s->distance, 1e-5 * s->distance) << "the visible side";
                EXPECT_NEAR(lights.pdfArea(0, Vec3d::Zero(), *hit), s->pdf, 1e-6 * s->pdf);
            }
            value = s->radiance[0] * std::max(0.0, s->wi.z()) / s->pdf;
        }
        sum += value;
        squares += value * value;
    }
    const double mean = sum / samples;
    return {mean, std::sqrt(std::max(0.0, squares / samples - mean * mean)) / mean};
}

TEST(SphereLight, IrradianceMatchesTheClosedFormWithLittleNoise) {
    // theta_max 30, 60 and 0.06 degrees (1 - cos(theta_max) = 5e-7 must keep its digits).
    for (const auto& [d, r] : {std::pair{2.0, 1.0}, std::pair{1.1547, 1.0}, std::pair{1e3, 1.0}}) {
        const double sin2Max = (r / d) * (r / d);
        const double exact = kPi * sin2Max;
        const IrradianceEstimate e = irradiance(sphereLightScene(d, r), 4096);
        // Within the cone the only variation is cos(theta) >= cos(theta_max): a relative
        // standard deviation of at most 0.3 per sample (area sampling of the same sphere wastes
        // the far half and gives about 1.2).
        EXPECT_LT(e.relativeStd, 0.3) << "d " << d;
        EXPECT_NEAR(e.mean, exact, 4 * e.relativeStd * exact / std::sqrt(4096.0) + 1e-10 * exact)
            << "d " << d;
    }
}

TEST(SphereLight, FromInsideItGivesNoLight) {
    const Scene scene = sphereLightScene(0.5, 1.0);  // the origin is inside
    const EmbreeScene geometry(scene);
    const LightSet lights(scene, geometry);
    std::mt19937_64 rng(3);
    std::uniform_real_distribution<double> uniform(0, 1);
    for (int i = 0; i < 256; ++i) {
        const auto s = lights.sample(0, Vec3d::Zero(), Vec2d(uniform(rng), uniform(rng)));
        EXPECT_FALSE(s) << "a sphere emits outwards only";
    }
}

// A mesh light of unequal triangles (a 2 x 1 rectangle split off-centre, and a small triangle
// beside it), sampled on a stratified 256 x 256 grid of the unit square: points are uniform by
// area (chi-square over a grid of cells on the rectangle, and the small triangle's share), and the
// density is the inverse area converted to solid angle.
TEST(MeshLight, StratifiedPointsAreUniformByArea) {
    Scene scene;
    scene.bsdfs.push_back(BsdfDesc{"black", "diffuse", PhongMaterial{}, {}});
    ShapeDesc light;
    light.type = ShapeDesc::Type::Obj;
    light.bsdf = 0;
    light.areaRadiance = Color3::Ones();
    // In the plane z = 1 facing down (-z) towards the origin: clockwise seen from below.
    light.mesh.positions = {{0, 0, 1}, {2, 0, 1}, {2, 1, 1}, {0, 1, 1}, {2.5, 0, 1}, {2.5, 0.5, 1}};
    light.mesh.indices = {0, 2, 1, 0, 3, 2, 1, 5, 4};
    scene.shapes.push_back(light);
    const EmbreeScene geometry(scene);
    const LightSet lights(scene, geometry);
    const double area = 2 + 0.125;
    constexpr int kGrid = 256, kCellsX = 8, kCellsY = 4;
    std::vector<double> observed(kCellsX * kCellsY + 1, 0.0);
    for (int i = 0; i < kGrid; ++i)
        for (int j = 0; j < kGrid; ++j) {
            const Vec2d u((i + 0.5) / kGrid, (j + 0.5) / kGrid);
            const std::optional<LightSample> s = lights.sample(0, Vec3d::Zero(), u);
            ASSERT_TRUE(s);
            const Vec3d q = s->distance * s->wi;
            ASSERT_NEAR(q.z(), 1, 1e-12);
            const double cosLight = s->wi.z();
            ASSERT_NEAR(s->pdf, s->distance * s->distance / (cosLight * area), 1e-9 * s->pdf);
            if (q.x() > 2) {
                ++observed.back();
            } else {
                ASSERT_GE(q.x(), 0);
                ASSERT_LE(q.y(), 1);
                ++observed[std::min(int(q.x() / 2 * kCellsX), kCellsX - 1) * kCellsY +
                           std::min(int(q.y() * kCellsY), kCellsY - 1)];
            }
        }
    const double n = double(kGrid) * kGrid;
    std::vector<double> expected(kCellsX * kCellsY, n * 2 / area / (kCellsX * kCellsY));
    expected.push_back(n * 0.125 / area);
    const ChiSquareResult r = chiSquareTest(observed, expected);
    EXPECT_GE(r.pValue, 0.01) << "chi2 = " << r.statistic;
    // The triangle is picked by u.x alone: its share of a stratified grid is exact to a column.
    EXPECT_NEAR(observed.back(), expected.back(), kGrid);
}

// A rectangle light is sampled as the parallelogram its toWorld makes of [-1, 1]^2 (here sheared,
// and mirrored, which turns its front): a stratified 64 x 64 grid of the unit square puts exactly
// as many points in each of 8 x 8 equal cells of the parallelogram; the density is the inverse area
// converted to solid angle, pdfArea gives it again where the direction meets the light, and light
// leaves the side that emits.
TEST(RectangleLight, StratifiedPointsFillItsParallelogramEvenly) {
    for (const double mirror : {1.0, -1.0}) {
        Eigen::Affine3d toWorld = Eigen::Affine3d::Identity();
        toWorld.linear() << 0.8, 0.3, 0, 0, 0.5 * mirror, 0, 0, 0, 1;
        toWorld.translation() = Vec3d(0.2, -0.1, 2);
        Scene scene;
        scene.bsdfs.push_back(BsdfDesc{"black", "diffuse", PhongMaterial{}, {}});
        ShapeDesc light;
        light.type = ShapeDesc::Type::Rectangle;
        light.mesh = scene_xml::transformed(scene_xml::unitRectangle(), toWorld);
        light.bsdf = 0;
        light.areaRadiance = Color3::Ones();
        scene.shapes.push_back(light);
        const EmbreeScene geometry(scene);
        const LightSet lights(scene, geometry);
        const double area = 4 * 0.8 * 0.5;
        const Eigen::Affine3d toLocal = toWorld.inverse();
        // Seen from below (z = 0) or above (z = 4): the light emits towards one of them.
        for (const double z : {0.0, 4.0}) {
            const Vec3d p(0.1, 0.2, z);
            constexpr int kGrid = 64, kCells = 8;
            std::vector<int> count(kCells * kCells, 0);
            int sampled = 0;
            for (int i = 0; i < kGrid; ++i)
                for (int j = 0; j < kGrid; ++j) {
                    const Vec2d u((i + 0.5) / kGrid, (j + 0.5) / kGrid);
                    const std::optional<LightSample> s = lights.sample(0, p, u);
                    const std::optional<Hit> hit =
                        geometry.intersect(Ray{p, (Vec3d(0.2, -0.1, 2) - p).normalized()});
                    ASSERT_TRUE(hit);
                    const bool front = lights.emitted(*hit, (hit->p - p).normalized())[0] > 0;
                    ASSERT_EQ(bool(s), front) << "z " << z << ", mirror " << mirror;
                    if (!s) continue;
                    ++sampled;
                    const Vec3d q = p + s->distance * s->wi;
                    const Vec3d local = toLocal * q;
                    ASSERT_NEAR(local.z(), 0, 1e-6);
                    ASSERT_LE(std::abs(local.x()), 1 + 1e-6);
                    ASSERT_LE(std::abs(local.y()), 1 + 1e-6);
                    ++count[std::min(int((local.x() + 1) / 2 * kCells), kCells - 1) * kCells +
                            std::min(int((local.y() + 1) / 2 * kCells), kCells - 1)];
                    const double cosLight = std::abs(s->wi.z());
                    // The light's corners are the mesh's float vertices.
                    ASSERT_NEAR(s->pdf, s->distance * s->distance / (cosLight * area),
                                1e-6 * s->pdf);
                    const std::optional<Hit> at = geometry.intersect(Ray{p, s->wi});
                    ASSERT_TRUE(at);
                    ASSERT_NEAR(lights.pdfArea(0, p, *at), s->pdf, 1e-5 * s->pdf);
                }
            if (sampled == 0) continue;
            EXPECT_EQ(sampled, kGrid * kGrid);
            for (const int c : count) EXPECT_EQ(c, kGrid * kGrid / (kCells * kCells));
        }
    }
}

}  // namespace
}  // namespace phongfit
