#include "scene_baker.h"

#include <fmt/format.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <pugixml.hpp>
#include <set>
#include <sstream>
#include <vector>

#include "atomic_file.h"
#include "error.h"
#include "scene_xml.h"

namespace phongfit {
namespace {

namespace fs = std::filesystem;
using scene_xml::isIdentifier;
using scene_xml::isSpace;

// A replacement of text[begin, end).
struct Splice {
    std::size_t begin, end;
    std::string text;
};

// Where the value of attribute `name` sits in the start tag whose element name begins at `offset`
// (pugixml's offset_debug), in a text pugixml accepted as well-formed, with that attribute:
// [begin, end) between the quotes.
std::pair<std::size_t, std::size_t> attributeValue(const std::string& text, std::size_t offset,
                                                   const std::string& name) {
    std::size_t i = offset;
    while (!isSpace(text[i]) && text[i] != '/' && text[i] != '>') ++i;
    for (;;) {
        while (isSpace(text[i])) ++i;
        const std::size_t nameBegin = i;
        while (!isSpace(text[i]) && text[i] != '=') ++i;
        const std::string attribute = text.substr(nameBegin, i - nameBegin);
        i = text.find_first_of("\"'", i);
        const std::size_t end = text.find(text[i], i + 1);
        if (attribute == name) return {i + 1, end};
        i = end + 1;
    }
}

std::string escapeXml(const std::string& s) {
    std::string out;
    for (const char c : s) {
        if (c == '&')
            out += "&amp;";
        else if (c == '<')
            out += "&lt;";
        else if (c == '"')
            out += "&quot;";
        else if (c == '\'')
            out += "&apos;";
        else
            out += c;
    }
    return out;
}

// A relative file name as seen from `toDir` instead of `fromDir`; empty where it needs no
// rewriting (absolute, or with a variable in it).
std::string movedPath(std::string_view file, const fs::path& fromDir, const fs::path& toDir) {
    const fs::path path(file);
    if (file.empty() || path.is_absolute() || file.find('$') != std::string_view::npos) return {};
    return fs::relative(fromDir / path, toDir).generic_string();
}

// Relative file names (meshes, environment maps) resolve against the scene's directory
// (scene_parser.h), so the baked scene, in another folder, needs them rewritten: `filename`
// strings written out are spliced here; those given by a default ("$name") are collected in
// `fromDefaults`, whose values are rewritten where the defaults are.
void filePathSplices(const std::string& text, pugi::xml_node node, const fs::path& fromDir,
                     const fs::path& toDir, std::vector<Splice>& splices,
                     std::set<std::string>& fromDefaults) {
    for (const pugi::xml_node child : node.children()) {
        const std::string_view value = child.attribute("value").value();
        if (std::string_view(child.name()) == "string" &&
            std::string_view(child.attribute("name").value()) == "filename" &&
            child.attribute("value")) {
            if (value.size() > 1 && value[0] == '$' && isIdentifier(value.substr(1))) {
                fromDefaults.insert(std::string(value.substr(1)));
            } else if (const std::string moved = movedPath(value, fromDir, toDir); !moved.empty()) {
                const auto [begin, end] = attributeValue(text, child.offset_debug(), "value");
                splices.push_back({begin, end, escapeXml(moved)});
            }
        }
        filePathSplices(text, child, fromDir, toDir, splices, fromDefaults);
    }
}

}  // namespace

std::set<std::string> bakeSceneDefaults(const std::string& inPath,
                                        const std::map<std::string, std::string>& values,
                                        const std::string& comment, const std::string& outPath) {
    std::ifstream in(inPath, std::ios::binary);
    if (!in) throw Error(fmt::format("cannot read scene '{}'", inPath));
    std::stringstream buffer;
    buffer << in.rdbuf();
    const std::string text = buffer.str();
    pugi::xml_document doc;
    const pugi::xml_parse_result parsed =
        doc.load_buffer(text.data(), text.size(), pugi::parse_default, pugi::encoding_utf8);
    if (!parsed)
        throw Error(fmt::format("{}: not well-formed XML: {}", inPath, parsed.description()));
    const pugi::xml_node root = doc.child("scene");
    if (!root) throw Error(fmt::format("{}: no <scene> root element", inPath));

    // Edits in place keep everything else byte for byte: layout, comments, quoting.
    std::vector<Splice> splices;
    std::set<std::string> replaced, fileDefaults;
    const fs::path fromDir = fs::absolute(inPath).parent_path(),
                   toDir = fs::absolute(outPath).parent_path();
    filePathSplices(text, root, fromDir, toDir, splices, fileDefaults);
    for (const pugi::xml_node d : root.children("default")) {
        const std::string name = d.attribute("name").value();
        const auto it = values.find(name);
        if (!d.attribute("value")) continue;
        const std::string value = it == values.end() ? d.attribute("value").value() : it->second;
        const std::string moved =
            fileDefaults.count(name) ? movedPath(value, fromDir, toDir) : std::string();
        if (it == values.end() && moved.empty()) continue;
        const auto [begin, end] = attributeValue(text, d.offset_debug(), "value");
        splices.push_back({begin, end, escapeXml(moved.empty() ? value : moved)});
        if (it != values.end()) replaced.insert(name);
    }
    if (!comment.empty()) {
        const std::size_t lt = std::size_t(root.offset_debug()) - 1;
        splices.push_back({lt, lt, "<!-- " + comment + " -->\n"});
    }
    std::sort(splices.begin(), splices.end(),
              [](const Splice& a, const Splice& b) { return a.begin > b.begin; });
    std::string out = text;
    for (const Splice& s : splices) out.replace(s.begin, s.end - s.begin, s.text);

    writeAtomically(outPath, [&](const fs::path& tmp) {
        std::ofstream file(tmp, std::ios::binary);
        file << out;
        if (!file) throw Error(fmt::format("cannot write '{}'", tmp.string()));
    });
    return replaced;
}

}  // namespace phongfit
