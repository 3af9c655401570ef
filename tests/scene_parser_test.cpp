#include "scene_parser.h"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <random>

#include "error.h"
#include "image.h"
#include "raw_exr.h"
#include "temp_dir.h"

namespace phongfit {
namespace {

namespace fs = std::filesystem;

constexpr const char* kSensorLine =
    R"(<sensor type="perspective"><float name="fov" value="45"/></sensor>)";

// `body` starts on line 3 of the file.
std::string doc(const std::string& body) {
    return fmt::format("<scene version=\"0.6.0\">\n{}\n{}\n</scene>\n", kSensorLine, body);
}

// `inner` starts on line 3, inside the sensor.
std::string sensorDoc(const std::string& inner) {
    return fmt::format(
        "<scene version=\"0.6.0\">\n<sensor type=\"perspective\">\n{}\n</sensor>\n"
        "</scene>\n",
        inner);
}

Scene parse(const std::string& text, const std::map<std::string, std::string>& defines = {},
            const std::string& baseDir = ".") {
    return parseScene(text, "t.xml", defines, baseDir);
}

std::string errorOf(const std::function<void()>& f) {
    try {
        f();
    } catch (const Error& e) {
        return e.what();
    }
    return "(no error)";
}

void expectNear(const Vec3d& actual, const Vec3d& expected, double tol = 1e-12) {
    EXPECT_LT((actual - expected).norm(), tol)
        << "actual " << actual.transpose() << ", expected " << expected.transpose();
}

Vec3d toD(const Vec3f& v) { return v.cast<double>(); }

// The normal the winding says: cross(p1 - p0, p2 - p0), normalized.
Vec3d windingNormal(const TriangleMesh& m, std::size_t triangle) {
    const Vec3d p0 = toD(m.positions[m.indices[3 * triangle]]);
    const Vec3d p1 = toD(m.positions[m.indices[3 * triangle + 1]]);
    const Vec3d p2 = toD(m.positions[m.indices[3 * triangle + 2]]);
    return (p1 - p0).cross(p2 - p0).normalized();
}

Vec3d centroid(const TriangleMesh& m, std::size_t triangle) {
    Vec3d c = Vec3d::Zero();
    for (int k = 0; k < 3; ++k) c += toD(m.positions[m.indices[3 * triangle + k]]);
    return c / 3;
}

// The sphere's world-space center after the given toWorld operations (center (1, 0, 0)).
Vec3d sphereCenterAfter(const std::string& ops) {
    const Scene s = parse(doc(fmt::format(
        R"(<shape type="sphere"><point name="center" x="1"/><transform name="toWorld">{})"
        R"(</transform></shape>)",
        ops)));
    return s.shapes.at(0).center;
}

Eigen::Affine3d sensorToWorld(const std::string& ops) {
    return parse(sensorDoc(fmt::format(R"(<float name="fov" value="45"/>)"
                                       R"(<transform name="toWorld">{}</transform>)",
                                       ops)))
        .sensor.toWorld;
}

TEST(SceneParser, MinimalSceneUsesMitsubaDefaults) {
    const Scene s = parse(doc(""));
    EXPECT_EQ(s.file, "t.xml");
    EXPECT_EQ(s.integrator.type, "direct");  // Mitsuba 0.6's default integrator
    EXPECT_EQ(s.integrator.maxDepth, 2);
    EXPECT_EQ(s.sensor.fovDegrees, 45);
    EXPECT_EQ(s.sensor.fovAxis, SensorDesc::FovAxis::X);
    EXPECT_EQ(s.sensor.width, 768);
    EXPECT_EQ(s.sensor.height, 576);
    EXPECT_EQ(s.sensor.sampleCount, 4);
    EXPECT_EQ(s.sensor.filter, SensorDesc::Filter::Box);
    EXPECT_TRUE(s.sensor.toWorld.isApprox(Eigen::Affine3d::Identity()));
    EXPECT_TRUE(s.shapes.empty());
    EXPECT_TRUE(s.emitters.empty());
}

TEST(SceneParser, Integrators) {
    Scene s = parse(doc(R"(<integrator type="path"><integer name="maxDepth" value="7"/>)"
                        R"(<integer name="rrDepth" value="3"/></integrator>)"));
    EXPECT_EQ(s.integrator.type, "path");
    EXPECT_EQ(s.integrator.maxDepth, 7);
    EXPECT_EQ(s.integrator.rrDepth, 3);
    s = parse(doc(R"(<integrator type="path"/>)"));
    EXPECT_EQ(s.integrator.maxDepth, -1);
    EXPECT_EQ(s.integrator.rrDepth, 5);
    s = parse(doc(R"(<integrator type="path"><integer name="maxDepth" value="-1"/></integrator>)"));
    EXPECT_EQ(s.integrator.maxDepth, -1);
    s = parse(doc(R"(<integrator type="direct"/>)"));
    EXPECT_EQ(s.integrator.type, "direct");
    EXPECT_EQ(s.integrator.maxDepth, 2);
}

TEST(SceneParser, SensorSamplerFilmAndFilters) {
    Scene s = parse(sensorDoc(R"(
        <float name="fov" value="30.5"/>
        <string name="fovAxis" value="smaller"/>
        <sampler type="independent"><integer name="sampleCount" value="64"/></sampler>
        <film type="hdrfilm">
            <integer name="width" value="320"/>
            <integer name="height" value="16384"/>
            <rfilter type="gaussian"><float name="stddev" value="0.25"/></rfilter>
        </film>)"));
    EXPECT_EQ(s.sensor.fovDegrees, 30.5);
    EXPECT_EQ(s.sensor.fovAxis, SensorDesc::FovAxis::Smaller);
    EXPECT_EQ(s.sensor.sampleCount, 64);
    EXPECT_EQ(s.sensor.width, 320);
    EXPECT_EQ(s.sensor.height, 16384);
    EXPECT_EQ(s.sensor.filter, SensorDesc::Filter::Gaussian);
    EXPECT_EQ(s.sensor.filterWidth, 0.25);
    EXPECT_EQ(s.sensor.pixelSampler, PixelSamplerType::Independent);
    // Mitsuba's low-discrepancy names: sobol (also what a sensor that names none takes) and
    // ldsampler, padded.
    for (const auto& [type, sampler] : {std::pair{"sobol", PixelSamplerType::Sobol},
                                        std::pair{"ldsampler", PixelSamplerType::Padded}}) {
        s = parse(sensorDoc(R"(<float name="fov" value="45"/><sampler type=")" + std::string(type) +
                            R"("/>)"));
        EXPECT_EQ(s.sensor.pixelSampler, sampler) << type;
    }
    s = parse(sensorDoc(R"(<float name="fov" value="45"/>)"));
    EXPECT_EQ(s.sensor.pixelSampler, PixelSamplerType::Sobol);

    s = parse(sensorDoc(R"(<float name="fov" value="45"/><film type="hdrfilm">)"
                        R"(<rfilter type="gaussian"/></film>)"));
    EXPECT_EQ(s.sensor.filter, SensorDesc::Filter::Gaussian);
    EXPECT_EQ(s.sensor.filterWidth, 0.5);
    s = parse(sensorDoc(R"(<float name="fov" value="45"/><film type="hdrfilm">)"
                        R"(<rfilter type="box"/></film>)"));
    EXPECT_EQ(s.sensor.filter, SensorDesc::Filter::Box);
    EXPECT_TRUE(s.sensor.filterNamed);
    // Tungsten's default and Mitsuba's tent: radius 1 unless named.
    s = parse(sensorDoc(R"(<float name="fov" value="45"/><film type="hdrfilm">)"
                        R"(<rfilter type="tent"/></film>)"));
    EXPECT_EQ(s.sensor.filter, SensorDesc::Filter::Tent);
    EXPECT_EQ(s.sensor.filterWidth, 1.0);
    s = parse(
        sensorDoc(R"(<float name="fov" value="45"/><film type="hdrfilm">)"
                  R"(<rfilter type="tent"><float name="radius" value="1.5"/></rfilter></film>)"));
    EXPECT_EQ(s.sensor.filterWidth, 1.5);
    // A film that names no filter takes the box, and says so.
    s = parse(sensorDoc(R"(<float name="fov" value="45"/><film type="hdrfilm"/>)"));
    EXPECT_EQ(s.sensor.filter, SensorDesc::Filter::Box);
    EXPECT_FALSE(s.sensor.filterNamed);

    const std::pair<const char*, SensorDesc::FovAxis> axes[] = {
        {"x", SensorDesc::FovAxis::X},
        {"y", SensorDesc::FovAxis::Y},
        {"smaller", SensorDesc::FovAxis::Smaller},
        {"larger", SensorDesc::FovAxis::Larger}};
    for (const auto& [name, axis] : axes) {
        s = parse(sensorDoc(fmt::format(
            R"(<float name="fov" value="45"/><string name="fovAxis" value="{}"/>)", name)));
        EXPECT_EQ(s.sensor.fovAxis, axis) << name;
    }
}

TEST(SceneParser, ValueForms) {
    const Scene s = parse(doc(R"(
        <bsdf type="phong" id="a">
            <float name="exponent" value=" +2.5e1 "/>
            <rgb name="diffuseReflectance" value="0.1, 0.2,0.3"/>
            <spectrum name="specularReflectance" value="0.25"/>
        </bsdf>
        <bsdf type="diffuse" id="b"><rgb name="reflectance" value="0.1 0.2	0.3"/></bsdf>
        <bsdf type="diffuse" id="c"><spectrum name="reflectance" value="0.1,0.2 0.3"/></bsdf>
        <emitter type="point"><point name="position" x="1" z="-2.5"/></emitter>
        <emitter type="directional"><vector name="direction" y="-2"/></emitter>)"));
    const BsdfDesc& a = s.bsdfs.at(std::size_t(s.findBsdf("a")));
    EXPECT_EQ(a.type, "phong");
    EXPECT_EQ(a.params.n, 25);
    EXPECT_TRUE((a.params.kd == Color3(0.1, 0.2, 0.3)).all());
    EXPECT_TRUE((a.params.ks == Color3::Constant(0.25)).all());
    for (const char* id : {"b", "c"}) {
        const BsdfDesc& b = s.bsdfs.at(std::size_t(s.findBsdf(id)));
        EXPECT_EQ(b.type, "diffuse");
        EXPECT_TRUE((b.params.kd == Color3(0.1, 0.2, 0.3)).all()) << id;
        EXPECT_TRUE((b.params.ks == 0).all()) << id;
    }
    ASSERT_EQ(s.emitters.size(), 2u);
    expectNear(s.emitters[0].position, Vec3d(1, 0, -2.5));  // a missing coordinate is 0
    expectNear(s.emitters[1].direction, Vec3d(0, -1, 0));   // normalized
}

TEST(SceneParser, LocationsNameFileAndLine) {
    const Scene s = parse(doc("<bsdf type=\"diffuse\" id=\"a\"/>\n\n<shape type=\"sphere\"/>"));
    EXPECT_EQ(s.bsdfs.at(0).loc.str(), "t.xml:3");
    EXPECT_EQ(s.shapes.at(0).loc.str(), "t.xml:5");
}

TEST(SceneParser, LineNumbersWithCrLf) {
    const std::string text = "<scene version=\"0.6.0\">\r\n<!-- a\r\ncomment -->\r\n" +
                             std::string(kSensorLine) +
                             "\r\n<shape type=\"sphere\">\r\n<float name=\"radius\" value=\"x\"/>"
                             "\r\n</shape>\r\n</scene>\r\n";
    EXPECT_NE(errorOf([&] { parse(text); }).find("t.xml:6: float name=\"radius\""),
              std::string::npos)
        << errorOf([&] { parse(text); });
}

TEST(SceneParser, TransformOperations) {
    // translate: missing coordinates are 0.
    expectNear(sphereCenterAfter(R"(<translate y="2"/>)"), Vec3d(1, 2, 0));
    // scale: uniform value, or x, y, z with missing ones 1.
    expectNear(sphereCenterAfter(R"(<scale value="3"/>)"), Vec3d(3, 0, 0));
    EXPECT_TRUE(sensorToWorld(R"(<scale x="2" z="4"/>)")
                    .linear()
                    .isApprox(Vec3d(2, 1, 4).asDiagonal().toDenseMatrix()));
    // rotate: right-handed about the axis, angle in degrees.
    expectNear(sphereCenterAfter(R"(<rotate z="1" angle="90"/>)"), Vec3d(0, 1, 0));
    expectNear(sphereCenterAfter(R"(<rotate x="0" y="5" z="0" angle="90"/>)"), Vec3d(0, 0, -1));
    // matrix: 16 numbers, row-major (the translation is the last column).
    const Eigen::Affine3d m =
        sensorToWorld(R"(<matrix value="0 -1 0 5, 1 0 0 6, 0 0 1 7, 0 0 0 1"/>)");
    expectNear(m * Vec3d(1, 0, 0), Vec3d(5, 7, 7));
    expectNear(m.translation(), Vec3d(5, 6, 7));
}

TEST(SceneParser, LaterOperationsApplyAfterEarlierOnes) {
    expectNear(sphereCenterAfter(R"(<scale value="2"/><translate x="1"/>)"), Vec3d(3, 0, 0));
    expectNear(sphereCenterAfter(R"(<translate x="1"/><scale value="2"/>)"), Vec3d(4, 0, 0));
    expectNear(sphereCenterAfter(R"(<rotate z="1" angle="90"/><translate x="1"/>)"),
               Vec3d(1, 1, 0));
    expectNear(sphereCenterAfter(R"(<translate x="1"/><rotate z="1" angle="90"/>)"),
               Vec3d(0, 2, 0));
    const Eigen::Affine3d m = sensorToWorld(
        R"(<translate x="1" y="2" z="3"/><rotate x="1" angle="90"/><scale x="2" y="3" z="4"/>)");
    const Eigen::Affine3d expected = Eigen::Scaling(2.0, 3.0, 4.0) *
                                     Eigen::AngleAxisd(kPi / 2, Vec3d::UnitX()) *
                                     Eigen::Translation3d(1, 2, 3);
    EXPECT_TRUE(m.matrix().isApprox(expected.matrix(), 1e-12)) << m.matrix();
}

TEST(SceneParser, LookAtFollowsMitsuba) {
    const Eigen::Affine3d m =
        sensorToWorld(R"(<lookat origin="1, 2, 3" target="1, 2, 0" up="0, 1, 0"/>)");
    // +z looks at the target, +y is up, +x = up x dir is the viewer's left (here world -x).
    expectNear(m.linear().col(0), Vec3d(-1, 0, 0));
    expectNear(m.linear().col(1), Vec3d(0, 1, 0));
    expectNear(m.linear().col(2), Vec3d(0, 0, -1));
    expectNear(m.translation(), Vec3d(1, 2, 3));

    // A tilted up is made orthogonal; without up, some perpendicular is chosen.
    for (const char* up : {R"( up="0.3, 1, 0.2")", ""}) {
        const Eigen::Affine3d l =
            sensorToWorld(fmt::format(R"(<lookat origin="0 0 0" target="1, 1, 1"{}/>)", up));
        EXPECT_TRUE((l.linear().transpose() * l.linear()).isIdentity(1e-12)) << up;
        EXPECT_NEAR(l.linear().determinant(), 1, 1e-12) << up;
        expectNear(l.linear().col(2), Vec3d(1, 1, 1).normalized());
    }
    // Later operations still compose after a lookat.
    const Eigen::Affine3d t =
        sensorToWorld(R"(<lookat origin="0, 0, 0" target="0, 0, 1"/><translate x="5"/>)");
    expectNear(t.translation(), Vec3d(5, 0, 0));
}

TEST(SceneParser, DefaultsAndDefines) {
    const std::string text = doc(R"(<default name="r" value="2"/>
        <default name="a" value="0.25"/>
        <default name="color" value="$a, 0.5,$a"/>
        <bsdf type="diffuse" id="d"><rgb name="reflectance" value="$color"/></bsdf>
        <shape type="sphere">
            <float name="radius" value="$r"/>
            <point name="center" x="1$r" y="-$a"/>
            <ref id="d"/>
        </shape>)");
    Scene s = parse(text);
    EXPECT_EQ(s.shapes.at(0).radius, 2);
    expectNear(s.shapes.at(0).center, Vec3d(12, -0.25, 0));
    EXPECT_TRUE((s.bsdfs.at(0).params.kd == Color3(0.25, 0.5, 0.25)).all());

    s = parse(text, {{"r", "3"}, {"a", "0.125"}});
    EXPECT_EQ(s.shapes.at(0).radius, 3);
    expectNear(s.shapes.at(0).center, Vec3d(13, -0.125, 0));
    EXPECT_TRUE((s.bsdfs.at(0).params.kd == Color3(0.125, 0.5, 0.125)).all());

    // A define that the file never declares is still usable.
    s = parse(doc(R"(<shape type="sphere"><float name="radius" value="$rr"/></shape>)"),
              {{"rr", "0.5"}});
    EXPECT_EQ(s.shapes.at(0).radius, 0.5);
}

TEST(SceneParser, BsdfsRefsAndDefaults) {
    const Scene s = parse(doc(R"(
        <bsdf type="phong" id="p"/>
        <bsdf type="diffuse" id="w"/>
        <shape type="sphere"><ref id="p"/></shape>
        <shape type="sphere"><ref id="p"/></shape>
        <shape type="sphere"><bsdf type="phong"><float name="exponent" value="7"/></bsdf></shape>
        <shape type="sphere"/>
        <shape type="sphere"><ref id="w"/></shape>)"));
    ASSERT_EQ(s.shapes.size(), 5u);
    const int p = s.findBsdf("p");
    ASSERT_GE(p, 0);
    EXPECT_EQ(s.shapes[0].bsdf, p);
    EXPECT_EQ(s.shapes[1].bsdf, p);
    // Mitsuba 0.6's phong defaults.
    EXPECT_EQ(s.bsdfs[std::size_t(p)].params.n, 30);
    EXPECT_TRUE((s.bsdfs[std::size_t(p)].params.kd == 0.5).all());
    EXPECT_TRUE((s.bsdfs[std::size_t(p)].params.ks == 0.2).all());
    // Nested: its own anonymous bsdf.
    const BsdfDesc& nested = s.bsdfs.at(std::size_t(s.shapes[2].bsdf));
    EXPECT_EQ(nested.id, "");
    EXPECT_EQ(nested.type, "phong");
    EXPECT_EQ(nested.params.n, 7);
    // None: diffuse 0.5.
    const BsdfDesc& none = s.bsdfs.at(std::size_t(s.shapes[3].bsdf));
    EXPECT_EQ(none.type, "diffuse");
    EXPECT_TRUE((none.params.kd == 0.5).all());
    EXPECT_TRUE((none.params.ks == 0).all());
    EXPECT_NE(s.shapes[3].bsdf, s.shapes[2].bsdf);
    const BsdfDesc& w = s.bsdfs.at(std::size_t(s.shapes[4].bsdf));
    EXPECT_EQ(w.id, "w");
    EXPECT_TRUE((w.params.kd == 0.5).all());
}

TEST(SceneParser, SphereAppliesToWorld) {
    const Scene s = parse(doc(R"(<shape type="sphere">
        <point name="center" x="1" y="2" z="3"/>
        <float name="radius" value="0.5"/>
        <transform name="toWorld"><rotate z="1" angle="90"/><scale value="-2"/>
            <translate x="10"/></transform>
        </shape>)"));
    const ShapeDesc& sphere = s.shapes.at(0);
    EXPECT_EQ(sphere.type, ShapeDesc::Type::Sphere);
    expectNear(sphere.center, Vec3d(10 + 4, -2, -6));
    EXPECT_NEAR(sphere.radius, 1, 1e-12);
}

TEST(SceneParser, RectangleIsTwoTrianglesFacingToWorldNormal) {
    const Scene s = parse(doc(R"(<shape type="rectangle"><transform name="toWorld">
        <scale x="2"/><rotate x="1" angle="-90"/><translate y="-1"/></transform></shape>)"));
    const ShapeDesc& r = s.shapes.at(0);
    EXPECT_EQ(r.type, ShapeDesc::Type::Rectangle);
    ASSERT_EQ(r.mesh.indices.size(), 6u);
    EXPECT_TRUE(r.mesh.normals.empty());
    for (const Vec3f& p : r.mesh.positions) {
        EXPECT_NEAR(p.y(), -1, 1e-6);
        EXPECT_NEAR(std::abs(p.x()), 2, 1e-6);
        EXPECT_NEAR(std::abs(p.z()), 1, 1e-6);
    }
    for (std::size_t t = 0; t < 2; ++t) expectNear(windingNormal(r.mesh, t), Vec3d(0, 1, 0), 1e-6);
    // Area 4 x 2.
    double area = 0;
    for (std::size_t t = 0; t < 2; ++t) {
        const Vec3d p0 = toD(r.mesh.positions[r.mesh.indices[3 * t]]);
        area += 0.5 * (toD(r.mesh.positions[r.mesh.indices[3 * t + 1]]) - p0)
                          .cross(toD(r.mesh.positions[r.mesh.indices[3 * t + 2]]) - p0)
                          .norm();
    }
    EXPECT_NEAR(area, 8, 1e-5);
}

TEST(SceneParser, CubeFacesPointOutwardEvenWhenMirrored) {
    for (const char* ops :
         {"", R"(<scale x="-1" y="0.5"/>)",
          R"(<rotate x="1" y="1" angle="30"/><scale x="-2"/><translate z="3"/>)"}) {
        const Scene s = parse(doc(fmt::format(
            R"(<shape type="cube"><transform name="toWorld">{}<translate x="5"/></transform>)"
            R"(</shape>)",
            ops)));
        const ShapeDesc& c = s.shapes.at(0);
        EXPECT_EQ(c.type, ShapeDesc::Type::Cube);
        ASSERT_EQ(c.mesh.indices.size(), 36u) << ops;
        Vec3d center = Vec3d::Zero();
        for (const Vec3f& p : c.mesh.positions) center += toD(p);
        center /= double(c.mesh.positions.size());
        for (std::size_t t = 0; t < 12; ++t)
            EXPECT_GT(windingNormal(c.mesh, t).dot((centroid(c.mesh, t) - center).normalized()),
                      0.1)
                << ops << " triangle " << t;
    }
    const Scene unit = parse(doc(R"(<shape type="cube"/>)"));
    for (const Vec3f& p : unit.shapes.at(0).mesh.positions) EXPECT_EQ(p.cwiseAbs(), Vec3f(1, 1, 1));
}

TEST(SceneParser, DiskKeepsToWorld) {
    const Scene s = parse(doc(R"(<shape type="disk"><transform name="toWorld">)"
                              R"(<scale value="2"/><translate z="1"/></transform></shape>)"));
    const ShapeDesc& d = s.shapes.at(0);
    EXPECT_EQ(d.type, ShapeDesc::Type::Disk);
    expectNear(d.toWorld * Vec3d(1, 0, 0), Vec3d(2, 0, 1));
    EXPECT_TRUE(d.mesh.indices.empty());
}

TEST(SceneParser, Emitters) {
    const Scene s = parse(doc(R"(
        <emitter type="point"><point name="position" x="1" y="2" z="3"/>
            <spectrum name="intensity" value="10"/></emitter>
        <emitter type="directional"><vector name="direction" x="0" y="0" z="-3"/>
            <rgb name="irradiance" value="1, 2, 3"/></emitter>
        <emitter type="constant"><rgb name="radiance" value="0.5"/></emitter>
        <emitter type="point"/>
        <shape type="rectangle"><emitter type="area"><rgb name="radiance" value="4, 5, 6"/>
            </emitter></shape>
        <shape type="sphere"/>)"));
    ASSERT_EQ(s.emitters.size(), 4u);
    EXPECT_EQ(s.emitters[0].type, EmitterDesc::Type::Point);
    expectNear(s.emitters[0].position, Vec3d(1, 2, 3));
    EXPECT_TRUE((s.emitters[0].value == 10).all());
    EXPECT_EQ(s.emitters[1].type, EmitterDesc::Type::Directional);
    expectNear(s.emitters[1].direction, Vec3d(0, 0, -1));
    EXPECT_TRUE((s.emitters[1].value == Color3(1, 2, 3)).all());
    EXPECT_EQ(s.emitters[2].type, EmitterDesc::Type::Constant);
    EXPECT_TRUE((s.emitters[2].value == 0.5).all());
    EXPECT_TRUE((s.emitters[3].value == 1).all());  // Mitsuba's default intensity
    ASSERT_TRUE(s.shapes.at(0).areaRadiance.has_value());
    EXPECT_TRUE((*s.shapes[0].areaRadiance == Color3(4, 5, 6)).all());
    EXPECT_FALSE(s.shapes.at(1).areaRadiance.has_value());
}

// A width x height map whose texel (x, y) holds (x, y, 1).
Image indexMap(int width, int height) {
    Image map(width, height);
    for (int y = 0; y < height; ++y)
        for (int x = 0; x < width; ++x) map.set(x, y, Color<float>(float(x), float(y), 1));
    return map;
}

TEST(SceneParser, EnvMapReadsItsFileScaleAndRotation) {
    const test::TempDir dir("scene_parser");
    fs::create_directories(dir.path() / "maps");
    writeExr(indexMap(8, 4), (dir.path() / "maps/probe.exr").string());
    const Scene s =
        parse(doc(R"(<emitter type="envmap"><string name="filename" value="maps/probe.exr"/>
        <float name="scale" value="2.5"/>
        <transform name="toWorld"><rotate y="1" angle="90"/><translate x="7"/></transform>
        </emitter>)"),
              {}, dir.path().string());
    ASSERT_EQ(s.emitters.size(), 1u);
    const EmitterDesc& e = s.emitters[0];
    EXPECT_EQ(e.type, EmitterDesc::Type::EnvMap);
    EXPECT_TRUE((e.value == 2.5).all());
    // A rotation by 90 degrees about +y takes +z to +x; the translation is ignored.
    expectNear(e.toWorld * Vec3d(0, 0, 1), Vec3d(1, 0, 0), 1e-12);
    ASSERT_TRUE(e.map);  // maps/probe.exr, resolved against the scene's folder
    EXPECT_EQ(e.map->width, 8);
    EXPECT_EQ(e.map->height, 4);
    EXPECT_TRUE((e.map->at(5, 3) == Color<float>(5, 3, 1)).all());
    // Defaults: scale 1, no rotation.
    const Scene d = parse(
        doc(R"(<emitter type="envmap"><string name="filename" value="maps/probe.exr"/></emitter>)"),
        {}, dir.path().string());
    EXPECT_TRUE((d.emitters.at(0).value == 1).all());
    EXPECT_TRUE(d.emitters[0].toWorld.isIdentity());
}

TEST(SceneParser, MalformedEnvMapsAreNamedWithWhatIsAllowed) {
    const test::TempDir dir("scene_parser");
    writeExr(indexMap(8, 4), (dir.path() / "good.exr").string());
    writeExr(indexMap(8, 8), (dir.path() / "square.exr").string());
    Image negative = indexMap(8, 4);
    negative.set(2, 1, Color<float>(0, -1, 0));
    writeExr(negative, (dir.path() / "negative.exr").string());
    Image nan = indexMap(8, 4), inf = indexMap(8, 4);
    nan.set(3, 2, Color<float>(std::numeric_limits<float>::quiet_NaN(), 0, 0));
    inf.set(7, 0, Color<float>(0, 0, std::numeric_limits<float>::infinity()));
    test::writeRawExr(nan, (dir.path() / "nan.exr").string());
    test::writeRawExr(inf, (dir.path() / "inf.exr").string());
    dir.write("garbage.exr", "not an image");
    const auto envmap = [](const std::string& file, const std::string& extra = "") {
        return doc(fmt::format(
            R"(<emitter type="envmap"><string name="filename" value="{}"/>{}</emitter>)", file,
            extra));
    };
    const std::pair<std::string, std::string> cases[] = {
        {envmap("missing.exr"), "t.xml:3: string name=\"filename\": envmap: cannot read"},
        {envmap("missing.exr"), "missing.exr"},
        {envmap("garbage.exr"), "garbage.exr"},
        {envmap("square.exr"), "square.exr' is 8x8 (allowed: a lat-long map twice as wide as high"},
        {envmap("negative.exr"),
         "negative.exr' has texel (2, 1) channel G = -1 (allowed: finite radiance >= 0)"},
        {envmap("nan.exr"), "nan.exr' has texel (3, 2) channel R = nan"},
        {envmap("inf.exr"), "inf.exr' has texel (7, 0) channel B = inf"},
        {envmap("good.exr", R"(<float name="scale" value="-1"/>)"),
         "t.xml:3: float name=\"scale\": scale -1 is invalid (allowed: >= 0)"},
        {envmap("good.exr", R"(<transform name="toWorld"><scale x="2"/></transform>)"),
         "toWorld of an envmap must be a rotation"},
        {envmap("good.exr", R"(<transform name="toWorld"><scale x="-1"/></transform>)"),
         "toWorld of an envmap must be a rotation"},
        {envmap("good.exr", R"(<float name="gamma" value="2.2"/>)"), "unknown parameter 'gamma'"},
        {doc(R"(<emitter type="envmap"/>)"),
         "t.xml:3: emitter type=\"envmap\": missing parameter 'filename'"},
        {doc(R"(<emitter type="constant"/>
<emitter type="envmap"><string name="filename" value="good.exr"/></emitter>)"),
         "t.xml:4: emitter type=\"envmap\": a second environment emitter (the first is at t.xml:3"},
    };
    for (const auto& [text, fragment] : cases) {
        const std::string message =
            errorOf([&, &text = text] { parse(text, {}, dir.path().string()); });
        EXPECT_NE(message.find(fragment), std::string::npos)
            << message << "\n  wanted: " << fragment;
        EXPECT_EQ(message.find('\n'), std::string::npos) << message;
    }
}

TEST(SceneParser, ObjMeshFromFile) {
    const test::TempDir dir("scene_parser");
    // A unit quad in z = 0 with normals tilted towards +x, and a triangle without normals.
    dir.write("quad.obj",
              "# quad\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvn 1 0 1\nf 1//1 2//1 3//1 4//1\n");
    dir.write("mixed.obj",
              "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nvn 0 0 1\n"
              "f 1//1 2//1 3//1\nf 1 2 4\n");
    const std::string text = doc(R"(
        <shape type="obj"><string name="filename" value="quad.obj"/>
            <transform name="toWorld"><scale x="2"/><translate z="1"/></transform></shape>
        <shape type="obj"><string name="filename" value="quad.obj"/>
            <boolean name="faceNormals" value="true"/></shape>
        <shape type="obj"><string name="filename" value="mixed.obj"/></shape>)");
    const Scene s = parse(text, {}, dir.path().string());
    const TriangleMesh& quad = s.shapes.at(0).mesh;
    EXPECT_EQ(s.shapes[0].type, ShapeDesc::Type::Obj);
    ASSERT_EQ(quad.indices.size(), 6u);
    ASSERT_EQ(quad.positions.size(), 4u);
    ASSERT_EQ(quad.normals.size(), 4u);
    for (const Vec3d& corner : {Vec3d(0, 0, 1), Vec3d(2, 0, 1), Vec3d(2, 1, 1), Vec3d(0, 1, 1)})
        EXPECT_EQ(std::count(quad.positions.begin(), quad.positions.end(), corner.cast<float>()), 1)
            << corner.transpose();
    // Normals go through the inverse transpose: (1, 0, 1) under scale x = 2 -> (0.5, 0, 1).
    for (const Vec3f& n : quad.normals) expectNear(toD(n), Vec3d(0.5, 0, 1).normalized(), 1e-6);
    for (std::size_t t = 0; t < 2; ++t) EXPECT_GT(windingNormal(quad, t).z(), 0.99);

    EXPECT_TRUE(s.shapes.at(1).mesh.normals.empty());  // faceNormals
    EXPECT_EQ(s.shapes.at(1).mesh.indices.size(), 6u);
    // Normals only when every face vertex has one.
    EXPECT_TRUE(s.shapes.at(2).mesh.normals.empty());
    EXPECT_EQ(s.shapes.at(2).mesh.indices.size(), 6u);

    // loadScene resolves against the scene file's directory, whatever the working directory.
    const fs::path file = dir.write("scene.xml", text);
    const Scene loaded = loadScene(file.string());
    EXPECT_EQ(loaded.file, file.string());
    EXPECT_EQ(loaded.shapes.at(0).mesh.positions, quad.positions);
}

TEST(SceneParser, BadObjFilesNameTheFile) {
    const test::TempDir dir("scene_parser");
    dir.write("empty.obj", "# nothing\nv 0 0 0\n");
    dir.write("badindex.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n");
    dir.write("badquad.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3 9\n");
    dir.write("badnormal.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 0\nf 1//1 2//1 3//1\n");
    const std::pair<const char*, const char*> cases[] = {
        {"missing.obj", "missing.obj' does not exist"},
        {"empty.obj", "empty.obj' has no valid triangles"},
        {"badindex.obj", "badindex.obj' is malformed: vertex index 9 is out of range"},
        {"badquad.obj", "badquad.obj' is malformed"},
        {"badnormal.obj", "badnormal.obj' is malformed: normal 1 is zero"},
    };
    for (const auto& [file, fragment] : cases) {
        const std::string message = errorOf([&, &file = file] {
            parse(doc(fmt::format(R"(<shape type="obj"><string name="filename" value="{}"/>)"
                                  R"(</shape>)",
                                  file)),
                  {}, dir.path().string());
        });
        EXPECT_NE(message.find("t.xml:3: string name=\"filename\": "), std::string::npos)
            << message;
        EXPECT_NE(message.find(fragment), std::string::npos) << message;
    }
}

TEST(SceneParser, MalformedInputsGiveFileLineAndWhatIsWrong) {
    struct Case {
        std::string text;
        std::string fragment;
        std::map<std::string, std::string> defines = {};
    };
    const Case cases[] = {
        {"<scene version=\"0.6.0\">\n<shape>\n</scene>", "t.xml:3: malformed XML: "},
        {"", "t.xml:1: malformed XML: "},
        {"<foo/>", "t.xml:1: foo: the root element must be <scene"},
        {"<scene>\n" + std::string(kSensorLine) + "\n</scene>",
         "t.xml:1: scene: missing attribute 'version'"},
        {"<scene version=\"2.0.0\">\n</scene>", "version '2.0.0' is not supported"},
        {"<scene version=\"0.6.0\">\n</scene>", "t.xml:1: scene: no <sensor>"},
        {doc(kSensorLine), "t.xml:3: sensor type=\"perspective\": a second <sensor>"},
        {doc(R"(<texture type="bitmap"/>)"),
         "t.xml:3: texture type=\"bitmap\": unknown element in <scene> (allowed: default, "
         "integrator, sensor, bsdf, shape, emitter)"},
        {doc(R"(<shape type="sphere" foo="1"/>)"),
         "t.xml:3: shape type=\"sphere\": unknown attribute 'foo' (allowed: type, id)"},
        {doc(R"(<shape type="sphere"><float name="radus" value="1"/></shape>)"),
         "t.xml:3: float name=\"radus\": unknown parameter 'radus' for shape type=\"sphere\" "
         "(allowed: center, radius, toWorld)"},
        {doc(R"(<shape type="sphere"><integer name="radius" value="1"/></shape>)"),
         "t.xml:3: integer name=\"radius\": wrong type <integer> for 'radius' (allowed: <float>)"},
        {doc(R"(<shape type="sphere"><rgb name="center" value="1"/></shape>)"),
         "wrong type <rgb> for 'center' (allowed: <point>)"},
        {doc(R"(<shape type="torus"/>)"),
         "t.xml:3: shape type=\"torus\": unknown type 'torus' (allowed: sphere, rectangle, cube, "
         "disk, obj)"},
        {doc(R"(<shape/>)"), "t.xml:3: shape: missing attribute 'type' (allowed: sphere"},
        {doc("<bsdf type=\"diffuse\" id=\"a\"/>\n<bsdf type=\"diffuse\" id=\"a\"/>"),
         "t.xml:4: bsdf type=\"diffuse\" id=\"a\": duplicate id 'a' (already used at t.xml:3)"},
        {doc(R"(<shape type="sphere"><ref id="nope"/></shape>)"),
         "t.xml:3: ref id=\"nope\": no object with id 'nope' is defined above"},
        {doc("<shape type=\"sphere\"><ref id=\"later\"/></shape>\n<bsdf type=\"diffuse\" "
             "id=\"later\"/>"),
         "t.xml:3: ref id=\"later\": no object with id 'later' is defined above"},
        {doc("<shape type=\"sphere\" id=\"ball\"/>\n<shape type=\"sphere\"><ref id=\"ball\"/>"
             "</shape>"),
         "t.xml:4: ref id=\"ball\": 'ball' is a shape (at t.xml:3), not a bsdf"},
        {doc("<bsdf type=\"diffuse\" id=\"w\"/>\n<shape type=\"sphere\"><bsdf type=\"diffuse\"/>"
             "<ref id=\"w\"/></shape>"),
         "t.xml:4: ref id=\"w\": the shape already has a bsdf (allowed: one nested <bsdf> or one "
         "<ref>)"},
        {doc(R"(<shape type="sphere"><float name="radius" value="1.2.3"/></shape>)"),
         "t.xml:3: float name=\"radius\": '1.2.3' is not a valid number"},
        {doc(R"(<shape type="sphere"><float name="radius" value="abc"/></shape>)"),
         "'abc' is not a valid number"},
        {doc(R"(<shape type="sphere"><float name="radius" value="nan"/></shape>)"),
         "'nan' is not a valid number"},
        {doc(R"(<shape type="sphere"><float name="radius" value="inf"/></shape>)"),
         "'inf' is not a valid number"},
        {doc(R"(<shape type="sphere"><float name="radius" value=""/></shape>)"),
         "'' is not a valid number"},
        {doc(R"(<shape type="sphere"><float name="radius" value="-1"/></shape>)"),
         "t.xml:3: float name=\"radius\": radius -1 is invalid (allowed: > 0)"},
        {doc(R"(<shape type="sphere"><float name="radius" value="1"/><float name="radius" )"
             R"(value="2"/></shape>)"),
         "parameter 'radius' is given twice"},
        {doc(R"(<shape type="sphere"><float name="radius" value="$r"/></shape>)"),
         "t.xml:3: float name=\"radius\": undefined variable '$r' (define it with <default "
         "name=\"r\""},
        {doc(R"(<shape type="sphere"><float name="radius" value="$"/></shape>)"),
         "'$' in '$' is not followed by a variable name"},
        {doc(R"(<shape type="sphere"/>)"),
         "'bad name' is not a valid variable name",
         {{"bad name", "1"}}},
        {doc("<default name=\"a\" value=\"1\"/>\n<default name=\"a\" value=\"2\"/>"),
         "t.xml:4: default name=\"a\": a second default for 'a' (first at line 3)"},
        {doc(R"(<shape type="sphere">hello</shape>)"), "t.xml:3: text: unexpected text 'hello'"},
        {doc(R"(<shape type="sphere"><transform name="toWorld"><scale x="2"/></transform>)"
             R"(</shape>)"),
         "t.xml:3: transform name=\"toWorld\": toWorld scales a sphere non-uniformly"},
        {doc(R"(<shape type="rectangle"><transform name="toWorld"><scale value="0"/>)"
             R"(</transform></shape>)"),
         "t.xml:3: scale: a scale factor of 0 collapses space"},
        {doc(R"(<shape type="rectangle"><transform name="toWorld"><matrix value="1 0 0 0 )"
             R"(0 1 0 0 0 0 0 0 0 0 0 1"/></transform></shape>)"),
         "t.xml:3: transform name=\"toWorld\": the transform is degenerate"},
        {doc(R"(<shape type="rectangle"><transform name="toWorld"><matrix value="1 0 0 0 )"
             R"(0 1 0 0 0 0 1 0 0 0 0"/></transform></shape>)"),
         "t.xml:3: matrix: value has 15 numbers (allowed: 16, row-major)"},
        {doc(R"(<shape type="rectangle"><transform name="toWorld"><matrix value="1 0 0 0 )"
             R"(0 1 0 0 0 0 1 0 0 0 1 1"/></transform></shape>)"),
         "the last row is not 0 0 0 1"},
        {doc(R"(<shape type="rectangle"><transform name="toWorld"><rotate angle="30"/>)"
             R"(</transform></shape>)"),
         "t.xml:3: rotate: the rotation axis x, y, z is zero"},
        {doc(R"(<shape type="rectangle"><transform name="toWorld"><skew/></transform></shape>)"),
         "t.xml:3: skew: unknown transform operation (allowed: translate, scale, rotate, "
         "matrix, lookat)"},
        {doc(R"(<shape type="rectangle"><transform name="toWorld"><translate w="1"/>)"
             R"(</transform></shape>)"),
         "t.xml:3: translate: unknown attribute 'w' (allowed: x, y, z)"},
        {doc(R"(<shape type="rectangle"><transform name="toWorld"><lookat origin="0 0 0" )"
             R"(target="0 1 0" up="0 2 0"/></transform></shape>)"),
         "t.xml:3: lookat: up is zero or parallel to target - origin"},
        {doc(R"(<shape type="rectangle"><transform name="toWorld"><lookat origin="1 2" )"
             R"(target="0 1 0"/></transform></shape>)"),
         "origin=\"1 2\" has 2 numbers (allowed: three"},
        {doc(R"(<shape type="rectangle"><transform name="objectToWorld"/></shape>)"),
         "unknown parameter 'objectToWorld' for shape type=\"rectangle\" (allowed: toWorld)"},
        {doc(R"(<integrator type="path"><integer name="maxDepth" value="-2"/></integrator>)"),
         "t.xml:3: integer name=\"maxDepth\": maxDepth -2 is invalid (allowed: -1 for "
         "unbounded, or >= 0)"},
        {doc(R"(<integrator type="path"><integer name="rrDepth" value="0"/></integrator>)"),
         "rrDepth 0 is invalid (allowed: >= 1)"},
        {doc(R"(<integrator type="path"><integer name="maxDepth" value="5.0"/></integrator>)"),
         "'5.0' is not a valid integer"},
        {doc(R"(<integrator type="path"><boolean name="hideEmitters" value="true"/>)"
             R"(</integrator>)"),
         "unknown parameter 'hideEmitters' for integrator type=\"path\" (allowed: maxDepth, "
         "rrDepth)"},
        {doc(R"(<integrator type="bdpt"/>)"), "unknown type 'bdpt' (allowed: path, direct)"},
        {doc("<integrator type=\"path\"/>\n<integrator type=\"path\"/>"),
         "t.xml:4: integrator type=\"path\": a second <integrator> (allowed: one)"},
        {sensorDoc(""), "t.xml:2: sensor type=\"perspective\": missing parameter 'fov'"},
        {sensorDoc(R"(<float name="fov" value="180"/>)"),
         "t.xml:3: float name=\"fov\": fov 180 is out of range (allowed: 0 < fov < 180 degrees)"},
        {sensorDoc(R"(<float name="fov" value="45"/><string name="fovAxis" value="diagonal"/>)"),
         "unknown fovAxis 'diagonal' (allowed: x, y, smaller, larger)"},
        {sensorDoc("<film type=\"hdrfilm\"><integer name=\"width\" value=\"0\"/></film>\n"
                   "<float name=\"fov\" value=\"45\"/>"),
         "t.xml:3: integer name=\"width\": width 0 is out of range (allowed: 1 to 16384)"},
        {sensorDoc("<film type=\"hdrfilm\"><integer name=\"height\" value=\"-5\"/></film>\n"
                   "<float name=\"fov\" value=\"45\"/>"),
         "height -5 is out of range (allowed: 1 to 16384)"},
        {sensorDoc("<film type=\"hdrfilm\"><integer name=\"width\" value=\"16385\"/></film>\n"
                   "<float name=\"fov\" value=\"45\"/>"),
         "width 16385 is out of range"},
        {sensorDoc("<film type=\"hdrfilm\"><integer name=\"width\" value=\"99999999999\"/>"
                   "</film>\n<float name=\"fov\" value=\"45\"/>"),
         "'99999999999' is not a valid integer"},
        {sensorDoc("<film type=\"ldrfilm\"/>\n<float name=\"fov\" value=\"45\"/>"),
         "t.xml:3: film type=\"ldrfilm\": unknown type 'ldrfilm' (allowed: hdrfilm)"},
        {sensorDoc("<film type=\"hdrfilm\"><rfilter type=\"gaussian\"><float name=\"stddev\" "
                   "value=\"0\"/></rfilter></film>\n<float name=\"fov\" value=\"45\"/>"),
         "stddev 0 is invalid (allowed: > 0 and <= 64 pixels)"},
        {sensorDoc("<film type=\"hdrfilm\"><rfilter type=\"tent\"><float name=\"radius\" "
                   "value=\"1e300\"/></rfilter></film>\n<float name=\"fov\" value=\"45\"/>"),
         "radius 1e+300 is invalid (allowed: > 0 and <= 64 pixels)"},
        {sensorDoc("<film type=\"hdrfilm\"><rfilter type=\"mitchell\"/></film>\n"
                   "<float name=\"fov\" value=\"45\"/>"),
         "unknown type 'mitchell' (allowed: box, gaussian, tent)"},
        {sensorDoc("<sampler type=\"independent\"><integer name=\"sampleCount\" value=\"0\"/>"
                   "</sampler>\n<float name=\"fov\" value=\"45\"/>"),
         "t.xml:3: integer name=\"sampleCount\": sampleCount 0 is invalid (allowed: >= 1)"},
        {sensorDoc("<sampler type=\"stratified\"/>\n<float name=\"fov\" value=\"45\"/>"),
         "unknown type 'stratified' (allowed: independent, ldsampler, sobol)"},
        {doc(R"(<bsdf type="phong" id="p"><rgb name="diffuseReflectance" value="0.8"/>)"
             R"(<rgb name="specularReflectance" value="0.5"/></bsdf>)"),
         "bsdf 'p' (t.xml:3): kd + ks = 0.8 + 0.5 = 1.3 in channel R exceeds 1"},
        {doc(R"(<shape type="sphere"><bsdf type="phong"><float name="exponent" value="-1"/>)"
             R"(</bsdf></shape>)"),
         "bsdf (t.xml:3): exponent n = -1 is invalid"},
        {doc(R"(<bsdf type="roughplastic"/>)"),
         "unknown type 'roughplastic' (allowed: diffuse, "
         "phong)"},
        {doc(R"(<bsdf type="diffuse"><rgb name="reflectance" value="0.1, 0.2"/></bsdf>)"),
         "'0.1, 0.2' has 2 numbers (allowed: one, or three for r, g, b)"},
        {doc(R"(<bsdf type="diffuse"><rgb name="reflectance" value="0.1,,0.2"/></bsdf>)"),
         "'0.1,,0.2' has an empty entry"},
        {doc(R"(<bsdf type="diffuse"><texture name="reflectance" type="bitmap"/></bsdf>)"),
         "t.xml:3: texture type=\"bitmap\" name=\"reflectance\": unknown element in <bsdf> "
         "(allowed: float, integer, boolean, string, rgb, spectrum, point, vector, transform)"},
        {doc(R"(<emitter type="area"/>)"),
         "t.xml:3: emitter type=\"area\": an area emitter must "
         "be nested in a shape"},
        {doc(R"(<shape type="sphere"><emitter type="point"/></shape>)"),
         "unknown type 'point' (allowed: area)"},
        {doc(R"(<emitter type="spot"/>)"),
         "unknown type 'spot' (allowed: point, directional, "
         "constant, envmap)"},
        {doc(R"(<emitter type="point"><rgb name="intensity" value="1, -1, 1"/></emitter>)"),
         "intensity (1, -1, 1) is negative (allowed: >= 0 per channel)"},
        {doc(R"(<emitter type="directional"><vector name="direction"/></emitter>)"),
         "direction is zero"},
        {doc(R"(<shape type="obj"><boolean name="faceNormals" value="maybe"/></shape>)"),
         "'maybe' is not a boolean (allowed: true, false)"},
        {doc(R"(<shape type="obj"/>)"),
         "t.xml:3: shape type=\"obj\": missing parameter "
         "'filename'"},
        {doc(R"(<shape type="sphere"><point name="center" x="1" w="2"/></shape>)"),
         "unknown attribute 'w' (allowed: name, x, y, z)"},
        {doc(R"(<shape type="sphere"><float value="2"/></shape>)"), "missing attribute 'name'"},
    };
    static_assert(std::size(cases) >= 25);
    for (const Case& c : cases) {
        const std::string message = errorOf([&] { parse(c.text, c.defines); });
        EXPECT_NE(message.find(c.fragment), std::string::npos)
            << "expected: " << c.fragment << "\n     got: " << message << "\n   input: " << c.text;
        EXPECT_EQ(message.find('\n'), std::string::npos) << message;  // one line
    }
}

TEST(SceneParser, LoadSceneErrors) {
    const test::TempDir dir("scene_parser");
    const std::string missing = (dir.path() / "missing.xml").string();
    EXPECT_NE(errorOf([&] { loadScene(missing); }).find("cannot open scene file '" + missing),
              std::string::npos);
    EXPECT_NE(errorOf([&] { loadScene(dir.path().string()); }).find("it is a directory"),
              std::string::npos);
    const fs::path bad = dir.write("bad.xml", doc(R"(<shape type="sphere" x="1"/>)"));
    EXPECT_NE(errorOf([&] { loadScene(bad.string()); }).find(bad.string() + ":3: shape"),
              std::string::npos);
}

const std::string kScenes = PHONGFIT_SCENES_DIR;

TEST(ShippedScenes, CornellPhong) {
    const Scene s = loadScene(kScenes + "/cornell_phong.xml");
    EXPECT_EQ(s.integrator.type, "path");
    EXPECT_EQ(s.integrator.maxDepth, 5);
    EXPECT_EQ(s.sensor.width, 256);
    EXPECT_EQ(s.sensor.height, 256);
    EXPECT_EQ(s.sensor.sampleCount, 64);
    EXPECT_EQ(s.sensor.filter, SensorDesc::Filter::Box);
    const int sphere = s.findBsdf("sphere");
    ASSERT_GE(sphere, 0);
    const BsdfDesc& b = s.bsdfs[std::size_t(sphere)];
    EXPECT_EQ(b.type, "phong");
    EXPECT_EQ(b.params.n, 30);
    EXPECT_TRUE((b.params.kd == 0.5).all());
    EXPECT_TRUE((b.params.ks == 0.2).all());

    int lights = 0, spheres = 0;
    const Vec3d camera = s.sensor.toWorld.translation();
    for (const ShapeDesc& shape : s.shapes) {
        if (shape.type == ShapeDesc::Type::Sphere) {
            ++spheres;
            EXPECT_EQ(shape.bsdf, sphere);
            EXPECT_LE(shape.center.cwiseAbs().maxCoeff() + shape.radius, 1);  // inside the box
            continue;
        }
        ASSERT_EQ(shape.type, ShapeDesc::Type::Rectangle);
        ASSERT_EQ(shape.mesh.indices.size(), 6u);
        // Every rectangle faces into the box, and the light faces down.
        const Vec3d n = windingNormal(shape.mesh, 0);
        EXPECT_LT(n.dot(centroid(shape.mesh, 0)), 0);
        if (shape.areaRadiance) {
            ++lights;
            expectNear(n, Vec3d(0, -1, 0), 1e-6);
            EXPECT_TRUE((*shape.areaRadiance > 0).all());
        }
    }
    EXPECT_EQ(lights, 1);
    EXPECT_EQ(spheres, 1);
    EXPECT_EQ(s.shapes.size(), 7u);
    // The camera is in front of the opening, looking in.
    EXPECT_GT(camera.z(), 1);
    expectNear(s.sensor.toWorld.linear().col(2), Vec3d(0, 0, -1));

    const Scene d = loadScene(kScenes + "/cornell_phong.xml", {{"kd", "0.3"}, {"spp", "8"}});
    EXPECT_TRUE((d.bsdfs[std::size_t(d.findBsdf("sphere"))].params.kd == 0.3).all());
    EXPECT_EQ(d.sensor.sampleCount, 8);
}

TEST(ShippedScenes, SpherePointAndSharp) {
    for (const auto& [file, exponent] :
         {std::pair{"sphere_point.xml", 30.0}, std::pair{"sphere_sharp.xml", 5000.0}}) {
        const Scene s = loadScene(kScenes + "/" + file);
        EXPECT_EQ(s.integrator.type, "direct") << file;
        EXPECT_EQ(s.sensor.width, 128) << file;
        EXPECT_EQ(s.sensor.height, 128) << file;
        ASSERT_EQ(s.emitters.size(), 1u) << file;
        EXPECT_EQ(s.emitters[0].type, EmitterDesc::Type::Point) << file;
        ASSERT_EQ(s.shapes.size(), 1u) << file;
        EXPECT_EQ(s.shapes[0].type, ShapeDesc::Type::Sphere);
        const int sphere = s.findBsdf("sphere");
        ASSERT_EQ(s.shapes[0].bsdf, sphere) << file;
        const PhongMaterial& m = s.bsdfs[std::size_t(sphere)].params;
        EXPECT_EQ(m.n, exponent) << file;
        EXPECT_TRUE((m.kd == 0.5).all()) << file;
        EXPECT_TRUE((m.ks == 0.3).all()) << file;
        // Camera and light on the same side, so the highlight is visible.
        const Vec3d toCamera = s.sensor.toWorld.translation().normalized();
        const Vec3d toLight = s.emitters[0].position.normalized();
        EXPECT_GT((toCamera + toLight).normalized().dot(toCamera), 0.5) << file;
    }
}

}  // namespace
}  // namespace phongfit
