// Renders a scene file (with `defines`) at `spp` paths a pixel into an EXR at `path`: the observed
// image of a scene-fit test.
#pragma once

#include <map>
#include <string>

#include "image.h"
#include "renderer.h"
#include "scene_parser.h"

namespace phongfit::test {

inline void renderToExr(const std::string& scenePath,
                        const std::map<std::string, std::string>& defines, int spp,
                        const std::string& path) {
    RenderOptions render;
    render.spp = spp;
    render.quiet = true;
    const RenderResult r = Renderer(loadScene(scenePath, defines)).render(render);
    Image out;
    out.width = r.width;
    out.height = r.height;
    out.rgb = r.rgb;
    writeExr(out, path);
}

}  // namespace phongfit::test
