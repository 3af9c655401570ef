// Writes a scene file back with fitted materials (the `fitted.xml` of `phongfit fit`).
#pragma once

#include <map>
#include <string>

#include "phong_brdf.h"

namespace phongfit {

// Copies the scene file `inPath` to `outPath` with the phong bsdfs named in `materials` (by id) set
// to the given values; everything else is kept byte for byte (comments, order, layout). `defines`
// are those the scene is used with: they resolve `$name` in the file. A replaced parameter is
// written as a literal (a `$name` there is dropped; its `default` stays); a phong parameter the
// file left at its default is added. When `outPath` is in another directory, relative obj and
// envmap file names are rewritten so they still point at the same files. Written atomically
// (temporary file and rename). Throws Error if the scene does not parse, an id is missing or not
// phong, or a material is invalid (validatePhong).
void writeSceneWithMaterials(const std::string& inPath,
                             const std::map<std::string, std::string>& defines,
                             const std::map<std::string, PhongMaterial>& materials,
                             const std::string& outPath);

}  // namespace phongfit
