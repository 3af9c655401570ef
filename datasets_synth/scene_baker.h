// Writes a scene file with some of its `default` values replaced, so the file alone renders the
// sample (phongfit render scene.xml) with no -D needed.
#pragma once

#include <map>
#include <set>
#include <string>

namespace phongfit {

// Copies the scene `inPath` to `outPath` (atomically) with the value of each <default> named in
// `values` replaced, and `comment` (if not empty) added before the root element. Everything else
// is kept as written; relative file names (meshes, environment maps; written out or given by a
// default) are rewritten so they still point at the same files from `outPath`'s directory. Returns
// the names that were replaced (a name the scene does not declare is left out). Throws Error if the
// file cannot be read or is not well-formed XML.
std::set<std::string> bakeSceneDefaults(const std::string& inPath,
                                        const std::map<std::string, std::string>& values,
                                        const std::string& comment, const std::string& outPath);

}  // namespace phongfit
