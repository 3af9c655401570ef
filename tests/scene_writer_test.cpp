#include "scene_writer.h"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <functional>
#include <random>
#include <sstream>

#include "error.h"
#include "image.h"
#include "scene_parser.h"
#include "temp_dir.h"

namespace phongfit {
namespace {

namespace fs = std::filesystem;

// A temp dir with the layout the tests use: in/mesh/ for inputs, out/ elsewhere.
class TempDir : public test::TempDir {
public:
    TempDir() : test::TempDir("scene_writer") {
        fs::create_directories(path() / "in" / "mesh");
        fs::create_directories(path() / "out");
    }
};

std::string read(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    std::ostringstream text;
    text << in.rdbuf();
    return text.str();
}

std::string replaced(std::string text, const std::string& from, const std::string& to) {
    const std::size_t at = text.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    if (at != std::string::npos) text.replace(at, from.size(), to);
    return text;
}

std::string errorOf(const std::function<void()>& f) {
    try {
        f();
    } catch (const Error& e) {
        return e.what();
    }
    return "(no error)";
}

PhongMaterial material(const Color3& kd, const Color3& ks, double n) {
    PhongMaterial m;
    m.kd = kd;
    m.ks = ks;
    m.n = n;
    return m;
}

const PhongMaterial& bsdf(const Scene& s, const std::string& id) {
    const int i = s.findBsdf(id);
    EXPECT_GE(i, 0) << id;
    return s.bsdfs.at(std::size_t(i)).params;
}

const std::string kScene = R"(<?xml version="1.0"?>
<!-- A scene to write fitted values into. -->
<scene version="0.6.0">
    <default name="kd" value="0.5"/>
    <default name="n" value="30"/>
    <sensor type="perspective"><float name="fov" value="45"/></sensor>
    <bsdf type="phong" id="ball">
        <!-- keep me -->
        <float name="exponent" value="$n"/>
        <rgb name="diffuseReflectance" value="$kd"/>
        <spectrum name="specularReflectance" value='0.2'/>
    </bsdf>
    <bsdf type="phong" id="bare"/>
    <bsdf type="phong" id="partial">
        <float name="exponent" value="10"/>
    </bsdf>
    <bsdf type="diffuse" id="wall"/>
    <shape type="sphere"><ref id="ball"/></shape>
    <shape type="obj">
        <string name="filename" value="mesh/tri.obj"/>
        <bsdf type="phong" id="nested"/>
    </shape>
</scene>
)";

const std::string kObj = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";

TEST(SceneWriter, ReplacesOnlyTheValuesOfTheFittedBsdf) {
    const TempDir dir;
    dir.write("in/mesh/tri.obj", kObj);
    const std::string in = dir.write("in/scene.xml", kScene);
    const std::string out = dir.at("in/fitted.xml");
    writeSceneWithMaterials(
        in, {}, {{"ball", material(Color3(0.1, 0.2, 0.3), Color3::Constant(0.25), 123.5)}}, out);
    // Byte for byte the input, but for the three values; `$name`s there become literals.
    std::string expected = replaced(kScene, R"(value="$n")", R"(value="123.5")");
    expected = replaced(expected, R"(value="$kd")", R"(value="0.1, 0.2, 0.3")");
    expected = replaced(expected, R"(value='0.2')", R"(value='0.25')");
    EXPECT_EQ(read(out), expected);

    const Scene s = loadScene(out);
    const PhongMaterial& ball = bsdf(s, "ball");
    EXPECT_TRUE((ball.kd == Color3(0.1, 0.2, 0.3)).all());
    EXPECT_TRUE((ball.ks == 0.25).all());
    EXPECT_EQ(ball.n, 123.5);
    EXPECT_EQ(read(in), kScene);  // the input is untouched
}

TEST(SceneWriter, AddsParametersTheFileLeftAtTheirDefaults) {
    const TempDir dir;
    dir.write("in/mesh/tri.obj", kObj);
    const std::string in = dir.write("in/scene.xml", kScene);
    const std::string out = dir.at("in/fitted.xml");
    const PhongMaterial bare = material(Color3::Constant(0.1), Color3::Constant(0.2), 40);
    const PhongMaterial partial = material(Color3(0.3, 0.2, 0.1), Color3(0, 0.05, 0.5), 2);
    const PhongMaterial nested = material(Color3::Constant(0.6), Color3::Constant(0), 0);
    writeSceneWithMaterials(in, {}, {{"bare", bare}, {"partial", partial}, {"nested", nested}},
                            out);
    const std::string text = read(out);
    EXPECT_NE(text.find(R"(
    <bsdf type="phong" id="bare">
        <rgb name="diffuseReflectance" value="0.1"/>
        <rgb name="specularReflectance" value="0.2"/>
        <float name="exponent" value="40"/>
    </bsdf>
    <bsdf type="phong" id="partial">
        <rgb name="diffuseReflectance" value="0.3, 0.2, 0.1"/>
        <rgb name="specularReflectance" value="0, 0.05, 0.5"/>
        <float name="exponent" value="2"/>
    </bsdf>
)"),
              std::string::npos)
        << text;
    // The untouched parts are kept.
    EXPECT_EQ(text.substr(0, text.find(R"(<bsdf type="phong" id="bare")")),
              kScene.substr(0, kScene.find(R"(<bsdf type="phong" id="bare")")));

    const Scene s = loadScene(out);
    for (const auto& [id, m] :
         {std::pair{"bare", bare}, {"partial", partial}, {"nested", nested}}) {
        EXPECT_TRUE((bsdf(s, id).kd == m.kd).all()) << id;
        EXPECT_TRUE((bsdf(s, id).ks == m.ks).all()) << id;
        EXPECT_EQ(bsdf(s, id).n, m.n) << id;
    }
    // Not fitted: as before, still through its `$name`s.
    EXPECT_TRUE((bsdf(s, "ball").kd == 0.5).all());
    EXPECT_EQ(bsdf(s, "ball").n, 30);
    EXPECT_NE(text.find(R"(value="$kd")"), std::string::npos);
}

TEST(SceneWriter, ValuesRoundTripExactly) {
    const TempDir dir;
    dir.write("in/mesh/tri.obj", kObj);
    const std::string in = dir.write("in/scene.xml", kScene);
    const std::string out = dir.at("in/fitted.xml");
    const PhongMaterial m = material(Color3(0.1234567890123456789, 1.0 / 3.0, 1e-7),
                                     Color3(2.0 / 3.0, 0.5, 1e-300), 987654.321);
    writeSceneWithMaterials(in, {}, {{"ball", m}}, out);
    const Scene fitted = loadScene(out);  // kept alive: `back` refers into it
    const PhongMaterial& back = bsdf(fitted, "ball");
    EXPECT_TRUE((back.kd == m.kd).all()) << back.kd.transpose();
    EXPECT_TRUE((back.ks == m.ks).all()) << back.ks.transpose();
    EXPECT_EQ(back.n, m.n);
}

TEST(SceneWriter, DefinesResolveTheFileAndStayDefines) {
    const TempDir dir;
    dir.write("in/mesh/tri.obj", kObj);
    const std::string in = dir.write("in/scene.xml", kScene);
    const std::string out = dir.at("in/fitted.xml");
    const std::map<std::string, std::string> defines = {{"kd", "0.7"}};
    writeSceneWithMaterials(
        in, defines, {{"bare", material(Color3::Constant(0.1), Color3::Constant(0.1), 5)}}, out);
    EXPECT_TRUE((bsdf(loadScene(out, defines), "ball").kd == 0.7).all());
    EXPECT_TRUE((bsdf(loadScene(out), "ball").kd == 0.5).all());
}

TEST(SceneWriter, RelativeObjPathsFollowTheOutputDirectory) {
    const TempDir dir;
    dir.write("in/mesh/tri.obj", kObj);
    const std::string in = dir.write("in/scene.xml", kScene);
    const std::string out = dir.at("out/fitted.xml");
    writeSceneWithMaterials(in, {}, {}, out);
    EXPECT_EQ(read(out), replaced(kScene, "mesh/tri.obj", "../in/mesh/tri.obj"));
    const Scene moved = loadScene(out);
    const Scene original = loadScene(in);
    ASSERT_EQ(moved.shapes.size(), 2u);
    EXPECT_EQ(moved.shapes[1].mesh.positions, original.shapes[1].mesh.positions);

    // In the same directory nothing needs to change.
    writeSceneWithMaterials(in, {}, {}, dir.at("in/copy.xml"));
    EXPECT_EQ(read(dir.at("in/copy.xml")), kScene);
}

TEST(SceneWriter, RelativeEnvMapPathsFollowTheOutputDirectory) {
    const TempDir dir;
    Image probe(4, 2);
    probe.set(1, 1, Color<float>(1, 2, 3));
    fs::create_directories(dir.at("in/probes"));
    writeExr(probe, dir.at("in/probes/sky.exr"));
    const std::string scene = R"(<scene version="0.6.0">
    <sensor type="perspective"><float name="fov" value="45"/></sensor>
    <bsdf type="phong" id="ball"/>
    <shape type="sphere"><ref id="ball"/></shape>
    <emitter type="envmap"><string name="filename" value="probes/sky.exr"/></emitter>
</scene>
)";
    const std::string in = dir.write("in/scene.xml", scene);
    fs::create_directories(dir.at("out/deeper"));
    const std::string out = dir.at("out/deeper/fitted.xml");
    writeSceneWithMaterials(in, {}, {}, out);
    EXPECT_EQ(read(out), replaced(scene, "probes/sky.exr", "../../in/probes/sky.exr"));
    const Scene moved = loadScene(out);
    ASSERT_EQ(moved.emitters.size(), 1u);
    EXPECT_TRUE((moved.emitters[0].map->at(1, 1) == Color<float>(1, 2, 3)).all());
}

TEST(SceneWriter, OverwritesInPlace) {
    const TempDir dir;
    dir.write("in/mesh/tri.obj", kObj);
    const std::string in = dir.write("in/scene.xml", kScene);
    writeSceneWithMaterials(
        in, {}, {{"ball", material(Color3::Constant(0.2), Color3::Constant(0.3), 7)}}, in);
    EXPECT_EQ(bsdf(loadScene(in), "ball").n, 7);
    EXPECT_EQ(std::distance(fs::directory_iterator(dir.at("in")), fs::directory_iterator()), 2)
        << "no temporary file is left behind";
}

TEST(SceneWriter, ErrorsLeaveNoOutput) {
    const TempDir dir;
    dir.write("in/mesh/tri.obj", kObj);
    const std::string in = dir.write("in/scene.xml", kScene);
    const std::string out = dir.at("out/fitted.xml");
    const PhongMaterial good = material(Color3::Constant(0.2), Color3::Constant(0.3), 7);
    const std::string badScene =
        dir.write("in/bad.xml", replaced(kScene, R"(value="$kd")", R"(value="$undefined")"));
    struct Case {
        std::function<void()> write;
        std::string fragment;
    };
    const Case cases[] = {
        {[&] {
             writeSceneWithMaterials(in, {}, {{"nope", good}}, out);
         },
         in + ": no bsdf with id 'nope' (allowed: the phong bsdf ids in the file: 'ball', 'bare', "
              "'partial', 'nested')"},
        {[&] {
             writeSceneWithMaterials(in, {}, {{"", good}}, out);
         },
         "no bsdf with id ''"},
        {[&] {
             writeSceneWithMaterials(in, {}, {{"wall", good}}, out);
         },
         in + ":17: bsdf 'wall' is diffuse, not phong"},
        {[&] {
             writeSceneWithMaterials(
                 in, {}, {{"ball", material(Color3::Constant(0.7), Color3::Constant(0.5), 7)}},
                 out);
         },
         "fitted material 'ball': kd + ks = 0.7 + 0.5 = 1.2"},
        {[&] {
             writeSceneWithMaterials(
                 in, {}, {{"ball", material(Color3::Constant(0.1), Color3::Constant(0.5), -3)}},
                 out);
         },
         "fitted material 'ball': exponent n = -3 is invalid"},
        {[&] {
             writeSceneWithMaterials(dir.at("in/missing.xml"), {}, {{"ball", good}}, out);
         },
         "cannot open scene file '" + dir.at("in/missing.xml")},
        {[&] {
             writeSceneWithMaterials(badScene, {}, {{"ball", good}}, out);
         },
         badScene + ":10: rgb name=\"diffuseReflectance\": undefined variable '$undefined'"},
        {[&] {
             writeSceneWithMaterials(in, {}, {{"ball", good}}, dir.at("nodir/fitted.xml"));
         },
         "directory '" + dir.at("nodir") + "' does not exist"},
    };
    for (const Case& c : cases) {
        const std::string message = errorOf(c.write);
        EXPECT_NE(message.find(c.fragment), std::string::npos)
            << "expected: " << c.fragment << "\n     got: " << message;
        EXPECT_FALSE(fs::exists(out));
        EXPECT_TRUE(fs::is_empty(dir.at("out")));
    }
    EXPECT_EQ(read(in), kScene);
}

}  // namespace
}  // namespace phongfit
