// Reading the elements of a scene file with blame: file and line of every element, typed
// attribute values, variables expanded, and one-line errors "FILE:LINE: element: what is wrong
// (allowed: ...)". Internal to the scene parser (scene_parser.h).
#pragma once

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <initializer_list>
#include <map>
#include <optional>
#include <pugixml.hpp>
#include <string>
#include <string_view>
#include <vector>

#include "error.h"
#include "math.h"
#include "scene.h"
#include "scene_parser.h"

namespace phongfit::scene_xml {

using Vars = std::map<std::string, std::string>;
using Names = std::initializer_list<const char*>;

inline bool contains(Names names, std::string_view s) {
    return std::any_of(names.begin(), names.end(), [&](const char* n) { return s == n; });
}

inline bool isIdentifier(std::string_view s) {
    return !s.empty() && std::all_of(s.begin(), s.end(), [](char c) {
        return std::isalnum(static_cast<unsigned char>(c)) || c == '_';
    });
}

inline bool isSpace(char c) { return c == ' ' || c == '\t' || c == '\n' || c == '\r'; }

inline std::string_view trim(std::string_view s) {
    while (!s.empty() && isSpace(s.front())) s.remove_prefix(1);
    while (!s.empty() && isSpace(s.back())) s.remove_suffix(1);
    return s;
}

// Strict: the whole string is one finite number (no "1.2.3", "abc", "nan", "inf").
inline std::optional<double> toNumber(std::string_view s) {
    s = trim(s);
    if (s.size() > 1 && s[0] == '+' && s[1] != '-') s.remove_prefix(1);
    double v = 0;
    const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
    if (s.empty() || ec != std::errc() || end != s.data() + s.size() || !std::isfinite(v))
        return std::nullopt;
    return v;
}

inline std::optional<int> toInteger(std::string_view s) {
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
inline std::string describe(pugi::xml_node n) {
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

// A <transform> element: later operations apply after earlier ones, M = op_k * ... * op_1.
Eigen::Affine3d parseTransform(const Context& ctx, pugi::xml_node n);

// The document's <scene> root element; throws Error for malformed XML or another root.
pugi::xml_node loadRoot(pugi::xml_document& doc, const std::string& text, const Context& ctx);

}  // namespace phongfit::scene_xml
