#include "scene_xml.h"

namespace phongfit::scene_xml {

Eigen::Affine3d parseTransform(const Context& ctx, pugi::xml_node n) {
    Eigen::Affine3d m = Eigen::Affine3d::Identity();
    for (const pugi::xml_node c : n.children()) {
        if (c.type() != pugi::node_element) ctx.failText(c);
        ctx.checkNoChildren(c);
        const std::string op = c.name();
        Eigen::Affine3d t = Eigen::Affine3d::Identity();
        if (op == "translate") {
            ctx.checkAttributes(c, {"x", "y", "z"});
            t = Eigen::Translation3d(ctx.optionalNumber(c, "x", 0), ctx.optionalNumber(c, "y", 0),
                                     ctx.optionalNumber(c, "z", 0));
        } else if (op == "scale") {
            ctx.checkAttributes(c, {"value", "x", "y", "z"});
            Vec3d s;
            if (const std::optional<std::string> value = ctx.attr(c, "value")) {
                if (c.attribute("x") || c.attribute("y") || c.attribute("z"))
                    ctx.fail(c, "both value= and x, y, z given (allowed: one of the two)");
                s.setConstant(ctx.number(c, *value));
            } else {
                s = Vec3d(ctx.optionalNumber(c, "x", 1), ctx.optionalNumber(c, "y", 1),
                          ctx.optionalNumber(c, "z", 1));
            }
            if ((s.array() == 0).any())
                ctx.fail(c, "a scale factor of 0 collapses space (allowed: nonzero factors)");
            t.linear() = s.asDiagonal();
        } else if (op == "rotate") {
            ctx.checkAttributes(c, {"x", "y", "z", "angle"});
            const Vec3d axis(ctx.optionalNumber(c, "x", 0), ctx.optionalNumber(c, "y", 0),
                             ctx.optionalNumber(c, "z", 0));
            if (axis.norm() == 0)
                ctx.fail(c, "the rotation axis x, y, z is zero (allowed: a nonzero axis)");
            const double angle = ctx.number(c, ctx.required(c, "angle", "degrees"));
            t = Eigen::AngleAxisd(angle * kPi / 180, axis.normalized());
        } else if (op == "matrix") {
            ctx.checkAttributes(c, {"value"});
            const std::string text = ctx.required(c, "value", "16 numbers, row-major");
            const std::vector<double> v = ctx.numberList(c, text);
            if (v.size() != 16)
                ctx.fail(c, fmt::format("value has {} numbers (allowed: 16, row-major)", v.size()));
            Eigen::Matrix4d mat;
            for (int i = 0; i < 4; ++i)
                for (int j = 0; j < 4; ++j) mat(i, j) = v[std::size_t(4 * i + j)];
            if (mat.row(3) != Eigen::RowVector4d(0, 0, 0, 1))
                ctx.fail(c, "the last row is not 0 0 0 1 (allowed: affine matrices)");
            t.matrix() = mat;
        } else if (op == "lookat") {
            ctx.checkAttributes(c, {"origin", "target", "up"});
            const Vec3d origin = ctx.vec3(c, "origin");
            const Vec3d target = ctx.vec3(c, "target");
            if (target == origin)
                ctx.fail(c, "origin and target coincide (allowed: distinct points)");
            const Vec3d dir = (target - origin).normalized();
            const Vec3d up = c.attribute("up") ? ctx.vec3(c, "up") : Frame<double>(dir).s;
            // As Mitsuba: camera +x = up x dir is the viewer's left.
            const Vec3d left = up.cross(dir);
            if (!(left.norm() > 1e-9 * up.norm()))
                ctx.fail(c,
                         "up is zero or parallel to target - origin (allowed: any other "
                         "direction)");
            t.linear().col(0) = left.normalized();
            t.linear().col(1) = dir.cross(t.linear().col(0));
            t.linear().col(2) = dir;
            t.translation() = origin;
        } else {
            ctx.fail(c,
                     "unknown transform operation (allowed: translate, scale, rotate, matrix, "
                     "lookat)");
        }
        m = t * m;
    }
    const Eigen::Matrix3d l = m.linear();
    const double scale = l.col(0).norm() * l.col(1).norm() * l.col(2).norm();
    if (!m.matrix().allFinite() || !(std::abs(l.determinant()) > 1e-12 * scale))
        ctx.fail(n,
                 "the transform is degenerate: it collapses space onto a plane, line or point "
                 "(allowed: invertible transforms)");
    return m;
}

pugi::xml_node loadRoot(pugi::xml_document& doc, const std::string& text, const Context& ctx) {
    const pugi::xml_parse_result result =
        doc.load_buffer(text.data(), text.size(), pugi::parse_default, pugi::encoding_utf8);
    if (!result)
        throw Error(fmt::format("{}:{}: malformed XML: {}", ctx.file(), ctx.line(result.offset),
                                result.description()));
    const pugi::xml_node root = doc.document_element();
    if (std::string_view(root.name()) != "scene")
        ctx.fail(root, "the root element must be <scene version=\"0.6.0\">");
    return root;
}

}  // namespace phongfit::scene_xml
