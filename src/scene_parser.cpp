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

#include "error.h"
#include "obj_mesh.h"

namespace phongfit {
namespace {

using Vars = std::map<std::string, std::string>;
using Names = std::initializer_list<const char*>;

// Limits with clear errors instead of memory or time exhaustion (the render command's flags allow
// the same ranges). A film of kMaxFilmPixels takes about 3 GB to render.
constexpr int kMaxFilmSize = 16384;
constexpr long kMaxFilmPixels = 1L << 25;
constexpr int kMaxSampleCount = 1 << 20;
constexpr int kMaxDepth = 1000;
constexpr std::size_t kMaxSceneTriangles = kMaxMeshTriangles;
// Embree works in float: world-space geometry must stay well inside its range.
constexpr double kMaxCoordinate = 1e30;
// Defaults may use earlier defaults, so expansion can grow a value exponentially ("billion
// laughs"); no honest value comes near this.
constexpr std::size_t kMaxExpandedLength = 1 << 20;
// Meshes live in OBJ files; the XML parser's tree takes several times the text.
constexpr std::uintmax_t kMaxSceneBytes = std::uintmax_t(64) << 20;
constexpr Names kParamTags = {"float",    "integer", "boolean", "string",   "rgb",
                              "spectrum", "point",   "vector",  "transform"};

bool contains(Names names, std::string_view s) {
    return std::any_of(names.begin(), names.end(), [&](const char* n) { return s == n; });
}

bool isIdentifier(std::string_view s) {
    return !s.empty() && std::all_of(s.begin(), s.end(), [](char c) {
        return std::isalnum(static_cast<unsigned char>(c)) || c == '_';
    });
}

bool isSpace(char c) { return c == ' ' || c == '\t' || c == '\n' || c == '\r'; }

std::string_view trim(std::string_view s) {
    while (!s.empty() && isSpace(s.front())) s.remove_prefix(1);
    while (!s.empty() && isSpace(s.back())) s.remove_suffix(1);
    return s;
}

// Strict: the whole string is one finite number (no "1.2.3", "abc", "nan", "inf").
std::optional<double> toNumber(std::string_view s) {
    s = trim(s);
    if (s.size() > 1 && s[0] == '+' && s[1] != '-') s.remove_prefix(1);
    double v = 0;
    const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
    if (s.empty() || ec != std::errc() || end != s.data() + s.size() || !std::isfinite(v))
        return std::nullopt;
    return v;
}

std::optional<int> toInteger(std::string_view s) {
    s = trim(s);
    if (s.size() > 1 && s[0] == '+' && s[1] != '-') s.remove_prefix(1);
    int v = 0;
    const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
    if (s.empty() || ec != std::errc() || end != s.data() + s.size()) return std::nullopt;
    return v;
}

// Byte offset -> 1-based line number.
class LineIndex {
public:
    explicit LineIndex(const std::string& text) {
        starts_.push_back(0);
        for (std::size_t i = 0; i < text.size(); ++i)
            if (text[i] == '\n') starts_.push_back(i + 1);
    }
    int line(std::ptrdiff_t offset) const {
        const std::size_t at = std::size_t(std::max<std::ptrdiff_t>(offset, 0));
        return int(std::upper_bound(starts_.begin(), starts_.end(), at) - starts_.begin());
    }

private:
    std::vector<std::size_t> starts_;
};

// An element as messages name it: its tag and identifying attributes, as written.
std::string describe(pugi::xml_node n) {
    if (n.type() != pugi::node_element) return "text";
    std::string s = n.name();
    for (const char* a : {"type", "id", "name"})
        if (const pugi::xml_attribute at = n.attribute(a))
            s += fmt::format(" {}=\"{}\"", a, at.value());
    return s;
}

// File name, line numbers and variables: everything an element needs to be read and blamed.
class Context {
public:
    Context(std::string file, const std::string& text) : file_(std::move(file)), lines_(text) {}

    const std::string& file() const { return file_; }
    int line(std::ptrdiff_t offset) const { return lines_.line(offset); }
    SourceLocation loc(pugi::xml_node n) const { return {file_, lines_.line(n.offset_debug())}; }
    std::string where(pugi::xml_node n) const { return loc(n).str() + ": " + describe(n); }

    [[noreturn]] void fail(pugi::xml_node n, const std::string& what) const {
        throw Error(where(n) + ": " + what);
    }

    void checkAttributes(pugi::xml_node n, Names allowed) const {
        for (const pugi::xml_attribute a : n.attributes())
            if (!contains(allowed, a.name()))
                fail(n, fmt::format("unknown attribute '{}' (allowed: {})", a.name(),
                                    fmt::join(allowed, ", ")));
    }

    void checkNoChildren(pugi::xml_node n) const {
        if (const pugi::xml_node c = n.first_child())
            fail(c, fmt::format("unexpected content inside <{}> (allowed: none)", n.name()));
    }

    [[noreturn]] void failText(pugi::xml_node n) const {
        std::string text(trim(n.value()));
        if (text.size() > 30) text = text.substr(0, 30) + "...";
        fail(n, fmt::format("unexpected text '{}' (values go in attributes, e.g. value=\"...\")",
                            text));
    }

    std::optional<std::string> attr(pugi::xml_node n, const char* name) const {
        const pugi::xml_attribute a = n.attribute(name);
        if (!a) return std::nullopt;
        return expandVariables(a.value(), vars, where(n));
    }

    std::string required(pugi::xml_node n, const char* name, std::string_view hint) const {
        if (std::optional<std::string> v = attr(n, name)) return *v;
        fail(n, fmt::format("missing attribute '{}' ({})", name, hint));
    }

    double number(pugi::xml_node n, const std::string& text) const {
        if (const std::optional<double> v = toNumber(text)) return *v;
        fail(n, fmt::format("'{}' is not a valid number (allowed: finite decimal numbers such "
                            "as 0.5, -2 or 1e-3)",
                            text));
    }

    // Numbers separated by commas and/or whitespace.
    std::vector<double> numberList(pugi::xml_node n, const std::string& text) const {
        std::vector<double> numbers;
        std::size_t start = 0;
        for (;;) {
            const std::size_t comma = std::min(text.find(',', start), text.size());
            const std::string_view piece(text.data() + start, comma - start);
            if (trim(piece).empty())
                fail(n, fmt::format("'{}' has an empty entry (allowed: numbers separated by "
                                    "commas and/or spaces)",
                                    text));
            for (std::size_t i = 0; i < piece.size();) {
                if (isSpace(piece[i])) {
                    ++i;
                    continue;
                }
                std::size_t j = i;
                while (j < piece.size() && !isSpace(piece[j])) ++j;
                numbers.push_back(number(n, std::string(piece.substr(i, j - i))));
                i = j;
            }
            if (comma == text.size()) break;
            start = comma + 1;
        }
        return numbers;
    }

    Vec3d vec3(pugi::xml_node n, const char* attribute) const {
        const std::string text = required(n, attribute, "three numbers \"x, y, z\"");
        const std::vector<double> v = numberList(n, text);
        if (v.size() != 3)
            fail(n, fmt::format("{}=\"{}\" has {} numbers (allowed: three, \"x, y, z\")", attribute,
                                text, v.size()));
        return Vec3d(v[0], v[1], v[2]);
    }

    double optionalNumber(pugi::xml_node n, const char* attribute, double fallback) const {
        const std::optional<std::string> text = attr(n, attribute);
        return text ? number(n, *text) : fallback;
    }

    Vars vars;

private:
    std::string file_;
    LineIndex lines_;
};

// Later operations apply after earlier ones: M = op_k * ... * op_1.
Eigen::Affine3d parseTransform(const Context& ctx, pugi::xml_node n) {
    Eigen::Affine3d m = Eigen::Affine3d::Identity();
    for (const pugi::xml_node c : n.children()) {
        if (c.type() != pugi::node_element) ctx.failText(c);
        ctx.checkNoChildren(c);
        const std::string op = c.name();
        Eigen::Affine3d t = Eigen::Affine3d::Identity();
        if (op == "translate") {
            ctx.checkAttributes(c, {"x", "y", "z"});
            t = Eigen::Translation3d(ctx.optionalNumber(c, "x", 0), ctx.optionalNumber(c, "y", 0),
                                     ctx.optionalNumber(c, "z", 0));
        } else if (op == "scale") {
            ctx.checkAttributes(c, {"value", "x", "y", "z"});
            Vec3d s;
            if (const std::optional<std::string> value = ctx.attr(c, "value")) {
                if (c.attribute("x") || c.attribute("y") || c.attribute("z"))
                    ctx.fail(c, "both value= and x, y, z given (allowed: one of the two)");
                s.setConstant(ctx.number(c, *value));
            } else {
                s = Vec3d(ctx.optionalNumber(c, "x", 1), ctx.optionalNumber(c, "y", 1),
                          ctx.optionalNumber(c, "z", 1));
            }
            if ((s.array() == 0).any())
                ctx.fail(c, "a scale factor of 0 collapses space (allowed: nonzero factors)");
            t.linear() = s.asDiagonal();
        } else if (op == "rotate") {
            ctx.checkAttributes(c, {"x", "y", "z", "angle"});
            const Vec3d axis(ctx.optionalNumber(c, "x", 0), ctx.optionalNumber(c, "y", 0),
                             ctx.optionalNumber(c, "z", 0));
            if (axis.norm() == 0)
                ctx.fail(c, "the rotation axis x, y, z is zero (allowed: a nonzero axis)");
            const double angle = ctx.number(c, ctx.required(c, "angle", "degrees"));
            t = Eigen::AngleAxisd(angle * kPi / 180, axis.normalized());
        } else if (op == "matrix") {
            ctx.checkAttributes(c, {"value"});
            const std::string text = ctx.required(c, "value", "16 numbers, row-major");
            const std::vector<double> v = ctx.numberList(c, text);
            if (v.size() != 16)
                ctx.fail(c, fmt::format("value has {} numbers (allowed: 16, row-major)", v.size()));
            Eigen::Matrix4d mat;
            for (int i = 0; i < 4; ++i)
                for (int j = 0; j < 4; ++j) mat(i, j) = v[std::size_t(4 * i + j)];
            if (mat.row(3) != Eigen::RowVector4d(0, 0, 0, 1))
                ctx.fail(c, "the last row is not 0 0 0 1 (allowed: affine matrices)");
            t.matrix() = mat;
        } else if (op == "lookat") {
            ctx.checkAttributes(c, {"origin", "target", "up"});
            const Vec3d origin = ctx.vec3(c, "origin");
            const Vec3d target = ctx.vec3(c, "target");
            if (target == origin)
                ctx.fail(c, "origin and target coincide (allowed: distinct points)");
            const Vec3d dir = (target - origin).normalized();
            const Vec3d up = c.attribute("up") ? ctx.vec3(c, "up") : Frame<double>(dir).s;
            // As Mitsuba: camera +x = up x dir is the viewer's left.
            const Vec3d left = up.cross(dir);
            if (!(left.norm() > 1e-9 * up.norm()))
                ctx.fail(c,
                         "up is zero or parallel to target - origin (allowed: any other "
                         "direction)");
            t.linear().col(0) = left.normalized();
            t.linear().col(1) = dir.cross(t.linear().col(0));
            t.linear().col(2) = dir;
            t.translation() = origin;
        } else {
            ctx.fail(c,
                     "unknown transform operation (allowed: translate, scale, rotate, matrix, "
                     "lookat)");
        }
        m = t * m;
    }
    const Eigen::Matrix3d l = m.linear();
    const double scale = l.col(0).norm() * l.col(1).norm() * l.col(2).norm();
    if (!m.matrix().allFinite() || !(std::abs(l.determinant()) > 1e-12 * scale))
        ctx.fail(n,
                 "the transform is degenerate: it collapses space onto a plane, line or point "
                 "(allowed: invertible transforms)");
    return m;
}

using ParamValue = std::variant<double, int, bool, std::string, Color3, Vec3d, Eigen::Affine3d>;

struct Param {
    pugi::xml_node node;
    std::string tag;
    ParamValue value;
};

// The parameters of one object. Getters name what the object accepts; finish() rejects the rest.
class Params {
public:
    Params(const Context& ctx, pugi::xml_node owner) : ctx_(ctx), owner_(owner) {}

    void add(pugi::xml_node n) {
        const std::string tag = n.name();
        if (tag == "transform") {
            ctx_.checkAttributes(n, {"name"});
        } else {
            if (tag == "point" || tag == "vector")
                ctx_.checkAttributes(n, {"name", "x", "y", "z"});
            else
                ctx_.checkAttributes(n, {"name", "value"});
            ctx_.checkNoChildren(n);
        }
        const std::string name = ctx_.required(n, "name", "the parameter's name");
        if (const auto it = params_.find(name); it != params_.end())
            ctx_.fail(n, fmt::format("parameter '{}' is given twice (first at line {})", name,
                                     ctx_.loc(it->second.node).line));
        ParamValue value;
        if (tag == "float") {
            value = ctx_.number(n, ctx_.required(n, "value", "a number"));
        } else if (tag == "integer") {
            const std::string text = ctx_.required(n, "value", "an integer");
            const std::optional<int> v = toInteger(text);
            if (!v)
                ctx_.fail(n, fmt::format("'{}' is not a valid integer (allowed: whole numbers "
                                         "such as 64 or -1)",
                                         text));
            value = *v;
        } else if (tag == "boolean") {
            const std::string text = ctx_.required(n, "value", "true or false");
            if (text != "true" && text != "false")
                ctx_.fail(n, fmt::format("'{}' is not a boolean (allowed: true, false)", text));
            value = text == "true";
        } else if (tag == "string") {
            value = ctx_.required(n, "value", "a string");
        } else if (tag == "rgb" || tag == "spectrum") {
            const std::string text = ctx_.required(n, "value", "one number or three: r, g, b");
            const std::vector<double> v = ctx_.numberList(n, text);
            if (v.size() == 1)
                value = Color3(Color3::Constant(v[0]));
            else if (v.size() == 3)
                value = Color3(v[0], v[1], v[2]);
            else
                ctx_.fail(n, fmt::format("'{}' has {} numbers (allowed: one, or three for r, g, b)",
                                         text, v.size()));
        } else if (tag == "point" || tag == "vector") {
            value = Vec3d(ctx_.optionalNumber(n, "x", 0), ctx_.optionalNumber(n, "y", 0),
                          ctx_.optionalNumber(n, "z", 0));
        } else {
            value = parseTransform(ctx_, n);
        }
        params_.emplace(name, Param{n, tag, std::move(value)});
    }

    std::optional<double> getFloat(const std::string& name) { return get<double>(name, {"float"}); }
    std::optional<int> getInt(const std::string& name) { return get<int>(name, {"integer"}); }
    std::optional<bool> getBool(const std::string& name) { return get<bool>(name, {"boolean"}); }
    std::optional<std::string> getString(const std::string& name) {
        return get<std::string>(name, {"string"});
    }
    std::optional<Color3> getColor(const std::string& name) {
        return get<Color3>(name, {"rgb", "spectrum"});
    }
    std::optional<Vec3d> getPoint(const std::string& name) { return get<Vec3d>(name, {"point"}); }
    std::optional<Vec3d> getVector(const std::string& name) { return get<Vec3d>(name, {"vector"}); }
    Eigen::Affine3d getTransform(const std::string& name) {
        return get<Eigen::Affine3d>(name, {"transform"}).value_or(Eigen::Affine3d::Identity());
    }

    // The parameter's element, or the object's when it is absent: where to blame a bad value.
    pugi::xml_node node(const std::string& name) const {
        const auto it = params_.find(name);
        return it == params_.end() ? owner_ : it->second.node;
    }

    void finish() const {
        for (const auto& [name, param] : params_)
            if (std::find(asked_.begin(), asked_.end(), name) == asked_.end())
                ctx_.fail(
                    param.node,
                    fmt::format(
                        "unknown parameter '{}' for {} (allowed: {})", name, describe(owner_),
                        asked_.empty() ? "none" : fmt::format("{}", fmt::join(asked_, ", "))));
    }

private:
    template <typename T>
    std::optional<T> get(const std::string& name, Names tags) {
        asked_.push_back(name);
        const auto it = params_.find(name);
        if (it == params_.end()) return std::nullopt;
        if (!contains(tags, it->second.tag))
            ctx_.fail(it->second.node, fmt::format("wrong type <{}> for '{}' (allowed: <{}>)",
                                                   it->second.tag, name, fmt::join(tags, ">, <")));
        return std::get<T>(it->second.value);
    }

    const Context& ctx_;
    pugi::xml_node owner_;
    std::map<std::string, Param> params_;
    std::vector<std::string> asked_;
};

pugi::xml_node loadRoot(pugi::xml_document& doc, const std::string& text, const Context& ctx) {
    const pugi::xml_parse_result result =
        doc.load_buffer(text.data(), text.size(), pugi::parse_default, pugi::encoding_utf8);
    if (!result)
        throw Error(fmt::format("{}:{}: malformed XML: {}", ctx.file(), ctx.line(result.offset),
                                result.description()));
    const pugi::xml_node root = doc.document_element();
    if (std::string_view(root.name()) != "scene")
        ctx.fail(root, "the root element must be <scene version=\"0.6.0\">");
    return root;
}

// `default`s in document order (each may use earlier ones); a define wins over a default.
Vars collectVariables(const Context& ctx, pugi::xml_node root, const Vars& defines) {
    for (const auto& [name, value] : defines)
        if (!isIdentifier(name))
            throw Error(
                fmt::format("-D {}={}: '{}' is not a valid variable name (allowed: "
                            "letters, digits and _)",
                            name, value, name));
    Vars vars = defines;
    std::map<std::string, pugi::xml_node> defaults;
    for (const pugi::xml_node d : root.children("default")) {
        ctx.checkAttributes(d, {"name", "value"});
        ctx.checkNoChildren(d);
        const pugi::xml_attribute nameAttr = d.attribute("name");
        const pugi::xml_attribute valueAttr = d.attribute("value");
        if (!nameAttr || !valueAttr)
            ctx.fail(d, fmt::format("missing attribute '{}' (a default needs name= and value=)",
                                    nameAttr ? "value" : "name"));
        const std::string name = nameAttr.value();
        if (!isIdentifier(name))
            ctx.fail(d, fmt::format("'{}' is not a valid variable name (allowed: letters, digits "
                                    "and _)",
                                    name));
        if (const auto it = defaults.find(name); it != defaults.end())
            ctx.fail(d, fmt::format("a second default for '{}' (first at line {})", name,
                                    ctx.loc(it->second).line));
        defaults.emplace(name, d);
        const std::string value = expandVariables(valueAttr.value(), vars, ctx.where(d));
        if (!defines.count(name)) vars[name] = value;
    }
    return vars;
}

TriangleMesh unitRectangle() {
    TriangleMesh m;
    m.positions = {Vec3f(-1, -1, 0), Vec3f(1, -1, 0), Vec3f(1, 1, 0), Vec3f(-1, 1, 0)};
    m.indices = {0, 1, 2, 0, 2, 3};
    return m;
}

TriangleMesh unitCube() {
    TriangleMesh m;
    for (int axis = 0; axis < 3; ++axis) {
        for (const float sign : {-1.0f, 1.0f}) {
            const Vec3f n = sign * Vec3f::Unit(axis);
            // cross(u, v) = n, so the face winds counter-clockwise seen from outside.
            Vec3f u = Vec3f::Unit((axis + 1) % 3), v = Vec3f::Unit((axis + 2) % 3);
            if (sign < 0) std::swap(u, v);
            const auto base = std::uint32_t(m.positions.size());
            for (const Vec3f& p :
                 {Vec3f(n - u - v), Vec3f(n + u - v), Vec3f(n + u + v), Vec3f(n - u + v)})
                m.positions.push_back(p);
            for (const std::uint32_t i : {0u, 1u, 2u, 0u, 2u, 3u}) m.indices.push_back(base + i);
        }
    }
    return m;
}

// Positions by toWorld, normals by its inverse transpose; a mirror would turn the winding
// inside out, so it is undone.
TriangleMesh transformed(TriangleMesh mesh, const Eigen::Affine3d& toWorld) {
    const Eigen::Matrix3d normalMatrix = toWorld.linear().inverse().transpose();
    for (Vec3f& p : mesh.positions) p = (toWorld * p.cast<double>()).cast<float>();
    for (Vec3f& n : mesh.normals) n = (normalMatrix * n.cast<double>()).normalized().cast<float>();
    if (toWorld.linear().determinant() < 0)
        for (std::size_t t = 0; t < mesh.indices.size(); t += 3)
            std::swap(mesh.indices[t + 1], mesh.indices[t + 2]);
    return mesh;
}

// The largest absolute world-space coordinate the shape reaches (infinity if any is not finite).
double worldExtent(const ShapeDesc& shape) {
    constexpr double kInfinity = std::numeric_limits<double>::infinity();
    const auto extent = [](const auto& v) {
        return v.allFinite() ? double(v.cwiseAbs().maxCoeff()) : kInfinity;
    };
    double e = 0;
    switch (shape.type) {
        case ShapeDesc::Type::Sphere:
            e = extent(shape.center) + (std::isfinite(shape.radius) ? shape.radius : kInfinity);
            break;
        case ShapeDesc::Type::Disk:
            e = extent(shape.toWorld.translation()) + extent(shape.toWorld.linear());
            break;
        default:
            for (const Vec3f& v : shape.mesh.positions) e = std::max(e, extent(v));
            for (const Vec3f& v : shape.mesh.normals)
                if (!v.allFinite()) e = kInfinity;
            break;
    }
    return e;
}

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
        typeOf(n, {"independent"});
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
        const std::string type = typeOf(n, {"box", "gaussian"});
        std::vector<pugi::xml_node> nested;
        Params p = collect(n, {}, nested);
        SensorDesc& sensor = scene_.sensor;
        if (type == "box") {
            sensor.filter = SensorDesc::Filter::Box;
        } else {
            sensor.filter = SensorDesc::Filter::Gaussian;
            sensor.gaussianStddev = p.getFloat("stddev").value_or(0.5);
            if (!(sensor.gaussianStddev > 0))
                ctx_.fail(p.node("stddev"),
                          fmt::format("stddev {} is invalid (allowed: > 0 pixels)",
                                      sensor.gaussianStddev));
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
            const std::optional<std::string> filename = p.getString("filename");
            if (!filename)
                ctx_.fail(n,
                          "missing parameter 'filename' (the OBJ file, relative to the scene "
                          "file, e.g. <string name=\"filename\" value=\"mesh.obj\"/>)");
            const bool faceNormals = p.getBool("faceNormals").value_or(false);
            std::filesystem::path path(*filename);
            if (path.is_relative()) path = std::filesystem::path(baseDir_) / path;
            TriangleMesh mesh = loadObjMesh(path.string(), ctx_.where(p.node("filename")));
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
                      "directional, constant)");
        const std::string type =
            shape ? typeOf(n, {"area"}) : typeOf(n, {"point", "directional", "constant"});
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
        } else {
            e.type = EmitterDesc::Type::Constant;
            e.value = power("radiance");
        }
        p.finish();
        registerId(n, "emitter", int(scene_.emitters.size()));
        scene_.emitters.push_back(std::move(e));
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

std::string expandVariables(const std::string& value, const Vars& variables,
                            const std::string& where) {
    std::string out;
    for (std::size_t i = 0; i < value.size();) {
        if (value[i] != '$') {
            out += value[i++];
            continue;
        }
        std::size_t j = i + 1;
        while (j < value.size() &&
               (std::isalnum(static_cast<unsigned char>(value[j])) || value[j] == '_'))
            ++j;
        const std::string name = value.substr(i + 1, j - i - 1);
        if (name.empty())
            throw Error(
                fmt::format("{}: '$' in '{}' is not followed by a variable name (allowed: "
                            "$name with letters, digits and _)",
                            where, value));
        const auto it = variables.find(name);
        if (it == variables.end())
            throw Error(
                fmt::format("{}: undefined variable '${}' (define it with <default "
                            "name=\"{}\" value=\"...\"/> or -D {}=...)",
                            where, name, name, name));
        if (out.size() + it->second.size() > kMaxExpandedLength)
            throw Error(
                fmt::format("{}: the variables in '{}' expand to over 1 MiB of text "
                            "(allowed: up to {} characters)",
                            where, value.substr(0, 40), kMaxExpandedLength));
        out += it->second;
        i = j;
    }
    return out;
}

Vars sceneVariables(const std::string& xmlText, const std::string& fileName, const Vars& defines) {
    const Context ctx(fileName, xmlText);
    pugi::xml_document doc;
    return collectVariables(ctx, loadRoot(doc, xmlText, ctx), defines);
}

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
