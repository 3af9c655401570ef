// A scene's variables: its `default`s, in document order (each may use earlier ones), overridden
// by `-D name=value` defines. Internal to the scene parser; expandVariables is public
// (scene_parser.h).
#pragma once

#include "scene_xml.h"

namespace phongfit::scene_xml {

// Defaults may use earlier defaults, so expansion can grow a value exponentially ("billion
// laughs"); no honest value comes near this.
constexpr std::size_t kMaxExpandedLength = 1 << 20;

// `default`s in document order (each may use earlier ones); a define wins over a default.
Vars collectVariables(const Context& ctx, pugi::xml_node root, const Vars& defines);

}  // namespace phongfit::scene_xml
