#include "scene_writer.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <pugixml.hpp>
#include <sstream>
#include <vector>

#include "atomic_file.h"
#include "error.h"
#include "scene_parser.h"

namespace phongfit {
namespace {

namespace fs = std::filesystem;
using Vars = std::map<std::string, std::string>;

// A replacement of text[pos, pos + length).
struct Edit {
    std::size_t pos, length;
    std::string text;
};

bool isSpace(char c) { return c == ' ' || c == '\t' || c == '\n' || c == '\r'; }

// The start tag of an element whose name begins at `offset` (pugixml's offset_debug), in a text
// pugixml has accepted as well-formed.
struct StartTag {
    std::map<std::string, std::pair<std::size_t, std::size_t>> values;  // attribute: [begin, end)
    std::size_t close = 0;                                              // where "/>" or ">" begins
    bool selfClosing = false;
};

StartTag scanStartTag(const std::string& text, std::size_t offset) {
    StartTag tag;
    std::size_t i = offset;
    while (!isSpace(text[i]) && text[i] != '/' && text[i] != '>') ++i;
    for (;;) {
        while (isSpace(text[i])) ++i;
        if (text[i] == '/' || text[i] == '>') {
            tag.close = i;
            tag.selfClosing = text[i] == '/';
            return tag;
        }
        const std::size_t nameBegin = i;
        while (!isSpace(text[i]) && text[i] != '=') ++i;
        const std::string name = text.substr(nameBegin, i - nameBegin);
        i = text.find_first_of("\"'", i);
        const std::size_t valueEnd = text.find(text[i], i + 1);
        tag.values[name] = {i + 1, valueEnd};
        i = valueEnd + 1;
    }
}

// The whitespace before the element's '<' on its line ("" if anything else precedes it).
std::string indentOf(const std::string& text, std::size_t offset) {
    const std::size_t lt = offset - 1;
    const std::size_t lineStart =
        text.rfind('\n', lt) == std::string::npos ? 0 : text.rfind('\n', lt) + 1;
    const std::string before = text.substr(lineStart, lt - lineStart);
    return std::all_of(before.begin(), before.end(), [](char c) { return c == ' ' || c == '\t'; })
               ? before
               : "";
}

std::string escapeXml(const std::string& s) {
    std::string out;
    for (const char c : s) {
        switch (c) {
            case '&':
                out += "&amp;";
                break;
            case '<':
                out += "&lt;";
                break;
            case '>':
                out += "&gt;";
                break;
            case '"':
                out += "&quot;";
                break;
            case '\'':
                out += "&apos;";
                break;
            default:
                out += c;
        }
    }
    return out;
}

// Shortest text that reads back as the same double.
std::string numberText(double v) { return fmt::format("{}", v); }

std::string colorText(const Color3& c) {
    if (c[0] == c[1] && c[1] == c[2]) return numberText(c[0]);
    return fmt::format("{}, {}, {}", numberText(c[0]), numberText(c[1]), numberText(c[2]));
}

void forEachElement(pugi::xml_node n, const std::function<void(pugi::xml_node)>& visit) {
    visit(n);
    for (const pugi::xml_node c : n.children())
        if (c.type() == pugi::node_element) forEachElement(c, visit);
}

fs::path directoryOf(const std::string& path) {
    const fs::path dir = fs::path(path).parent_path();
    return dir.empty() ? fs::path(".") : dir;
}

bool sameDirectory(const fs::path& a, const fs::path& b) {
    std::error_code ea, eb;
    const fs::path ca = fs::weakly_canonical(fs::absolute(a), ea);
    const fs::path cb = fs::weakly_canonical(fs::absolute(b), eb);
    if (ea || eb) return fs::absolute(a).lexically_normal() == fs::absolute(b).lexically_normal();
    return ca == cb;
}

std::string readText(const std::string& path) {
    std::error_code ec;
    if (fs::is_directory(path, ec))
        throw Error(fmt::format("cannot read scene file '{}': it is a directory", path));
    std::ifstream in(path, std::ios::binary);
    if (!in)
        throw Error(fmt::format("cannot open scene file '{}': {}", path, std::strerror(errno)));
    std::ostringstream text;
    text << in.rdbuf();
    return text.str();
}

using Expand = std::function<std::string(pugi::xml_node, const char*)>;

// Sets the three phong parameters of `bsdf`: existing elements get a new value= text, missing ones
// are added as the first children.
void phongEdits(const std::string& text, pugi::xml_node bsdf, const PhongMaterial& m,
                const Expand& expand, std::vector<Edit>& edits) {
    struct Value {
        const char* name;
        const char* tag;
        std::string text;
        bool present = false;
    };
    Value values[] = {{"diffuseReflectance", "rgb", colorText(m.kd)},
                      {"specularReflectance", "rgb", colorText(m.ks)},
                      {"exponent", "float", numberText(m.n)}};
    std::string childIndent;
    for (const pugi::xml_node c : bsdf.children()) {
        const std::size_t offset = std::size_t(c.offset_debug());
        if (childIndent.empty()) childIndent = indentOf(text, offset);
        const std::string name = expand(c, "name");
        for (Value& v : values) {
            if (name != v.name) continue;
            const auto [begin, end] = scanStartTag(text, offset).values.at("value");
            edits.push_back({begin, end - begin, v.text});
            v.present = true;
        }
    }
    std::string added;
    const std::string indent = indentOf(text, std::size_t(bsdf.offset_debug()));
    if (childIndent.empty()) childIndent = indent + "    ";
    for (const Value& v : values)
        if (!v.present)
            added += fmt::format("\n{}<{} name=\"{}\" value=\"{}\"/>", childIndent, v.tag, v.name,
                                 v.text);
    if (added.empty()) return;
    const StartTag tag = scanStartTag(text, std::size_t(bsdf.offset_debug()));
    if (tag.selfClosing)
        edits.push_back({tag.close, 2, fmt::format(">{}\n{}</{}>", added, indent, bsdf.name())});
    else
        edits.push_back({tag.close + 1, 0, added});
}

}  // namespace

void writeSceneWithMaterials(const std::string& inPath, const Vars& defines,
                             const std::map<std::string, PhongMaterial>& materials,
                             const std::string& outPath) {
    const std::string text = readText(inPath);
    const fs::path inDir = directoryOf(inPath), outDir = directoryOf(outPath);
    const Scene scene = parseScene(text, inPath, defines, inDir.string());
    for (const auto& [id, material] : materials) {
        const int index = id.empty() ? -1 : scene.findBsdf(id);
        if (index < 0) {
            std::vector<std::string> phongIds;
            for (const BsdfDesc& b : scene.bsdfs)
                if (b.type == "phong" && !b.id.empty()) phongIds.push_back("'" + b.id + "'");
            throw Error(fmt::format(
                "{}: no bsdf with id '{}' (allowed: the phong bsdf ids in the "
                "file: {})",
                inPath, id,
                phongIds.empty() ? "none" : fmt::format("{}", fmt::join(phongIds, ", "))));
        }
        const BsdfDesc& bsdf = scene.bsdfs[std::size_t(index)];
        if (bsdf.type != "phong")
            throw Error(
                fmt::format("{}: bsdf '{}' is {}, not phong (allowed: phong bsdfs, the only "
                            "ones fitted values can be written to)",
                            bsdf.loc.str(), id, bsdf.type));
        validatePhong(material, fmt::format("fitted material '{}'", id));
    }

    const Vars vars = sceneVariables(text, inPath, defines);
    const Expand expand = [&](pugi::xml_node n, const char* attribute) {
        return expandVariables(n.attribute(attribute).value(), vars, inPath);
    };
    pugi::xml_document doc;
    doc.load_buffer(text.data(), text.size(), pugi::parse_default, pugi::encoding_utf8);
    const bool moved = !sameDirectory(inDir, outDir);
    std::vector<Edit> edits;
    forEachElement(doc.document_element(), [&](pugi::xml_node n) {
        const std::string_view tag = n.name();
        if (tag == "bsdf" && n.attribute("id")) {
            const auto it = materials.find(expand(n, "id"));
            if (it != materials.end()) phongEdits(text, n, it->second, expand, edits);
        } else if (moved && ((tag == "shape" && expand(n, "type") == "obj") ||
                             (tag == "emitter" && expand(n, "type") == "envmap"))) {
            for (const pugi::xml_node c : n.children("string")) {
                const fs::path file(expand(c, "value"));
                if (expand(c, "name") != "filename" || file.is_absolute()) continue;
                const fs::path target = fs::absolute(inDir / file).lexically_normal();
                const fs::path relative =
                    target.lexically_relative(fs::absolute(outDir).lexically_normal());
                const auto [begin, end] =
                    scanStartTag(text, std::size_t(c.offset_debug())).values.at("value");
                edits.push_back({begin, end - begin,
                                 escapeXml((relative.empty() ? target : relative).string())});
            }
        }
    });
    std::sort(edits.begin(), edits.end(),
              [](const Edit& a, const Edit& b) { return a.pos > b.pos; });
    std::string out = text;
    for (const Edit& e : edits) out.replace(e.pos, e.length, e.text);

    writeAtomically(outPath, [&](const fs::path& temporary) {
        // What `render` will read must parse (it does, unless this writer has a bug). Checked
        // here, where the output directory is known to exist, so relative obj and envmap paths
        // resolve.
        parseScene(out, outPath, defines, outDir.string());
        std::ofstream file(temporary, std::ios::binary);
        file << out;
        file.close();
        if (!file) throw Error(fmt::format("cannot write '{}'", temporary.string()));
    });
}

}  // namespace phongfit
