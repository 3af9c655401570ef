#include "scene_variables.h"

namespace phongfit {
namespace scene_xml {

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

}  // namespace scene_xml

std::string expandVariables(const std::string& value,
                            const std::map<std::string, std::string>& variables,
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
        if (out.size() + it->second.size() > scene_xml::kMaxExpandedLength)
            throw Error(
                fmt::format("{}: the variables in '{}' expand to over 1 MiB of text "
                            "(allowed: up to {} characters)",
                            where, value.substr(0, 40), scene_xml::kMaxExpandedLength));
        out += it->second;
        i = j;
    }
    return out;
}

std::map<std::string, std::string> sceneVariables(
    const std::string& xmlText, const std::string& fileName,
    const std::map<std::string, std::string>& defines) {
    const scene_xml::Context ctx(fileName, xmlText);
    pugi::xml_document doc;
    return scene_xml::collectVariables(ctx, scene_xml::loadRoot(doc, xmlText, ctx), defines);
}

}  // namespace phongfit
