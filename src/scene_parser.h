// Reads the Mitsuba 0.6 XML subset of DESIGN.md ("Scenes") into a validated Scene.
//
// As in Mitsuba 0.6: `$name` in any attribute value expands to a `default` of the scene (direct
// children of <scene>), which `-D name=value` defines override; ids are defined before they are
// referenced; a shape without a bsdf is diffuse 0.5; a scene without an integrator uses `direct`.
// Unlike Mitsuba, anything outside the subset is an error rather than a warning, and the sensor
// needs an explicit `fov`. Every error reads "FILE:LINE: element: what is wrong (allowed: ...)".
#pragma once

#include <map>
#include <string>

#include "scene.h"

namespace phongfit {

// Relative file names in the scene (obj) resolve against the scene file's directory.
Scene loadScene(const std::string& path, const std::map<std::string, std::string>& defines = {});

// As loadScene, from text: `fileName` is what messages name, `baseDir` what relative files
// resolve against.
Scene parseScene(const std::string& xmlText, const std::string& fileName,
                 const std::map<std::string, std::string>& defines = {},
                 const std::string& baseDir = ".");

// What `$name` expands to in a scene text: its `default`s, overridden by `defines`. For tools that
// edit a scene file in place (scene_writer).
std::map<std::string, std::string> sceneVariables(
    const std::string& xmlText, const std::string& fileName,
    const std::map<std::string, std::string>& defines);

// `value` with every `$name` replaced from `variables`; an undefined name throws an Error that
// starts with `where`.
std::string expandVariables(const std::string& value,
                            const std::map<std::string, std::string>& variables,
                            const std::string& where);

}  // namespace phongfit
