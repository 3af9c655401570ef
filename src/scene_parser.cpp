#include "scene_parser.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <optional>
#include <pugixml.hpp>
#include <sstream>
#include <string_view>
#include <utility>
#include <variant>
#include <vector>

#include "envmap_file.h"
#include "error.h"
#include "obj_mesh.h"
#include "scene_params.h"
#include "scene_shapes.h"
#include "scene_variables.h"
#include "scene_xml.h"

namespace phongfit {
namespace {

using namespace scene_xml;

// Limits with clear errors instead of memory or time exhaustion (the render command's flags allow
// the same ranges). A film of kMaxFilmPixels takes about 3 GB to render.
constexpr int kMaxFilmSize = 16384;
constexpr long kMaxFilmPixels = 1L << 25;
constexpr int kMaxSampleCount = 1 << 20;
constexpr int kMaxDepth = 1000;
constexpr std::size_t kMaxSceneTriangles = kMaxMeshTriangles;
// Embree refuses (asserts on) rays whose origin lies beyond 1.8e18 (its FLT_LARGE); rays start at
// the camera and on surfaces, so both stay well inside that.
constexpr double kMaxCoordinate = 1e15;
// Meshes live in OBJ files; the XML parser's tree takes several times the text.
constexpr std::uintmax_t kMaxSceneBytes = std::uintmax_t(64) << 20;

class Parser {
public:
    Parser(const std::string& text, const std::string& file, const Vars& defines,
           std::string baseDir)
        : ctx_(file, text), baseDir_(std::move(baseDir)) {
        root_ = loadRoot(doc_, text, ctx_);
        ctx_.checkAttributes(root_, {"version"});
        const std::string version =
            ctx_.required(root_, "version", "the format version, e.g. version=\"0.6.0\"");
        if (!version.starts_with("0."))
            ctx_.fail(root_, fmt::format("version '{}' is not supported (allowed: 0.x.y, the "
                                         "Mitsuba 0.6 format)",
                                         version));
        ctx_.vars = collectVariables(ctx_, root_, defines);
    }

    Scene run() {
        bool haveIntegrator = false, haveSensor = false;
        for (const pugi::xml_node c : root_.children()) {
            if (c.type() != pugi::node_element) ctx_.failText(c);
            const std::string_view tag = c.name();
            if (tag == "default") continue;  // read by collectVariables
            const auto once = [&](bool& seen) {
                if (seen) ctx_.fail(c, fmt::format("a second <{}> (allowed: one)", tag));
                seen = true;
            };
            if (tag == "integrator") {
                once(haveIntegrator);
                parseIntegrator(c);
            } else if (tag == "sensor") {
                once(haveSensor);
                parseSensor(c);
            } else if (tag == "bsdf") {
                parseBsdf(c);
            } else if (tag == "shape") {
                parseShape(c);
            } else if (tag == "emitter") {
                parseEmitter(c, nullptr);
            } else {
                ctx_.fail(c,
                          "unknown element in <scene> (allowed: default, integrator, sensor, "
                          "bsdf, shape, emitter)");
            }
        }
        if (!haveSensor)
            ctx_.fail(root_, "no <sensor> (allowed: exactly one sensor type=\"perspective\")");
        if (!haveIntegrator) {
            // Mitsuba 0.6's default.
            scene_.integrator.type = "direct";
            scene_.integrator.maxDepth = 2;
        }
        scene_.file = ctx_.file();
        return std::move(scene_);
    }

private:
    // Sorts an object's children into parameters and nested objects (tags in `nestedAllowed`).
    Params collect(pugi::xml_node n, Names nestedAllowed, std::vector<pugi::xml_node>& nested) {
        Params params(ctx_, n);
        for (const pugi::xml_node c : n.children()) {
            if (c.type() != pugi::node_element) ctx_.failText(c);
            if (contains(kParamTags, c.name())) {
                params.add(c);
            } else if (contains(nestedAllowed, c.name())) {
                nested.push_back(c);
            } else {
                std::vector<std::string> allowed(kParamTags.begin(), kParamTags.end());
                allowed.insert(allowed.end(), nestedAllowed.begin(), nestedAllowed.end());
                ctx_.fail(c, fmt::format("unknown element in <{}> (allowed: {})", n.name(),
                                         fmt::join(allowed, ", ")));
            }
        }
        return params;
    }

    std::string typeOf(pugi::xml_node n, Names allowed) const {
        const std::string type =
            ctx_.required(n, "type", fmt::format("allowed: {}", fmt::join(allowed, ", ")));
        if (!contains(allowed, type))
            ctx_.fail(
                n, fmt::format("unknown type '{}' (allowed: {})", type, fmt::join(allowed, ", ")));
        return type;
    }

    // Ids are global, as in Mitsuba, and must be unique; returns the id ("" if none).
    std::string registerId(pugi::xml_node n, const std::string& kind, int index) {
        const std::optional<std::string> id = ctx_.attr(n, "id");
        if (!id) return "";
        if (id->empty()) ctx_.fail(n, "empty id (allowed: a non-empty name)");
        if (const auto it = ids_.find(*id); it != ids_.end())
            ctx_.fail(n, fmt::format("duplicate id '{}' (already used at {})", *id,
                                     it->second.loc.str()));
        ids_.emplace(*id, IdEntry{kind, index, ctx_.loc(n)});
        return *id;
    }

    void parseIntegrator(pugi::xml_node n) {
        ctx_.checkAttributes(n, {"type", "id"});
        IntegratorDesc& integrator = scene_.integrator;
        integrator.type = typeOf(n, {"path", "direct"});
        std::vector<pugi::xml_node> nested;
        Params p = collect(n, {}, nested);
        if (integrator.type == "path") {
            integrator.maxDepth = p.getInt("maxDepth").value_or(-1);
            integrator.rrDepth = p.getInt("rrDepth").value_or(5);
            if (integrator.maxDepth < -1)
                ctx_.fail(p.node("maxDepth"), fmt::format("maxDepth {} is invalid (allowed: -1 for "
                                                          "unbounded, or >= 0)",
                                                          integrator.maxDepth));
            if (integrator.rrDepth < 1)
                ctx_.fail(p.node("rrDepth"),
                          fmt::format("rrDepth {} is invalid (allowed: >= 1)", integrator.rrDepth));
            for (const auto& [name, depth] : {std::pair{"maxDepth", integrator.maxDepth},
                                              std::pair{"rrDepth", integrator.rrDepth}})
                if (depth > kMaxDepth)
                    ctx_.fail(p.node(name), fmt::format("{} {} is too large (allowed: up to {})",
                                                        name, depth, kMaxDepth));
        } else {
            // The renderer runs `direct` as a path tracer that stops after direct illumination.
            integrator.maxDepth = 2;
        }
        p.finish();
        registerId(n, "integrator", 0);
    }

    void parseSensor(pugi::xml_node n) {
        ctx_.checkAttributes(n, {"type", "id"});
        typeOf(n, {"perspective"});
        std::vector<pugi::xml_node> nested;
        Params p = collect(n, {"sampler", "film"}, nested);
        SensorDesc& sensor = scene_.sensor;
        const std::optional<double> fov = p.getFloat("fov");
        if (!fov)
            ctx_.fail(n,
                      "missing parameter 'fov' (the field of view in degrees, e.g. <float "
                      "name=\"fov\" value=\"45\"/>)");
        if (!(*fov > 0 && *fov < 180))
            ctx_.fail(p.node("fov"),
                      fmt::format("fov {} is out of range (allowed: 0 < fov < 180 degrees)", *fov));
        sensor.fovDegrees = *fov;
        const std::string axis = p.getString("fovAxis").value_or("x");
        using Axis = SensorDesc::FovAxis;
        const std::map<std::string, Axis> axes = {
            {"x", Axis::X}, {"y", Axis::Y}, {"smaller", Axis::Smaller}, {"larger", Axis::Larger}};
        const auto it = axes.find(axis);
        if (it == axes.end())
            ctx_.fail(p.node("fovAxis"), fmt::format("unknown fovAxis '{}' (allowed: x, y, "
                                                     "smaller, larger)",
                                                     axis));
        sensor.fovAxis = it->second;
        sensor.toWorld = p.getTransform("toWorld");
        if (!(sensor.toWorld.translation().cwiseAbs().maxCoeff() <= kMaxCoordinate))
            ctx_.fail(p.node("toWorld"), fmt::format("the camera is placed beyond +-{:g} (allowed: "
                                                     "coordinates within +-{:g})",
                                                     kMaxCoordinate, kMaxCoordinate));
        p.finish();

        bool haveSampler = false, haveFilm = false;
        for (const pugi::xml_node c : nested) {
            const std::string_view tag = c.name();
            bool& seen = tag == "sampler" ? haveSampler : haveFilm;
            if (seen) ctx_.fail(c, fmt::format("a second <{}> in the sensor (allowed: one)", tag));
            seen = true;
            if (tag == "sampler")
                parseSampler(c);
            else
                parseFilm(c);
        }
        registerId(n, "sensor", 0);
    }

    void parseSampler(pugi::xml_node n) {
        ctx_.checkAttributes(n, {"type", "id"});
        // As Mitsuba: sobol, one Sobol sequence over all dimensions; ldsampler, padded 2D points.
        scene_.sensor.pixelSampler =
            pixelSamplerType(typeOf(n, {"independent", "ldsampler", "sobol"}));
        std::vector<pugi::xml_node> nested;
        Params p = collect(n, {}, nested);
        const int count = p.getInt("sampleCount").value_or(4);
        if (count < 1)
            ctx_.fail(p.node("sampleCount"),
                      fmt::format("sampleCount {} is invalid (allowed: >= 1)", count));
        if (count > kMaxSampleCount)
            ctx_.fail(p.node("sampleCount"),
                      fmt::format("sampleCount {} is too large (allowed: up to {}; --spp overrides "
                                  "it)",
                                  count, kMaxSampleCount));
        scene_.sensor.sampleCount = count;
        p.finish();
        registerId(n, "sampler", 0);
    }

    void parseFilm(pugi::xml_node n) {
        ctx_.checkAttributes(n, {"type", "id"});
        typeOf(n, {"hdrfilm"});
        std::vector<pugi::xml_node> nested;
        Params p = collect(n, {"rfilter"}, nested);
        SensorDesc& sensor = scene_.sensor;
        for (const auto& [name, size] :
             {std::pair{"width", &sensor.width}, std::pair{"height", &sensor.height}}) {
            *size = p.getInt(name).value_or(*size);
            if (*size < 1 || *size > kMaxFilmSize)
                ctx_.fail(p.node(name), fmt::format("{} {} is out of range (allowed: 1 to {})",
                                                    name, *size, kMaxFilmSize));
        }
        const long pixels = long(sensor.width) * sensor.height;
        if (pixels > kMaxFilmPixels)
            ctx_.fail(n, fmt::format("the film has {}x{} = {} pixels (allowed: up to {}, e.g. "
                                     "8192x4096)",
                                     sensor.width, sensor.height, pixels, kMaxFilmPixels));
        p.finish();
        if (nested.size() > 1)
            ctx_.fail(nested[1], "a second <rfilter> in the film (allowed: one)");
        if (!nested.empty()) parseFilter(nested[0]);
        registerId(n, "film", 0);
    }

    void parseFilter(pugi::xml_node n) {
        ctx_.checkAttributes(n, {"type", "id"});
        const std::string type = typeOf(n, {"box", "gaussian", "tent"});
        std::vector<pugi::xml_node> nested;
        Params p = collect(n, {}, nested);
        SensorDesc& sensor = scene_.sensor;
        sensor.filterNamed = true;
        const PixelFilterName& f =
            *std::find_if(std::begin(kPixelFilters), std::end(kPixelFilters),
                          [&](const PixelFilterName& known) { return type == known.type; });
        sensor.filter = f.filter;
        if (f.width != nullptr) {
            // In pixels: > 0, and within the film's reach of a pixel.
            sensor.filterWidth = p.getFloat(f.width).value_or(f.defaultWidth);
            if (!filterWidthAllowed(sensor.filterWidth))
                ctx_.fail(p.node(f.width),
                          fmt::format("{} {} is invalid (allowed: > 0 and <= {} pixels)", f.width,
                                      sensor.filterWidth, kMaxFilterWidth));
        }
        p.finish();
        registerId(n, "rfilter", 0);
    }

    int parseBsdf(pugi::xml_node n) {
        ctx_.checkAttributes(n, {"type", "id"});
        BsdfDesc bsdf;
        bsdf.type = typeOf(n, {"diffuse", "phong"});
        bsdf.loc = ctx_.loc(n);
        std::vector<pugi::xml_node> nested;
        Params p = collect(n, {}, nested);
        const Color3 half = Color3::Constant(0.5);
        if (bsdf.type == "diffuse") {
            bsdf.params.kd = p.getColor("reflectance").value_or(half);
        } else {
            // Mitsuba 0.6's phong defaults.
            bsdf.params.n = p.getFloat("exponent").value_or(30);
            bsdf.params.kd = p.getColor("diffuseReflectance").value_or(half);
            bsdf.params.ks = p.getColor("specularReflectance").value_or(Color3::Constant(0.2));
        }
        p.finish();
        const int index = int(scene_.bsdfs.size());
        bsdf.id = registerId(n, "bsdf", index);
        validatePhong(bsdf.params, bsdf.id.empty()
                                       ? fmt::format("bsdf ({})", bsdf.loc.str())
                                       : fmt::format("bsdf '{}' ({})", bsdf.id, bsdf.loc.str()));
        scene_.bsdfs.push_back(std::move(bsdf));
        return index;
    }

    int resolveRef(pugi::xml_node n) const {
        ctx_.checkAttributes(n, {"id"});
        ctx_.checkNoChildren(n);
        const std::string id = ctx_.required(n, "id", "the id of a bsdf defined above");
        const auto it = ids_.find(id);
        if (it == ids_.end()) {
            std::vector<std::string> bsdfIds;
            for (const BsdfDesc& b : scene_.bsdfs)
                if (!b.id.empty()) bsdfIds.push_back("'" + b.id + "'");
            ctx_.fail(
                n, fmt::format(
                       "no object with id '{}' is defined above (allowed: bsdf ids "
                       "defined before this line: {})",
                       id, bsdfIds.empty() ? "none" : fmt::format("{}", fmt::join(bsdfIds, ", "))));
        }
        if (it->second.kind != "bsdf")
            ctx_.fail(n, fmt::format("'{}' is a {} (at {}), not a bsdf (allowed: ids of bsdfs)", id,
                                     it->second.kind, it->second.loc.str()));
        return it->second.index;
    }

    void parseShape(pugi::xml_node n) {
        ctx_.checkAttributes(n, {"type", "id"});
        const std::string type = typeOf(n, {"sphere", "rectangle", "cube", "disk", "obj"});
        std::vector<pugi::xml_node> nested;
        Params p = collect(n, {"bsdf", "ref", "emitter"}, nested);
        ShapeDesc shape;
        shape.loc = ctx_.loc(n);
        if (type == "sphere") {
            shape.type = ShapeDesc::Type::Sphere;
            const Vec3d center = p.getPoint("center").value_or(Vec3d::Zero());
            const double radius = p.getFloat("radius").value_or(1);
            if (!(radius > 0))
                ctx_.fail(p.node("radius"),
                          fmt::format("radius {} is invalid (allowed: > 0)", radius));
            const Eigen::Affine3d toWorld = p.getTransform("toWorld");
            const Eigen::Matrix3d gram = toWorld.linear().transpose() * toWorld.linear();
            const double scale2 = gram.trace() / 3;
            if ((gram - scale2 * Eigen::Matrix3d::Identity()).norm() > 1e-6 * scale2)
                ctx_.fail(p.node("toWorld"),
                          "toWorld scales a sphere non-uniformly (allowed: "
                          "translate, rotate, uniform scale)");
            shape.center = toWorld * center;
            shape.radius = radius * std::sqrt(scale2);
        } else if (type == "rectangle") {
            shape.type = ShapeDesc::Type::Rectangle;
            shape.mesh = transformed(unitRectangle(), p.getTransform("toWorld"));
        } else if (type == "cube") {
            shape.type = ShapeDesc::Type::Cube;
            shape.mesh = transformed(unitCube(), p.getTransform("toWorld"));
        } else if (type == "disk") {
            shape.type = ShapeDesc::Type::Disk;
            shape.toWorld = p.getTransform("toWorld");
        } else {
            shape.type = ShapeDesc::Type::Obj;
            const std::string path = fileParameter(n, p, "the OBJ file", "mesh.obj");
            const bool faceNormals = p.getBool("faceNormals").value_or(false);
            TriangleMesh mesh = loadObjMesh(path, ctx_.where(p.node("filename")));
            if (faceNormals) mesh.normals.clear();
            shape.mesh = transformed(std::move(mesh), p.getTransform("toWorld"));
        }
        if (worldExtent(shape) > kMaxCoordinate)
            ctx_.fail(n, fmt::format("the shape reaches {:g} in world space (allowed: coordinates "
                                     "and sizes within +-{:g}, as the renderer works in float)",
                                     worldExtent(shape), kMaxCoordinate));
        triangles_ += shape.mesh.indices.size() / 3;
        if (triangles_ > kMaxSceneTriangles)
            ctx_.fail(n, fmt::format("the scene has {} triangles with this shape (allowed: up to "
                                     "{})",
                                     triangles_, kMaxSceneTriangles));
        p.finish();

        for (const pugi::xml_node c : nested) {
            const std::string_view tag = c.name();
            if (tag == "emitter") {
                if (shape.areaRadiance)
                    ctx_.fail(c, "a second emitter in the shape (allowed: one area emitter)");
                parseEmitter(c, &shape);
                continue;
            }
            if (shape.bsdf >= 0)
                ctx_.fail(c,
                          "the shape already has a bsdf (allowed: one nested <bsdf> or one "
                          "<ref>)");
            shape.bsdf = tag == "bsdf" ? parseBsdf(c) : resolveRef(c);
        }
        if (shape.bsdf < 0) {
            // Mitsuba's default material.
            BsdfDesc bsdf;
            bsdf.type = "diffuse";
            bsdf.params.kd = Color3::Constant(0.5);
            bsdf.loc = shape.loc;
            shape.bsdf = int(scene_.bsdfs.size());
            scene_.bsdfs.push_back(std::move(bsdf));
        }
        registerId(n, "shape", int(scene_.shapes.size()));
        scene_.shapes.push_back(std::move(shape));
    }

    // Top-level emitters when `shape` is null; otherwise the shape's area emitter.
    void parseEmitter(pugi::xml_node n, ShapeDesc* shape) {
        ctx_.checkAttributes(n, {"type", "id"});
        if (!shape && ctx_.attr(n, "type") == "area")
            ctx_.fail(n,
                      "an area emitter must be nested in a shape (allowed here: point, "
                      "directional, constant, envmap)");
        const std::string type =
            shape ? typeOf(n, {"area"}) : typeOf(n, {"point", "directional", "constant", "envmap"});
        std::vector<pugi::xml_node> nested;
        Params p = collect(n, {}, nested);
        const auto power = [&](const char* name) {
            const Color3 c = p.getColor(name).value_or(Color3::Ones());
            if (!(c >= 0).all())
                ctx_.fail(p.node(name),
                          fmt::format("{} ({}, {}, {}) is negative (allowed: >= 0 per channel)",
                                      name, c[0], c[1], c[2]));
            return c;
        };
        if (shape) {
            shape->areaRadiance = power("radiance");
            p.finish();
            registerId(n, "emitter", -1);
            return;
        }
        EmitterDesc e;
        e.loc = ctx_.loc(n);
        if (type == "point") {
            e.type = EmitterDesc::Type::Point;
            e.position = p.getPoint("position").value_or(Vec3d::Zero());
            e.value = power("intensity");
        } else if (type == "directional") {
            e.type = EmitterDesc::Type::Directional;
            const Vec3d d = p.getVector("direction").value_or(Vec3d(0, 0, 1));
            if (d.norm() == 0)
                ctx_.fail(p.node("direction"), "direction is zero (allowed: a nonzero vector)");
            e.direction = d.normalized();
            e.value = power("irradiance");
        } else if (type == "constant") {
            e.type = EmitterDesc::Type::Constant;
            e.value = power("radiance");
        } else {
            parseEnvMap(n, p, e);
        }
        if (e.type == EmitterDesc::Type::Constant || e.type == EmitterDesc::Type::EnvMap) {
            for (const EmitterDesc& other : scene_.emitters)
                if (other.type == EmitterDesc::Type::Constant ||
                    other.type == EmitterDesc::Type::EnvMap)
                    ctx_.fail(n, fmt::format("a second environment emitter (the first is at {}; "
                                             "allowed: one constant or envmap)",
                                             other.loc.str()));
        }
        p.finish();
        registerId(n, "emitter", int(scene_.emitters.size()));
        scene_.emitters.push_back(std::move(e));
    }

    // Mitsuba's envmap: filename (relative to the scene file), scale, toWorld (a rotation;
    // a translation is ignored, as Mitsuba does).
    void parseEnvMap(pugi::xml_node n, Params& p, EmitterDesc& e) {
        e.type = EmitterDesc::Type::EnvMap;
        const double scale = p.getFloat("scale").value_or(1);
        if (!(scale >= 0))
            ctx_.fail(p.node("scale"), fmt::format("scale {} is invalid (allowed: >= 0)", scale));
        e.value = Color3::Constant(scale);
        e.toWorld = p.getTransform("toWorld").linear();
        if ((e.toWorld.transpose() * e.toWorld - Eigen::Matrix3d::Identity()).norm() > 1e-6 ||
            !(e.toWorld.determinant() > 0))
            ctx_.fail(p.node("toWorld"),
                      "toWorld of an envmap must be a rotation (allowed: rotate, lookat; no "
                      "scale or mirror)");
        e.map = loadEnvironmentMap(fileParameter(n, p, "the lat-long EXR", "probe.exr"),
                                   ctx_.where(p.node("filename")));
    }

    // The required `filename` parameter, resolved against the scene file's folder.
    std::string fileParameter(pugi::xml_node n, Params& p, const char* what, const char* example) {
        const std::optional<std::string> filename = p.getString("filename");
        if (!filename)
            ctx_.fail(n, fmt::format("missing parameter 'filename' ({}, relative to the scene "
                                     "file, e.g. <string name=\"filename\" value=\"{}\"/>)",
                                     what, example));
        std::filesystem::path path(*filename);
        if (path.is_relative()) path = std::filesystem::path(baseDir_) / path;
        return path.string();
    }

    struct IdEntry {
        std::string kind;
        int index;
        SourceLocation loc;
    };

    Context ctx_;
    std::string baseDir_;
    pugi::xml_document doc_;
    pugi::xml_node root_;
    Scene scene_;
    std::map<std::string, IdEntry> ids_;
    std::size_t triangles_ = 0;
};

}  // namespace

Scene parseScene(const std::string& xmlText, const std::string& fileName, const Vars& defines,
                 const std::string& baseDir) {
    return Parser(xmlText, fileName, defines, baseDir).run();
}

Scene loadScene(const std::string& path, const Vars& defines) {
    std::error_code ec;
    if (std::filesystem::is_directory(path, ec))
        throw Error(fmt::format("cannot read scene file '{}': it is a directory", path));
    const std::uintmax_t bytes = std::filesystem::file_size(path, ec);
    if (!ec && bytes > kMaxSceneBytes)
        throw Error(fmt::format("scene file '{}' is {} MiB (allowed: up to {} MiB)", path,
                                bytes >> 20, kMaxSceneBytes >> 20));
    std::ifstream in(path, std::ios::binary);
    if (!in)
        throw Error(fmt::format("cannot open scene file '{}': {}", path, std::strerror(errno)));
    std::ostringstream text;
    text << in.rdbuf();
    if (in.bad()) throw Error(fmt::format("cannot read scene file '{}'", path));
    const std::filesystem::path dir = std::filesystem::path(path).parent_path();
    return parseScene(text.str(), path, defines, dir.empty() ? "." : dir.string());
}

}  // namespace phongfit