// Renders checked against closed forms: a Phong sphere under a point light (direct light, every
// interior pixel box-filtered analytically), the furnace (a closed emitting diffuse enclosure), and
// a floor under a rectangle light.
#include "renderer.h"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include "error.h"
#include "error_of.h"
#include "scene_parser.h"

namespace phongfit {
namespace {

Eigen::Affine3d lookAt(const Vec3d& origin, const Vec3d& target, const Vec3d& up) {
    const Vec3d dir = (target - origin).normalized();
    const Vec3d left = up.cross(dir).normalized();
    Eigen::Affine3d m = Eigen::Affine3d::Identity();
    m.linear().col(0) = left;
    m.linear().col(1) = dir.cross(left);
    m.linear().col(2) = dir;
    m.translation() = origin;
    return m;
}

// One Phong sphere (radius 1 at the origin) seen from +z, lit by a point light.
Scene sphereScene(const PhongMaterial& material, int size) {
    Scene scene;
    scene.integrator.type = "direct";
    scene.sensor.fovDegrees = 30;
    scene.sensor.width = scene.sensor.height = size;
    scene.sensor.toWorld = lookAt(Vec3d(0, 0, 5), Vec3d(0, 0, 0), Vec3d(0, 1, 0));
    scene.bsdfs.push_back(BsdfDesc{"sphere", "phong", material, {}});
    ShapeDesc sphere;
    sphere.type = ShapeDesc::Type::Sphere;
    sphere.radius = 1;
    sphere.bsdf = 0;
    scene.shapes.push_back(sphere);
    EmitterDesc light;
    light.type = EmitterDesc::Type::Point;
    light.position = Vec3d(2, 3, 4);
    light.value = Color3(20, 15, 10);
    scene.emitters.push_back(light);
    return scene;
}

// Radiance along a camera ray, written from the formulas in world space (long double), independent
// of the renderer's local-frame code. NaN where the ray misses the sphere.
long double analyticRadiance(const Scene& scene, const Ray& ray, int channel) {
    const PhongMaterial& m = scene.bsdfs[0].params;
    const Vec3d& o = ray.origin;
    const Vec3d& d = ray.dir;
    const long double b = o.dot(d), c = o.squaredNorm() - 1.0L;
    const long double disc = b * b - c;
    if (disc < 0) return NAN;
    const long double t = -b - std::sqrt(disc);
    const long double px = o.x() + t * d.x(), py = o.y() + t * d.y(), pz = o.z() + t * d.z();
    const long double n[3] = {px, py, pz};  // unit: the sphere has radius 1 at the origin
    const Vec3d& l = scene.emitters[0].position;
    long double wi[3] = {l.x() - px, l.y() - py, l.z() - pz};
    const long double dist2 = wi[0] * wi[0] + wi[1] * wi[1] + wi[2] * wi[2];
    for (auto& w : wi) w /= std::sqrt(dist2);
    const long double wo[3] = {-d.x(), -d.y(), -d.z()};
    const long double cosI = n[0] * wi[0] + n[1] * wi[1] + n[2] * wi[2];
    const long double cosO = n[0] * wo[0] + n[1] * wo[1] + n[2] * wo[2];
    if (cosI <= 0 || cosO <= 0) return 0;
    long double cosAlpha = 0;  // mirror of wo about n, dotted with wi
    for (int k = 0; k < 3; ++k) cosAlpha += (2 * cosO * n[k] - wo[k]) * wi[k];
    const long double spec =
        cosAlpha > 0 ? (m.n + 2) / (2 * M_PIl) * std::pow(cosAlpha, (long double)m.n) : 0;
    const long double f = m.kd[channel] / M_PIl + m.ks[channel] * spec;
    return f * cosI * scene.emitters[0].value[channel] / dist2;
}

struct AnalyticCase {
    double kd, ks, n;
    int spp;
};

// The pixel's box-filtered reference by midpoint quadrature; NaN if any part misses the sphere.
// Sub-pixel highlights (n = 5000 spans ~0.1 pixel here) get a much finer grid.
Color<long double> boxFilteredReference(const Scene& scene, const Camera& camera, int x, int y,
                                        int sub) {
    Color<long double> sum = Color<long double>::Zero();
    long double lo = INFINITY, hi = 0;
    for (int j = 0; j < sub; ++j)
        for (int i = 0; i < sub; ++i) {
            const Ray ray = camera.generateRay(x + (i + 0.5) / sub, y + (j + 0.5) / sub);
            for (int ch = 0; ch < 3; ++ch) {
                const long double v = analyticRadiance(scene, ray, ch);
                if (std::isnan(v)) return Color<long double>::Constant(NAN);
                sum[ch] += v / (sub * sub);
                if (ch == 0) lo = std::min(lo, v), hi = std::max(hi, v);
            }
        }
    if (sub < 64 && hi > 2 * lo + 1e-3) return boxFilteredReference(scene, camera, x, y, 64);
    return sum;
}

class AnalyticSphere : public ::testing::TestWithParam<AnalyticCase> {};

TEST_P(AnalyticSphere, InteriorPixelsMatchTheBoxFilteredClosedForm) {
    const AnalyticCase& c = GetParam();
    PhongMaterial m;
    m.kd = Color3(c.kd, 0.8 * c.kd, 0.6 * c.kd);
    m.ks = Color3::Constant(c.ks);
    m.n = c.n;
    const int size = 48;
    const Scene scene = sphereScene(m, size);
    RenderOptions options;
    options.spp = c.spp;
    options.quiet = true;
    const RenderResult r = Renderer(scene).render(options);

    const Camera camera(scene.sensor);
    long double sumAbsErr = 0, sumRef = 0;
    int interior = 0;
    for (int y = 0; y < size; ++y)
        for (int x = 0; x < size; ++x) {
            const Color<long double> ref = boxFilteredReference(scene, camera, x, y, 8);
            if (std::isnan(ref[0])) continue;
            ++interior;
            for (int ch = 0; ch < 3; ++ch) {
                sumAbsErr += std::abs(r.rgb[3 * (y * size + x) + ch] - ref[ch]);
                sumRef += ref[ch];
            }
        }
    ASSERT_GT(interior, 500);
    // The Sobol pixel sampler leaves 1e-4 to 2.5e-4 at these spp: 0.2% is a bias, not noise.
    EXPECT_LT(double(sumAbsErr / sumRef), 0.002)
        << "mean relative error over " << interior << " pixels";
}

INSTANTIATE_TEST_SUITE_P(Materials, AnalyticSphere,
                         ::testing::Values(AnalyticCase{0.5, 0.3, 30, 256},
                                           AnalyticCase{0.8, 0.0, 1, 256},
                                           AnalyticCase{0.0, 0.9, 10, 256},
                                           AnalyticCase{0.1, 0.5, 300, 2048},
                                           AnalyticCase{0.2, 0.8, 5000, 4096}),
                         [](const ::testing::TestParamInfo<AnalyticCase>& info) {
                             return fmt::format("n{}_spp{}", info.param.n, info.param.spp);
                         });

// A closed box, faces towards the inside, every face emitting Le and reflecting diffusely with
// albedo rho: radiance is Le / (1 - rho) everywhere.
Scene furnaceScene(double rho, double le) {
    Scene scene;
    scene.integrator.maxDepth = -1;
    scene.integrator.rrDepth = 5;
    scene.sensor.fovDegrees = 60;
    scene.sensor.width = scene.sensor.height = 16;
    scene.sensor.toWorld = lookAt(Vec3d(0.1, 0.2, 0.3), Vec3d(1, 0.5, -0.7), Vec3d(0, 1, 0));
    PhongMaterial m;
    m.kd = Color3(rho, rho, rho);
    scene.bsdfs.push_back(BsdfDesc{"wall", "diffuse", m, {}});
    ShapeDesc box;
    box.type = ShapeDesc::Type::Obj;
    box.bsdf = 0;
    box.areaRadiance = Color3::Constant(le);
    for (int i = 0; i < 8; ++i)
        box.mesh.positions.emplace_back(i & 1 ? 1.f : -1.f, i & 2 ? 1.f : -1.f, i & 4 ? 1.f : -1.f);
    // Each face wound clockwise seen from outside, i.e. front side inwards.
    const std::uint32_t faces[6][4] = {{0, 1, 3, 2}, {4, 6, 7, 5}, {0, 4, 5, 1},
                                       {2, 3, 7, 6}, {0, 2, 6, 4}, {1, 5, 7, 3}};
    for (const auto& f : faces) {
        box.mesh.indices.insert(box.mesh.indices.end(), {f[0], f[1], f[2], f[0], f[2], f[3]});
    }
    scene.shapes.push_back(box);
    return scene;
}

TEST(Furnace, RadianceIsEmissionOverOneMinusAlbedo) {
    const double rho = 0.5, le = 0.7;
    const Scene scene = furnaceScene(rho, le);
    const double expected = le / (1 - rho);
    for (const PixelSamplerType type : {PixelSamplerType::Independent, PixelSamplerType::Sobol}) {
        SCOPED_TRACE(pixelSamplerName(type));
        // Faces must point inwards for the test to mean anything.
        RenderOptions options;
        options.spp = 512;
        options.quiet = true;
        options.pixelSampler = type;
        const RenderResult r = Renderer(scene).render(options);
        double mean = 0, meanVar = 0;
        for (std::size_t i = 0; i < r.rgb.size(); ++i) {
            mean += r.rgb[i];
            meanVar += r.variance[i];
        }
        mean /= r.rgb.size();
        // The sample variance of stratified samples overstates the error: a safe bound.
        const double stdErr = std::sqrt(meanVar) / r.rgb.size();
        EXPECT_NEAR(mean, expected, 5 * stdErr + 1e-4 * expected) << "standard error " << stdErr;
        for (std::size_t i = 0; i < r.rgb.size(); ++i)
            ASSERT_NEAR(r.rgb[i], expected, 6 * std::sqrt(r.variance[i]) + 1e-3)
                << "pixel " << i / 3;
    }
}

// For every pixel sampler: the Sobol ones are as counter-based as the independent one.
TEST(Determinism, SameSeedSameImageWhateverTheThreadCount) {
    PhongMaterial m;
    m.kd = Color3(0.4, 0.5, 0.6);
    m.ks = Color3::Constant(0.3);
    m.n = 50;
    Scene scene = furnaceScene(0.6, 1.0);
    scene.shapes.push_back(sphereScene(m, 8).shapes[0]);
    scene.shapes.back().radius = 0.3;
    scene.shapes.back().center = Vec3d(0.5, 0.3, -0.4);
    scene.bsdfs.push_back(BsdfDesc{"sphere", "phong", m, {}});
    scene.shapes.back().bsdf = 1;
    scene.sensor.width = scene.sensor.height = 40;
    const Renderer renderer(scene);
    std::vector<float> previous;
    for (const PixelSamplerType type :
         {PixelSamplerType::Independent, PixelSamplerType::Sobol, PixelSamplerType::Padded}) {
        SCOPED_TRACE(pixelSamplerName(type));
        RenderOptions options;
        options.spp = 8;
        options.seed = 7;
        options.quiet = true;
        options.pixelSampler = type;
        options.threads = 1;
        const RenderResult one = renderer.render(options);
        options.threads = 2;
        const RenderResult two = renderer.render(options);
        options.threads = 5;
        const RenderResult five = renderer.render(options);
        EXPECT_EQ(one.rgb, two.rgb);
        EXPECT_EQ(one.rgb, five.rgb);
        EXPECT_NE(one.rgb, previous);
        previous = one.rgb;
        options.seed = 8;
        EXPECT_NE(one.rgb, renderer.render(options).rgb);
    }
}

// Pixels left out of a render (a fit's comparison renders only the pixels it compares, its
// rendered noise only the pixels that hold a parameter) take no sample and read 0; the others are
// the full render's to the bit, their samples being keyed by the pixel, with a box filter, a
// Gaussian or a tent (importance-sampled: each sample is its own pixel's, none reaches a
// neighbour). A mask of the wrong size is refused.
TEST(Determinism, PixelsLeftOutTakeNoSampleAndTheOthersAreTheFullRenders) {
    PhongMaterial m;
    m.kd = Color3(0.4, 0.5, 0.6);
    m.ks = Color3::Constant(0.3);
    m.n = 50;
    Scene scene = sphereScene(m, 8);
    scene.sensor.width = scene.sensor.height = 24;
    RenderOptions options;
    options.spp = 4;
    options.seed = 3;
    options.quiet = true;
    std::vector<std::uint8_t> rendered(24 * 24, 0);
    for (std::size_t p = 0; p < rendered.size(); p += 3) rendered[p] = 1;
    for (const SensorDesc::Filter filter :
         {SensorDesc::Filter::Box, SensorDesc::Filter::Gaussian, SensorDesc::Filter::Tent}) {
        scene.sensor.filter = filter;
        const Renderer renderer(scene);
        options.rendered = {};
        const RenderResult full = renderer.render(options);
        options.rendered = rendered;
        const RenderResult part = renderer.render(options);
        EXPECT_EQ(part.stats.samples, full.stats.samples / 3);
        for (std::size_t p = 0; p < rendered.size(); ++p) {
            EXPECT_EQ(part.sampleCount[p], rendered[p] ? 4u : 0u) << "pixel " << p;
            for (int c = 0; c < 3; ++c)
                EXPECT_EQ(part.rgb[3 * p + c], rendered[p] ? full.rgb[3 * p + c] : 0.0f)
                    << "pixel " << p;
        }
        EXPECT_GT(*std::max_element(part.rgb.begin(), part.rgb.end()), 0.0f);
    }
    const std::vector<std::uint8_t> wrong(10, 1);
    options.rendered = wrong;
    EXPECT_EQ(test::errorOf([&] { Renderer(scene).render(options); }),
              "render: 10 rendered-pixel flags given for a 24x24 film");
}

// A window of the film renders its pixels as the whole film does, to the bit (their samples are
// keyed by the pixel's index on the whole film), and a bsdf rendered with other parameters, or the
// film with another pixel filter, renders as the scene that holds them: what a fit's renders of a
// few pixels at its estimate rely on. A window off the film, parameters that are not one per
// listed bsdf of the scene, and a filter width out of range are refused.
TEST(Determinism, AWindowAndReplacedParametersRenderAsTheWholeSceneWithThem) {
    PhongMaterial m;
    m.kd = Color3(0.4, 0.5, 0.6);
    m.ks = Color3::Constant(0.3);
    m.n = 50;
    PhongMaterial other = m;
    other.kd = Color3(0.2, 0.1, 0.3);
    other.ks = Color3(0.5, 0.6, 0.4);
    other.n = 400;
    Scene scene = sphereScene(m, 24);
    scene.sensor.filter = SensorDesc::Filter::Gaussian;
    Scene withOther = scene;
    withOther.bsdfs[0].params = other;
    withOther.sensor.filter = SensorDesc::Filter::Tent;
    withOther.sensor.filterWidth = 1.3;
    RenderOptions options;
    options.spp = 4;
    options.seed = 5;
    options.quiet = true;
    const RenderResult full = Renderer(withOther).render(options);
    const Renderer renderer(scene);
    options.window = {7, 9, 5, 3};
    options.bsdfs = {0};
    options.bsdfParams = {other};
    options.pixelFilter = PixelFilter{SensorDesc::Filter::Tent, 1.3};
    const RenderResult part = renderer.render(options);
    ASSERT_EQ(part.width, 5);
    ASSERT_EQ(part.height, 3);
    ASSERT_EQ(part.rgb.size(), 3u * 5 * 3);
    EXPECT_EQ(part.stats.samples, 4u * 5 * 3);
    for (int y = 0; y < 3; ++y)
        for (int x = 0; x < 5; ++x)
            for (int c = 0; c < 3; ++c)
                EXPECT_EQ(part.rgb[3 * (y * 5 + x) + c], full.rgb[3 * ((9 + y) * 24 + 7 + x) + c])
                    << x << ", " << y;
    options.bsdfs = {};
    options.bsdfParams = {};
    EXPECT_NE(renderer.render(options).rgb, part.rgb);  // the scene's own parameters
    options.bsdfs = {0};
    options.bsdfParams = {other};
    options.pixelFilter.reset();
    EXPECT_NE(renderer.render(options).rgb, part.rgb);  // the scene's own filter
    options.pixelFilter = PixelFilter{SensorDesc::Filter::Gaussian, 0};
    EXPECT_EQ(test::errorOf([&] { renderer.render(options); }),
              "render: pixel filter width 0 is not in (0, 64]");
    options.pixelFilter.reset();
    options.bsdfs = {1};
    EXPECT_EQ(test::errorOf([&] { renderer.render(options); }),
              "render: bsdf 1 is not one of the scene's 1");
    options.bsdfs = {0, 0};
    EXPECT_EQ(test::errorOf([&] { renderer.render(options); }),
              "render: one material per bsdf replaced is needed");
    options.bsdfs = {0};
    options.window = {20, 9, 5, 3};
    EXPECT_EQ(test::errorOf([&] { renderer.render(options); }),
              "render: window 5x3 at (20, 9) is not within the 24x24 film");
}

// At the last vertex that can reflect (here the only one: depth 2), a diffuse surface is lit by
// light sampling alone: one camera ray and one shadow ray a sample, no BRDF-sampled ray, and the
// closed-form irradiance under a rectangle light parallel to the floor, centred above the point
// seen: four times the form factor to a parallel rectangle with a corner overhead, E = 2 L (A /
// sqrt(1 + A^2) atan(B / sqrt(1 + A^2)) + (A <-> B)), A and B a quarter's sides over the height.
TEST(LastVertex, DiffuseSurfaceIsLitByLightSamplingAloneAndExactly) {
    const double a = 0.5, b = 0.3, h = 1, radiance = 2, kd = 0.6;
    const Scene scene = parseScene(fmt::format(R"(<scene version="0.6.0">
        <integrator type="path"><integer name="maxDepth" value="2"/></integrator>
        <sensor type="perspective"><float name="fov" value="1"/>
            <transform name="toWorld"><lookat origin="0, 0, 0.5" target="0, 0, 0" up="0, 1, 0"/></transform>
            <film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="8"/></film>
        </sensor>
        <bsdf type="diffuse" id="floor"><rgb name="reflectance" value="{}"/></bsdf>
        <shape type="rectangle"><transform name="toWorld"><scale value="10"/></transform><ref id="floor"/></shape>
        <shape type="rectangle">
            <transform name="toWorld"><scale x="{}" y="{}"/><rotate x="1" angle="180"/><translate z="{}"/></transform>
            <emitter type="area"><rgb name="radiance" value="{}"/></emitter>
        </shape>
    </scene>)",
                                               kd, a, b, h, radiance),
                                   "last_vertex.xml");
    RenderOptions options;
    options.spp = 256;
    options.quiet = true;
    const RenderResult r = Renderer(scene).render(options);
    EXPECT_EQ(r.stats.rays, 2 * r.stats.samples);
    const auto quarter = [](double x, double y) {
        const double sx = std::sqrt(1 + x * x), sy = std::sqrt(1 + y * y);
        return x / sx * std::atan(y / sx) + y / sy * std::atan(x / sy);
    };
    const double irradiance = 2 * radiance * quarter(a / h, b / h);
    const double expected = kd / kPi * irradiance;
    double mean = 0;
    for (const float v : r.rgb) mean += v / double(r.rgb.size());
    EXPECT_NEAR(mean, expected, 1e-3 * expected);

    // Under a sky the BRDF-sampled ray stays: cosine sampling is what lights a diffuse surface
    // there (light sampling alone had 72x its variance). Per sample: the camera ray, the shadow
    // ray to the rectangle, one to the sky for the half of its samples above the floor, and the
    // BRDF-sampled ray.
    Scene sky = scene;
    EmitterDesc constant;
    constant.type = EmitterDesc::Type::Constant;
    constant.value = Color3::Constant(0.1);
    sky.emitters.push_back(constant);
    const RenderResult underSky = Renderer(sky).render(options);
    EXPECT_GT(underSky.stats.rays, 3 * underSky.stats.samples);
}

}  // namespace
}  // namespace phongfit
