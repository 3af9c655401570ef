// `phongfit synth`: drawing samples, baking scenes, and the command end to end (generation,
// determinism, resume after SIGINT and after a lost truth.json, one-line errors for bad configs).
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <csignal>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <random>
#include <sstream>

#include "file_snapshot.h"
#include "image.h"
#include "sample_spec.h"
#include "scene_baker.h"
#include "scene_parser.h"
#include "subprocess.h"
#include "synth_config.h"

namespace phongfit {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

const std::string kScenes = PHONGFIT_SCENES_DIR;
const std::string kSmallConfig = PHONGFIT_CONFIGS_DIR "/small.json";

using test::snapshot;

std::string readFile(const fs::path& path) { return test::readFileBytes(path); }

void expectSameFiles(const fs::path& a, const fs::path& b) {
    const auto fa = snapshot(a), fb = snapshot(b);
    ASSERT_EQ(fa.size(), fb.size());
    for (const auto& [name, bytes] : fa) {
        ASSERT_TRUE(fb.count(name)) << name;
        EXPECT_TRUE(bytes == fb.at(name)) << name << " differs";
    }
}

int completeSamples(const fs::path& dir) {
    int n = 0;
    if (!fs::exists(dir)) return 0;
    for (const auto& entry : fs::directory_iterator(dir))
        n += fs::exists(entry.path() / "truth.json");
    return n;
}

class Synth : public ::testing::Test {
protected:
    void SetUp() override {
        dir_ = fs::temp_directory_path() / ("phongfit_synth_" + std::to_string(getpid()) + "_" +
                                            std::to_string(std::random_device{}()));
        fs::create_directories(dir_);
    }
    void TearDown() override { fs::remove_all(dir_); }
    fs::path path(const std::string& name) const { return dir_ / name; }

    // A config in the temporary folder (scenes by absolute path).
    std::string writeConfig(const std::string& name, const json& config) const {
        std::ofstream(path(name)) << config.dump(2);
        return path(name).string();
    }
    static json baseConfig() {
        return {{"scenes", {kScenes + "/sphere_point.xml"}},
                {"material", "sphere"},
                {"samples", 3},
                {"seed", 5},
                {"spp", 4},
                {"albedo", {0.4, 0.9}},
                {"ks_share", {0.1, 0.5}},
                {"n", {5, 500}},
                {"defines", {{"width", 16}, {"height", 16}}}};
    }
    static test::ProcessResult synth(const std::string& config, const fs::path& out,
                                     std::vector<std::string> extra = {},
                                     const test::SignalPlan& signal = {}) {
        std::vector<std::string> args = {"synth", config, "-o", out.string(), "--quiet"};
        args.insert(args.end(), extra.begin(), extra.end());
        return test::runPhongfit(args, signal);
    }

    fs::path dir_;
};

TEST(SampleSpec, IsAPureFunctionOfSeedAndIndexWithinTheRanges) {
    SynthConfig config;
    config.seed = 9;
    GroupConfig g;
    g.name = "a";
    g.samples = 50;
    g.scenes = {"s.xml"};
    g.scenePaths = {"s.xml"};
    g.material = "sphere";
    g.spp = 4;
    g.albedo = {0.9, 1.0};
    g.ksShare = {0.1, 0.3};
    g.n = {10, 1e4};
    g.colour = true;
    g.tint = {0.5, 1};
    g.light = LightSpec{{120, 150}, {0, 360}, {7, 7}};
    g.defines["width"] = DefineSpec{std::nullopt, {16, 32, true}};
    config.groups = {g, g};
    config.groups[1].name = "b";
    config.groups[1].colour = false;

    std::vector<SampleSpec> forward;
    for (int i = 0; i < 100; ++i) forward.push_back(drawSample(config, i));
    for (int i = 99; i >= 0; --i) {
        const SampleSpec again = drawSample(config, i);
        EXPECT_EQ(again.defines, forward[i].defines) << i;
        EXPECT_EQ(again.renderSeed, forward[i].renderSeed) << i;
    }
    for (const SampleSpec& s : forward) {
        EXPECT_EQ(s.group, s.index < 50 ? 0 : 1);
        const PhongMaterial& m = s.material;
        validatePhong(m, s.name);  // kd + ks <= 1 per channel
        EXPECT_GE(m.n, 10);
        EXPECT_LE(m.n, 1e4);
        const double albedo = s.group == 0 ? (m.kd + m.ks).maxCoeff() : m.kd[0] + m.ks[0];
        EXPECT_LE(albedo, 1.0 + 1e-12);
        if (s.group == 1) {
            EXPECT_TRUE((m.kd == m.kd[0]).all() && (m.ks == m.ks[0]).all());
            EXPECT_GE(albedo, 0.9 - 1e-12);
            EXPECT_NEAR(m.ks[0] / albedo, 0.2, 0.1 + 1e-12);
        }
        ASSERT_TRUE(s.light.has_value());
        EXPECT_NEAR(s.light->position.norm(), 7, 1e-9);
        // The phase is the angle from +z, where the camera is.
        const double phase = std::acos(s.light->position.z() / 7) * 180 / kPi;
        EXPECT_NEAR(phase, s.light->phaseDeg, 1e-6);
        EXPECT_GE(phase, 120 - 1e-6);
        EXPECT_LE(phase, 150 + 1e-6);
        const int width = std::stoi(s.defines.at("width"));
        EXPECT_GE(width, 16);
        EXPECT_LE(width, 32);
        EXPECT_EQ(s.defines.at("width"), std::to_string(width));  // integers stay integers
        // Baked text reads back as exactly the drawn value.
        EXPECT_EQ(std::stod(s.defines.at("n")), m.n);
    }
    EXPECT_NE(forward[0].defines, forward[1].defines);
    EXPECT_NE(forward[0].renderSeed, forward[1].renderSeed);
    EXPECT_EQ(sampleName(7, 100), "sample_0007");
    EXPECT_EQ(sampleName(7, 20000), "sample_00007");
}

// A grid: scene-major, then exponent, then material; exactly the listed values.
TEST(SampleSpec, GridTakesEveryExponentWithEveryMaterialForEveryScene) {
    SynthConfig config;
    GroupConfig g;
    g.name = "matrix";
    g.scenes = g.scenePaths = {"a.xml", "b.xml"};
    g.material = "sphere";
    g.spp = 4;
    g.grid = GridSpec{
        {1, 300, 30000},
        {{Color3(0.6, 0.5, 0.4), Color3::Zero()}, {Color3::Constant(0.45), Color3::Constant(0.5)}}};
    g.samples = 2 * g.grid->cells();
    config.groups = {g};
    ASSERT_EQ(config.totalSamples(), 12);
    for (int i = 0; i < 12; ++i) {
        const SampleSpec s = drawSample(config, i);
        EXPECT_EQ(s.scene, i / 6) << i;
        EXPECT_EQ(s.material.n, (std::vector<double>{1, 300, 30000})[(i % 6) / 2]) << i;
        const GridSpec::Material& m = g.grid->materials[i % 2];
        EXPECT_TRUE((s.material.kd == m.kd).all() && (s.material.ks == m.ks).all()) << i;
        EXPECT_EQ(s.defines.at("kd"), i % 2 ? "0.45" : "0.6, 0.5, 0.4");
        EXPECT_EQ(s.defines.at("ks"), i % 2 ? "0.5" : "0");
    }
}

// `file` in configs/ reads as `groups` groups, each a grid of `n` with 3 materials, `samples` in
// all.
SynthConfig expectGridConfig(const std::string& file, std::size_t groups, int samples,
                             const std::vector<double>& n) {
    const SynthConfig config = loadSynthConfig(PHONGFIT_CONFIGS_DIR "/" + file);
    EXPECT_EQ(config.groups.size(), groups);
    EXPECT_EQ(config.totalSamples(), samples);
    for (const GroupConfig& g : config.groups) {
        EXPECT_TRUE(g.grid.has_value()) << g.name;
        if (!g.grid) continue;
        EXPECT_EQ(g.grid->n, n) << g.name;
        EXPECT_EQ(g.grid->materials.size(), 3u) << g.name;
    }
    return config;
}

// The recovery matrix config reads, and is what issue 12 asks: 5 lights x 2 scenes x 5 exponents x
// 3 materials.
TEST(SynthConfig, MatrixConfigHoldsEveryCell) {
    expectGridConfig("matrix.json", 10, 150, {1, 30, 300, 3000, 30000});
}

// The cells outside the matrix (README, "Outside the matrix") read: 4 scenes x 5 exponents x
// 3 materials, the first on kd + ks = 1.
TEST(SynthConfig, OutsideConfigHoldsEveryCell) {
    const SynthConfig config =
        expectGridConfig("outside.json", 4, 60, {7, 150, 1500, 12000, 150000});
    for (const GroupConfig& g : config.groups) {
        ASSERT_TRUE(g.grid && !g.grid->materials.empty()) << g.name;
        const Color3 albedo = g.grid->materials[0].kd + g.grid->materials[0].ks;
        EXPECT_TRUE(((albedo - 1).abs() < 1e-12).all()) << g.name;
    }
}

// The second set outside the matrix (README, "Outside the matrix") reads: 4 lights x 5 exponents x
// 3 materials, none of them the matrix's or the first outside set's, every kd + ks below 1.
TEST(SynthConfig, SecondOutsideConfigHoldsEveryCell) {
    const SynthConfig config =
        expectGridConfig("outside_second.json", 4, 60, {3, 60, 700, 8000, 60000});
    std::vector<GridSpec> others;
    for (const char* file : {"matrix.json", "outside.json"})
        for (const GroupConfig& g :
             loadSynthConfig(PHONGFIT_CONFIGS_DIR "/" + std::string(file)).groups)
            if (g.grid) others.push_back(*g.grid);
    for (const GroupConfig& g : config.groups) {
        if (!g.grid) continue;
        for (const GridSpec::Material& m : g.grid->materials) {
            EXPECT_TRUE(((m.kd + m.ks) < 1).all()) << g.name;
            for (const GridSpec& other : others)
                for (const GridSpec::Material& o : other.materials)
                    EXPECT_FALSE((m.kd == o.kd).all() && (m.ks == o.ks).all()) << g.name;
        }
        for (const GridSpec& other : others)
            for (const double n : g.grid->n)
                EXPECT_EQ(std::count(other.n.begin(), other.n.end(), n), 0) << g.name;
    }
}

// The drawn set (README, "Outside the matrix") reads: 48 coloured materials drawn over six lights,
// n log-uniform from 2 to 2e5, none on a grid.
TEST(SynthConfig, DrawnConfigDrawsColouredMaterialsUnderSixLights) {
    const SynthConfig config = loadSynthConfig(PHONGFIT_CONFIGS_DIR "/drawn.json");
    ASSERT_EQ(config.groups.size(), 6u);
    EXPECT_EQ(config.totalSamples(), 48);
    for (const GroupConfig& g : config.groups) {
        EXPECT_FALSE(g.grid) << g.name;
        EXPECT_TRUE(g.colour) << g.name;
        EXPECT_EQ(g.n.lo, 2) << g.name;
        EXPECT_EQ(g.n.hi, 200000) << g.name;
    }
}

// The draw under the matrix's lights (README, "Drawn under the matrix's own lights") reads: 40
// coloured materials drawn under the recovery matrix's ten lights and scenes, with their paths a
// pixel, n log-uniform from 1 to 50000.
TEST(SynthConfig, DrawnUnderMatrixLightsUsesTheMatrixScenes) {
    const SynthConfig config = loadSynthConfig(PHONGFIT_CONFIGS_DIR "/drawn_matrix_lights.json");
    const SynthConfig matrix = loadSynthConfig(PHONGFIT_CONFIGS_DIR "/matrix.json");
    ASSERT_EQ(config.groups.size(), matrix.groups.size());
    EXPECT_EQ(config.totalSamples(), 40);
    for (std::size_t i = 0; i < config.groups.size(); ++i) {
        const GroupConfig& g = config.groups[i];
        const GroupConfig& m = matrix.groups[i];
        EXPECT_EQ(g.name, m.name);
        EXPECT_EQ(g.scenePaths, m.scenePaths) << g.name;
        EXPECT_EQ(g.spp, m.spp) << g.name;
        EXPECT_FALSE(g.grid) << g.name;
        EXPECT_TRUE(g.colour) << g.name;
        EXPECT_EQ(g.n.lo, 1) << g.name;
        EXPECT_EQ(g.n.hi, 50000) << g.name;
        for (const auto& [name, define] : m.defines) {
            if (name == "width" || name == "height") continue;
            EXPECT_EQ(g.defines.count(name), 1u) << g.name << " " << name;
        }
    }
}

// The third set outside the matrix (README, "Outside the matrix") reads: 3 lights x 4 exponents x
// 3 materials, the exponents beyond every other set's up to the fitter's bound.
TEST(SynthConfig, ThirdOutsideConfigReachesTheExponentBound) {
    const SynthConfig config =
        expectGridConfig("outside_third.json", 3, 36, {150, 15000, 200000, 1e6});
    double most = 0;
    for (const char* file : {"matrix.json", "outside.json", "outside_second.json"})
        for (const GroupConfig& g :
             loadSynthConfig(PHONGFIT_CONFIGS_DIR "/" + std::string(file)).groups)
            if (g.grid)
                most = std::max(most, *std::max_element(g.grid->n.begin(), g.grid->n.end()));
    for (const GroupConfig& g : config.groups) {
        ASSERT_TRUE(g.grid) << g.name;
        EXPECT_GT(g.grid->n[2], most) << g.name;
    }
}

TEST_F(Synth, BakedSceneKeepsTheFileAndSetsTheDefaults) {
    const std::string in = kScenes + "/sphere_orbit.xml";
    const fs::path out = path("baked.xml");
    const auto replaced =
        bakeSceneDefaults(in, {{"kd", "0.1, 0.2, 0.3"}, {"light_z", "-2.5"}, {"not_declared", "1"}},
                          "made here", out.string());
    EXPECT_EQ(replaced, (std::set<std::string>{"kd", "light_z"}));
    const Scene scene = loadScene(out.string());
    const PhongMaterial& m = scene.bsdfs[scene.findBsdf("sphere")].params;
    EXPECT_EQ(m.kd[2], 0.3);
    EXPECT_EQ(scene.emitters[0].position.z(), -2.5);
    // Only the two values and the comment changed.
    std::string expected = readFile(in);
    for (const auto& [from, to] :
         {std::pair<std::string, std::string>{"name=\"kd\" value=\"0.5\"",
                                              "name=\"kd\" value=\"0.1, 0.2, 0.3\""},
          {"name=\"light_z\" value=\"5\"", "name=\"light_z\" value=\"-2.5\""},
          {"<scene version", "<!-- made here -->\n<scene version"}})
        expected.replace(expected.find(from), from.size(), to);
    EXPECT_EQ(readFile(out), expected);

    // A relative mesh path still names the same file from the baked scene's folder.
    std::ofstream(path("mesh.xml")) << "<scene version=\"0.6.0\">\n  <shape type=\"obj\">\n"
                                       "    <string name=\"filename\" value=\"meshes/a.obj\"/>\n"
                                       "  </shape>\n</scene>\n";
    fs::create_directories(path("sample"));
    bakeSceneDefaults(path("mesh.xml").string(), {}, "", path("sample/scene.xml").string());
    EXPECT_NE(readFile(path("sample/scene.xml")).find("value=\"../meshes/a.obj\""),
              std::string::npos)
        << readFile(path("sample/scene.xml"));

    // So does an environment map's, written out or given by a default, replaced or not; a default
    // that names no file keeps its value.
    std::ofstream(path("probe.xml"))
        << "<scene version=\"0.6.0\">\n  <default name=\"map\" value=\"maps/probe.exr\"/>\n"
           "  <default name=\"label\" value=\"maps/x\"/>\n"
           "  <emitter type=\"envmap\"><string name=\"filename\" value=\"$map\"/></emitter>\n"
           "  <emitter type=\"envmap\"><string name=\"filename\" value=\"sky.exr\"/></emitter>\n"
           "</scene>\n";
    bakeSceneDefaults(path("probe.xml").string(), {}, "", path("sample/probe.xml").string());
    const std::string probe = readFile(path("sample/probe.xml"));
    for (const char* moved :
         {"name=\"map\" value=\"../maps/probe.exr\"", "name=\"label\" value=\"maps/x\"",
          "value=\"$map\"", "value=\"../sky.exr\""})
        EXPECT_NE(probe.find(moved), std::string::npos) << moved << "\n" << probe;
    EXPECT_EQ(bakeSceneDefaults(path("probe.xml").string(), {{"map", "other.exr"}}, "",
                                path("sample/probe.xml").string()),
              std::set<std::string>{"map"});
    EXPECT_NE(readFile(path("sample/probe.xml")).find("name=\"map\" value=\"../other.exr\""),
              std::string::npos)
        << readFile(path("sample/probe.xml"));
}

TEST_F(Synth, SmallConfigGeneratesDeterministicallyAndRedoesOnlyIncompleteSamples) {
    const auto a = synth(kSmallConfig, path("a"));
    ASSERT_EQ(a.exitCode, 0) << a.err;
    EXPECT_NE(a.out.find("4 samples (4 rendered, 0 already complete)"), std::string::npos) << a.out;
    const json config = json::parse(readFile(kSmallConfig));
    const json index = json::parse(readFile(path("a/index.json")));
    ASSERT_EQ(index["count"], 4);
    ASSERT_EQ(index["samples"].size(), 4u);
    for (const json& entry : index["samples"]) {
        const fs::path sample = path("a") / entry["name"].get<std::string>();
        const json truth = json::parse(readFile(sample / "truth.json"));
        const Image image = readImage((sample / "image.exr").string());
        EXPECT_EQ(image.width, 48);
        EXPECT_EQ(image.height, 48);
        double sum = 0;
        for (const float v : image.rgb) sum += v;
        EXPECT_GT(sum, 0);
        // The scene file alone describes the sample: its material is the truth.
        const Scene scene = loadScene((sample / "scene.xml").string());
        const PhongMaterial& m = scene.bsdfs[scene.findBsdf("sphere")].params;
        EXPECT_EQ(m.n, truth["n"].get<double>());
        for (int c = 0; c < 3; ++c) {
            EXPECT_EQ(m.kd[c], truth["kd"][c].get<double>());
            EXPECT_EQ(m.ks[c], truth["ks"][c].get<double>());
        }
        EXPECT_EQ(scene.sensor.width, 48);
        const double albedo = m.kd[0] + m.ks[0];
        EXPECT_GE(albedo, config["albedo"][0].get<double>());
        EXPECT_LE(albedo, config["albedo"][1].get<double>());
        EXPECT_GE(m.n, config["n"][0].get<double>());
        EXPECT_LE(m.n, config["n"][1].get<double>());
        EXPECT_EQ(truth["spp"], config["spp"]);
    }

    const auto b = synth(kSmallConfig, path("b"), {"--jobs", "2"});
    ASSERT_EQ(b.exitCode, 0) << b.err;
    expectSameFiles(path("a"), path("b"));

    // A lost truth.json (and a temporary file an interrupted write left) redoes that sample only.
    const fs::path lost = path("a/sample_0002");
    const auto before = snapshot(path("a"));
    std::map<std::string, fs::file_time_type> times;
    for (const auto& entry : fs::recursive_directory_iterator(path("a")))
        if (entry.is_regular_file()) times[entry.path().string()] = entry.last_write_time();
    fs::remove(lost / "truth.json");
    std::ofstream(lost / ".image.exr.123-0.tmp.exr") << "partial";
    const auto redo = synth(kSmallConfig, path("a"));
    ASSERT_EQ(redo.exitCode, 0) << redo.err;
    EXPECT_NE(redo.out.find("(1 rendered, 3 already complete)"), std::string::npos) << redo.out;
    EXPECT_EQ(snapshot(path("a")), before);
    for (const auto& [file, time] : times) {
        if (file.find("sample_0002") != std::string::npos ||
            file.find("index.json") != std::string::npos)
            continue;
        EXPECT_EQ(fs::last_write_time(file), time) << file << " was rewritten";
    }
    EXPECT_NE(fs::last_write_time(lost / "image.exr"), times[(lost / "image.exr").string()]);

    // Another config into the same folder is refused.
    json other = config;
    other["seed"] = 2;
    other["scenes"] = {kScenes + "/sphere_point.xml"};
    const auto changed = synth(writeConfig("other.json", other), path("a"));
    EXPECT_NE(changed.exitCode, 0);
    EXPECT_NE(changed.err.find("another config"), std::string::npos) << changed.err;
    EXPECT_EQ(snapshot(path("a")), before);
}

TEST_F(Synth, ResumesAfterSigintWithTheSameFilesAsAnUninterruptedRun) {
    json config = baseConfig();
    config["samples"] = 12;
    config["spp"] = 512;
    config["defines"] = {{"width", 48}, {"height", 48}};
    const std::string file = writeConfig("resume.json", config);

    const auto start = std::chrono::steady_clock::now();
    const auto full = synth(file, path("full"));
    const auto duration = std::chrono::steady_clock::now() - start;
    ASSERT_EQ(full.exitCode, 0) << full.err;

    // Interrupted about half way through (with two jobs: resuming must not depend on how the work
    // was split).
    const auto cut =
        synth(file, path("resumed"), {"--jobs", "2"},
              {test::after(std::chrono::duration_cast<std::chrono::milliseconds>(duration / 2)),
               {SIGINT}});
    EXPECT_NE(cut.exitCode, 0);
    const int done = completeSamples(path("resumed"));
    EXPECT_LT(done, 12);
    EXPECT_FALSE(fs::exists(path("resumed/index.json")));
    if (cut.signal == 0) {  // the handler was installed: a one-line message on how to go on
        EXPECT_NE(cut.err.find("interrupted: "), std::string::npos) << cut.err;
        EXPECT_NE(cut.err.find("run the same command again to resume"), std::string::npos);
    }

    const auto resumed = synth(file, path("resumed"));
    ASSERT_EQ(resumed.exitCode, 0) << resumed.err;
    EXPECT_NE(resumed.out.find(fmt::format("({} rendered, {} already complete)", 12 - done, done)),
              std::string::npos)
        << resumed.out;
    expectSameFiles(path("full"), path("resumed"));
}

TEST_F(Synth, BadConfigsGiveOneLineNamingTheKey) {
    auto with = [](const std::string& key, const json& value) {
        json c = baseConfig();
        c[key] = value;
        return c;
    };
    json noSamples = baseConfig();
    noSamples.erase("samples");
    json groupsAndSamples = baseConfig();
    groupsAndSamples["groups"] = {{{"name", "a"}, {"samples", 1}}};
    json duplicateGroups = baseConfig();
    duplicateGroups.erase("samples");
    duplicateGroups["groups"] = {{{"name", "a"}, {"samples", 1}}, {{"name", "a"}, {"samples", 2}}};
    json grid = baseConfig();
    grid.erase("samples");
    for (const char* k : {"albedo", "ks_share", "n"}) grid.erase(k);
    grid["grid"] = {{"n", {10, 100}}, {"materials", {{{"kd", 0.5}, {"ks", 0.2}}}}};
    auto gridWith = [&](const std::string& key, const json& value) {
        json c = grid;
        c[key] = value;
        return c;
    };
    json gridBadN = grid, gridOverOne = grid, gridBadColour = grid;
    gridBadN["grid"]["n"] = {10, 0};
    gridOverOne["grid"]["materials"][0] = {{"kd", {0.5, 0.9, 0.5}}, {"ks", 0.2}};
    gridBadColour["grid"]["materials"][0]["ks"] = {0.1, 0.2};
    json badGroupValue = duplicateGroups;
    badGroupValue["groups"][1] = {{"name", "b"}, {"samples", 1}, {"ks_share", {0.5, 0.2}}};

    const std::vector<std::pair<json, std::vector<std::string>>> cases = {
        {with("albedos", 1), {"albedos", "unknown key", "allowed: scenes"}},
        {with("samples", 0), {"samples = 0", "[1, 1000000]"}},
        {with("albedo", {0.5, 1.2}), {"albedo = [0.5,1.2]", "0 <= lo <= hi <= 1"}},
        {with("n", {0, 100}), {"n = [0,100]", "log-uniformly"}},
        {with("ks_share", "0.2"), {"ks_share = \"0.2\"", "a number or [lo, hi]"}},
        {with("spp", 2.5), {"spp = 2.5", "integer"}},
        {with("seed", -1), {"seed = -1"}},
        {with("colour", "yes"), {"colour = \"yes\"", "true or false"}},
        {with("tint", {0.2, 1}), {"tint", "\"colour\": true"}},
        {with("material", "ball"), {"scenes[0]", "no phong bsdf with id 'ball'"}},
        {with("scenes", {kScenes + "/missing.xml"}), {"scenes[0]", "missing.xml"}},
        {with("scenes", json::array()), {"scenes = []", "non-empty list"}},
        {with("light", {{"phase_deg", 10}, {"azimuth_deg", 0}, {"distance", 5}}),
         {"scenes[0]", "light_x", "for light"}},
        {with("light", {{"phase_deg", 200}, {"azimuth_deg", 0}, {"distance", 5}}),
         {"light.phase_deg = 200", "<= 180"}},
        {with("defines", {{"kd", 0.5}}), {"defines.kd", "set by albedo"}},
        {with("defines", {{"exposure", 2}}), {"scenes[0]", "exposure", "for defines.exposure"}},
        {noSamples, {"missing key 'samples'"}},
        {groupsAndSamples, {"samples", "in each group"}},
        {duplicateGroups, {"groups[1].name", "a second group"}},
        {badGroupValue, {"groups[1].ks_share = [0.5,0.2]"}},
        {gridWith("samples", 2), {"samples = 2", "its cells for every scene"}},
        {gridWith("albedo", 0.5), {"albedo = 0.5", "\"grid\" beside it"}},
        {gridBadN, {"grid.n[1] = 0", "[0.001, 1e6]"}},
        {gridOverOne, {"grid.materials[0]", "at most 1 in every channel"}},
        {gridBadColour, {"grid.materials[0].ks = [0.1,0.2]", "[r, g, b]"}},
        {gridWith("grid", {{"n", {10}}}), {"missing key 'grid.materials'"}},
    };
    for (const auto& [config, fragments] : cases) {
        const std::string file = writeConfig("bad.json", config);
        const auto r = synth(file, path("out"));
        EXPECT_NE(r.exitCode, 0) << config.dump();
        for (const std::string& f : fragments)
            EXPECT_NE(r.err.find(f), std::string::npos) << "'" << f << "' not in: " << r.err;
        EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
        EXPECT_NE(r.err.find("bad.json"), std::string::npos) << r.err;
        EXPECT_FALSE(fs::exists(path("out"))) << config.dump();
    }

    std::ofstream(path("broken.json")) << "{\"samples\": 3,";
    const auto broken = synth(path("broken.json").string(), path("out"));
    EXPECT_NE(broken.exitCode, 0);
    EXPECT_NE(broken.err.find("broken.json: not valid JSON"), std::string::npos) << broken.err;
    EXPECT_EQ(std::count(broken.err.begin(), broken.err.end(), '\n'), 1) << broken.err;
}

}  // namespace
}  // namespace phongfit
