// The envmap emitter: its 2D distribution, its mapping (Mitsuba's lat-long convention), its pdf
// (integrates to 1, matches its sampler by chi-square), the real tiled half-float probe, and
// renders against independent answers: a constant map against the `constant` emitter, a one-texel
// map against a directional light, a diffuse sphere under the probe against a brute-force sum of
// the irradiance over the texels.
#include "environment_map.h"

#include <ImfRgbaFile.h>
#include <ImfTiledRgbaFile.h>
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "chi_square.h"
#include "renderer.h"

namespace phongfit {
namespace {

const std::string kKerner = std::string(PHONGFIT_DATA_DIR) + "/envmaps/KernerEnvLatLong.exr";

// A map with smooth variation, a dark band and one bright texel, so that the sampler has
// something to follow.
Image testMap(int width, int height) {
    Image map(width, height);
    for (int y = 0; y < height; ++y)
        for (int x = 0; x < width; ++x) {
            const float v = y == height / 2 ? 0.0f : 0.2f + float(x) / width + float(y) / height;
            map.set(x, y, Color<float>(v, 0.5f * v, 2 * v));
        }
    map.set(width / 3, height / 4, Color<float>(40, 30, 20));
    return map;
}

Eigen::Matrix3d rotation(const Vec3d& axis, double degrees) {
    return Eigen::AngleAxisd(degrees * kPi / 180, axis.normalized()).toRotationMatrix();
}

TEST(Distribution2D, PicksCellsByWeightAndLeavesAUniformPointWithin) {
    const std::vector<double> weights = {0, 1, 2, 3, 0, 0, 0, 0, 5, 0.5, 0, 1};
    const Distribution2D d(weights, 4, 3);
    double total = 0;
    for (int y = 0; y < 3; ++y)
        for (int x = 0; x < 4; ++x) {
            EXPECT_NEAR(d.probability(x, y), weights[y * 4 + x] / 12.5, 1e-15);
            total += d.probability(x, y);
        }
    EXPECT_NEAR(total, 1, 1e-15);
    std::vector<double> observed(12, 0), expected(12), within(10, 0);
    std::mt19937_64 rng(7);
    std::uniform_real_distribution<double> uniform;
    const int n = 200000;
    for (int i = 0; i < n; ++i) {
        const Distribution2D::Sample s = d.sample(Vec2d(uniform(rng), uniform(rng)));
        ASSERT_GT(weights[s.y * 4 + s.x], 0) << "picked a cell of weight 0";
        ASSERT_TRUE(s.within.x() >= 0 && s.within.x() < 1 && s.within.y() >= 0 && s.within.y() < 1);
        observed[s.y * 4 + s.x] += 1;
        within[int(s.within.x() * 10)] += 1;
    }
    for (int c = 0; c < 12; ++c) expected[c] = n * weights[c] / 12.5;
    EXPECT_GT(chiSquareTest(observed, expected).pValue, 1e-3);
    EXPECT_GT(chiSquareTest(within, std::vector<double>(10, n / 10.0)).pValue, 1e-3);
    // All zero: uniform.
    const Distribution2D flat(std::vector<double>(6, 0), 3, 2);
    EXPECT_DOUBLE_EQ(flat.probability(2, 1), 1.0 / 6);
}

TEST(EnvironmentMap, FollowsMitsubasLatLongConvention) {
    // Mitsuba 0.6 envmap.cpp: u = atan2(d.x, -d.z) / 2pi (wrapped), v = acos(d.y) / pi.
    const struct {
        Vec3d dir;
        double u, v;
    } cases[] = {{Vec3d(0, 0, -1), 0, 0.5},
                 {Vec3d(1, 0, 0), 0.25, 0.5},
                 {Vec3d(0, 0, 1), 0.5, 0.5},
                 {Vec3d(-1, 0, 0), 0.75, 0.5},
                 {Vec3d(0, 1, 0), 0, 0},
                 {Vec3d(0, -1, 0), 0, 1},
                 {Vec3d(1, 1, 0).normalized(), 0.25, 0.25}};
    for (const auto& c : cases) {
        const Vec2d uv = EnvironmentMap::directionToUv(c.dir);
        EXPECT_NEAR(uv.y(), c.v, 1e-12) << c.dir.transpose();
        if (c.v > 0 && c.v < 1) {
            EXPECT_NEAR(uv.x(), c.u, 1e-12) << c.dir.transpose();
        }
        if (c.v > 0 && c.v < 1) {  // at the poles u is arbitrary
            EXPECT_LT((EnvironmentMap::uvToDirection(uv) - c.dir).norm(), 1e-12);
        }
    }
    // Texel centres give the texel's value times the scale; the rotation turns the map.
    const Image map = testMap(16, 8);
    const auto shared = std::make_shared<const Image>(map);
    const EnvironmentMap env(shared, Color3(2, 3, 4), Eigen::Matrix3d::Identity());
    const Eigen::Matrix3d r = rotation(Vec3d(1, 2, 3), 70);
    const EnvironmentMap turned(shared, Color3(2, 3, 4), r);
    for (int y = 0; y < 8; ++y)
        for (int x = 0; x < 16; ++x) {
            const Vec3d d = EnvironmentMap::uvToDirection(Vec2d((x + 0.5) / 16, (y + 0.5) / 8));
            const Color3 expected = map.at(x, y).cast<double>() * Color3(2, 3, 4);
            EXPECT_LT((env.lookup(d).radiance - expected).abs().maxCoeff(),
                      1e-5 * (1 + expected.maxCoeff()));
            EXPECT_LT((turned.lookup(r * d).radiance - expected).abs().maxCoeff(),
                      1e-5 * (1 + expected.maxCoeff()));
        }
    // Halfway between two texel centres across the seam at u = 0: their mean.
    const Color3 seam = env.lookup(EnvironmentMap::uvToDirection(Vec2d(0, 0.5 / 8))).radiance;
    const Color3 mean = 0.5 * (map.at(0, 0) + map.at(15, 0)).cast<double>() * Color3(2, 3, 4);
    EXPECT_LT((seam - mean).abs().maxCoeff(), 1e-5);
}

// Integral over the sphere by the midpoint rule in (phi, cos theta), fine enough for a 16 x 8 map.
template <typename F>
double sphereIntegral(F f, int n = 1024) {
    double sum = 0;
    for (int j = 0; j < n; ++j) {
        const double y = 1 - 2 * (j + 0.5) / n;
        const double s = std::sqrt(1 - y * y);
        for (int i = 0; i < 2 * n; ++i) {
            const double phi = 2 * kPi * (i + 0.5) / (2 * n);
            sum += f(Vec3d(s * std::cos(phi), y, s * std::sin(phi)));
        }
    }
    return sum * 4 * kPi / (2.0 * n * n);
}

TEST(EnvironmentMap, PdfIntegratesToOneAndMatchesItsSamples) {
    for (const bool real : {false, true}) {
        const EnvironmentMap env(
            std::make_shared<const Image>(real ? readImage(kKerner) : testMap(16, 8)),
            Color3::Ones(), rotation(Vec3d(0, 1, 1), 30));
        EXPECT_NEAR(
            sphereIntegral([&](const Vec3d& d) { return env.lookup(d).pdf; }, real ? 2048 : 512), 1,
            1e-3)
            << (real ? "Kerner" : "test map");
        // Samples: pdf and radiance as lookup() says.
        std::mt19937_64 rng(11);
        std::uniform_real_distribution<double> uniform;
        for (int i = 0; i < 2000; ++i) {
            const auto s = env.sample(Vec2d(uniform(rng), uniform(rng)));
            ASSERT_TRUE(s);
            EXPECT_NEAR(s->wi.norm(), 1, 1e-12);
            EXPECT_NEAR(s->pdf, env.lookup(s->wi).pdf, 1e-6 * s->pdf);
            EXPECT_LT((s->radiance - env.lookup(s->wi).radiance).abs().maxCoeff(),
                      1e-4 * (1 + s->radiance.maxCoeff()));
        }
    }
}

TEST(EnvironmentMap, SamplerPassesChiSquareAgainstItsPdf) {
    // Cells in (phi, cos theta) of the world frame, not aligned with the (rotated) texels.
    const EnvironmentMap env(std::make_shared<const Image>(testMap(16, 8)), Color3::Ones(),
                             rotation(Vec3d(1, 0, 1), 25));
    const int nPhi = 24, nY = 12, sub = 24;
    std::vector<double> expected(nPhi * nY, 0), observed(nPhi * nY, 0);
    const long n = 400000;
    for (int j = 0; j < nY; ++j)
        for (int i = 0; i < nPhi; ++i)
            for (int b = 0; b < sub; ++b)
                for (int a = 0; a < sub; ++a) {
                    const double y = 1 - 2 * (j + (b + 0.5) / sub) / nY;
                    const double phi = 2 * kPi * (i + (a + 0.5) / sub) / nPhi;
                    const double s = std::sqrt(1 - y * y);
                    const Vec3d d(s * std::cos(phi), y, s * std::sin(phi));
                    expected[j * nPhi + i] +=
                        n * env.lookup(d).pdf * 4 * kPi / (double(nPhi) * nY * sub * sub);
                }
    std::mt19937_64 rng(3);
    std::uniform_real_distribution<double> uniform;
    for (long k = 0; k < n; ++k) {
        const auto s = env.sample(Vec2d(uniform(rng), uniform(rng)));
        ASSERT_TRUE(s);
        const int j = std::min(nY - 1, int((1 - s->wi.y()) / 2 * nY));
        double phi = std::atan2(s->wi.z(), s->wi.x());
        if (phi < 0) phi += 2 * kPi;
        const int i = std::min(nPhi - 1, int(phi / (2 * kPi) * nPhi));
        observed[j * nPhi + i] += 1;
    }
    const ChiSquareResult r = chiSquareTest(observed, expected);
    EXPECT_GT(r.pValue, 1e-3) << "statistic " << r.statistic << ", dof " << r.dof;
    EXPECT_EQ(r.impossible, 0);
}

TEST(EnvironmentMap, ReadsTheTiledMipMappedHalfProbeAtFullResolution) {
    const Image map = readImage(kKerner);
    ASSERT_EQ(map.width, 1024);
    ASSERT_EQ(map.height, 512);
    // Level (0, 0) read independently, through OpenEXR's tiled RGBA interface.
    Imf::TiledRgbaInputFile file(kKerner.c_str());
    ASSERT_GT(file.numLevels(), 1) << "the probe is mip-mapped";
    const Imath::Box2i window = file.dataWindowForLevel(0, 0);
    const int w = window.max.x - window.min.x + 1, h = window.max.y - window.min.y + 1;
    ASSERT_EQ(w, 1024);
    std::vector<Imf::Rgba> pixels(std::size_t(w) * h);
    file.setFrameBuffer(pixels.data() - window.min.x - window.min.y * w, 1, w);
    file.readTiles(0, file.numXTiles(0) - 1, 0, file.numYTiles(0) - 1, 0, 0);
    double maxDiff = 0, sum = 0;
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            const Imf::Rgba& p = pixels[std::size_t(y) * w + x];
            const Color<float> c = map.at(x, y);
            maxDiff = std::max({maxDiff, std::abs(double(c[0] - float(p.r))),
                                std::abs(double(c[1] - float(p.g))),
                                std::abs(double(c[2] - float(p.b)))});
            sum += c.sum();
        }
    EXPECT_EQ(maxDiff, 0);
    EXPECT_GT(sum, 0);
}

// A unit sphere at the origin seen from (0, 0, 5) looking down -z, under `emitter`.
Scene sphereUnder(const EmitterDesc& emitter, const PhongMaterial& m, int size) {
    Scene scene;
    scene.integrator.type = "direct";
    scene.sensor.fovDegrees = 30;
    scene.sensor.width = scene.sensor.height = size;
    scene.sensor.toWorld.linear() << -1, 0, 0, 0, 1, 0, 0, 0, -1;
    scene.sensor.toWorld.translation() = Vec3d(0, 0, 5);
    scene.bsdfs.push_back(BsdfDesc{"sphere", "phong", m, {}});
    ShapeDesc sphere;
    sphere.type = ShapeDesc::Type::Sphere;
    sphere.bsdf = 0;
    scene.shapes.push_back(sphere);
    scene.emitters.push_back(emitter);
    return scene;
}

EmitterDesc envmapEmitter(const Image& map,
                          const Eigen::Matrix3d& toWorld = Eigen::Matrix3d::Identity(),
                          double scale = 1) {
    EmitterDesc e;
    e.type = EmitterDesc::Type::EnvMap;
    e.map = std::make_shared<const Image>(map);
    e.value = Color3::Constant(scale);
    e.toWorld = toWorld;
    return e;
}

std::vector<float> render(const Scene& scene, int spp) {
    RenderOptions options;
    options.spp = spp;
    options.quiet = true;
    return Renderer(scene).render(options).rgb;
}

// The unit normal where the ray through pixel (x, y)'s centre meets the sphere, if it does.
std::optional<Vec3d> normalAtPixel(const Scene& scene, int x, int y) {
    const Ray ray = Camera(scene.sensor).generateRay(x + 0.5, y + 0.5);
    const double b = ray.origin.dot(ray.dir), c = ray.origin.squaredNorm() - 1;
    if (b * b - c < 0.05) return std::nullopt;  // misses, or too close to the silhouette
    return (ray.origin + (-b - std::sqrt(b * b - c)) * ray.dir).normalized();
}

TEST(EnvironmentMapRender, ConstantMapRendersLikeTheConstantEmitter) {
    Image flat(8, 4);
    for (int y = 0; y < 4; ++y)
        for (int x = 0; x < 8; ++x) flat.set(x, y, Color<float>(0.5f, 1.0f, 2.0f));
    EmitterDesc constant;
    constant.type = EmitterDesc::Type::Constant;
    constant.value = Color3(1, 2, 4);
    PhongMaterial m;
    m.kd = Color3(0.3, 0.4, 0.5);
    m.ks = Color3::Constant(0.4);
    m.n = 20;
    const int size = 32;
    const std::vector<float> a =
        render(sphereUnder(envmapEmitter(flat, rotation(Vec3d(0, 1, 0), 40), 2), m, size), 256);
    const std::vector<float> b = render(sphereUnder(constant, m, size), 256);
    double sumA = 0, sumB = 0, sumSq = 0;
    for (std::size_t i = 0; i < a.size(); ++i) {
        sumA += a[i], sumB += b[i];
        sumSq += (a[i] - b[i]) * (a[i] - b[i]);
        ASSERT_TRUE(std::isfinite(a[i]));
    }
    EXPECT_NEAR(sumA / sumB, 1, 2e-3);
    EXPECT_LT(std::sqrt(sumSq / a.size()) / (sumB / b.size()), 0.02);
    // The background sees the map exactly; a diffuse-only sphere would be kd * radiance.
    EXPECT_FLOAT_EQ(a[0], 1.0f);
    EXPECT_FLOAT_EQ(a[2], 4.0f);
}

TEST(EnvironmentMapRender, OneBrightTexelApproachesADirectionalLight) {
    const int w = 256, h = 128, tx = 150, ty = 50;
    Image map(w, h);
    const float bright = 1000;
    map.set(tx, ty, Color<float>(bright, bright, bright));
    const Eigen::Matrix3d r = rotation(Vec3d(1, 0, 0), -20);
    // The texel's direction and the irradiance its bilinear footprint gives at normal incidence:
    // the tent integrates to one texel's area in (u, v), 1 / (w h), times 2 pi^2 sin(theta).
    const Vec2d uv((tx + 0.5) / w, (ty + 0.5) / h);
    const Vec3d toTexel = r * EnvironmentMap::uvToDirection(uv);
    const double irradiance = bright * 2 * kPi * kPi * std::sin(kPi * uv.y()) / (double(w) * h);
    EmitterDesc sun;
    sun.type = EmitterDesc::Type::Directional;
    sun.direction = -toTexel;
    sun.value = Color3::Constant(irradiance);
    PhongMaterial m;
    m.kd = Color3::Constant(0.8);
    m.ks = Color3::Zero();
    const int size = 32;
    const Scene envScene = sphereUnder(envmapEmitter(map, r), m, size);
    const std::vector<float> a = render(envScene, 64);
    const std::vector<float> b = render(sphereUnder(sun, m, size), 64);
    int compared = 0;
    for (int y = 0; y < size; ++y)
        for (int x = 0; x < size; ++x) {
            const auto n = normalAtPixel(envScene, x, y);
            if (!n || n->dot(toTexel) < 0.3) continue;  // away from the terminator
            const std::size_t i = 3 * (std::size_t(y) * size + x);
            EXPECT_NEAR(a[i] / b[i], 1, 0.01) << "pixel " << x << ", " << y;
            ++compared;
        }
    EXPECT_GT(compared, 150);
}

TEST(EnvironmentMapRender, DiffuseSphereMatchesABruteForceIrradianceSum) {
    const Image map = readImage(kKerner);
    const Eigen::Matrix3d r = rotation(Vec3d(0, 1, 0), 120);
    const double scale = 0.7;
    PhongMaterial m;
    m.kd = Color3(0.6, 0.5, 0.4);
    m.ks = Color3::Zero();
    const int size = 48;
    const Scene scene = sphereUnder(envmapEmitter(map, r, scale), m, size);
    const std::vector<float> image = render(scene, 512);
    // Every texel as a small source of solid angle (2 pi / w)(cos theta0 - cos theta1) at its
    // centre's direction, rotated to the world.
    struct Texel {
        Vec3d dir;
        Color3 power;
    };
    std::vector<Texel> texels;
    for (int y = 0; y < map.height; ++y) {
        const double solidAngle =
            2 * kPi / map.width *
            (std::cos(kPi * y / map.height) - std::cos(kPi * (y + 1) / map.height));
        for (int x = 0; x < map.width; ++x) {
            const double phi = 2 * kPi * (x + 0.5) / map.width,
                         theta = kPi * (y + 0.5) / map.height;
            const Vec3d local(std::sin(theta) * std::sin(phi), std::cos(theta),
                              -std::sin(theta) * std::cos(phi));
            texels.push_back({r * local, map.at(x, y).cast<double>() * scale * solidAngle});
        }
    }
    double sumAbs = 0, sumRef = 0, sumSigned = 0;
    int compared = 0;
    for (int y = 1; y < size; y += 4)
        for (int x = 1; x < size; x += 4) {
            const auto n = normalAtPixel(scene, x, y);
            if (!n) continue;
            Color3 e = Color3::Zero();
            for (const Texel& t : texels) e += t.power * std::max(0.0, n->dot(t.dir));
            const Color3 expected = m.kd * kInvPi * e;
            for (int c = 0; c < 3; ++c) {
                const double got = image[3 * (std::size_t(y) * size + x) + c];
                sumAbs += std::abs(got - expected[c]);
                sumSigned += got - expected[c];
                sumRef += expected[c];
            }
            ++compared;
        }
    ASSERT_GT(compared, 60);
    EXPECT_LT(sumAbs / sumRef, 0.01) << "mean relative error; bias " << sumSigned / sumRef;
    EXPECT_LT(std::abs(sumSigned) / sumRef, 0.003) << "bias";
}

}  // namespace
}  // namespace phongfit
