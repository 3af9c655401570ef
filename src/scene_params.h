// The parameters of one scene object (<float>, <rgb>, <transform>, ...), typed: getters name
// what the object accepts, finish() rejects the rest. Internal to the scene parser.
#pragma once

#include <map>
#include <optional>
#include <string>
#include <variant>
#include <vector>

#include "scene_xml.h"

namespace phongfit::scene_xml {

constexpr Names kParamTags = {"float",    "integer", "boolean", "string",   "rgb",
                              "spectrum", "point",   "vector",  "transform"};

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

}  // namespace phongfit::scene_xml
