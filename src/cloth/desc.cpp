// ClothDesc validation: check at creation, so the hot loop can assume.
#include "base/validate.hpp"
#include "sim/sheet_attachments.hpp"
#include "sim/validate_material.hpp"
#include "tearables/cloth.hpp"

#include <cmath>
#include <set>
#include <utility>

namespace tearables {

namespace {

using detail::num;
using detail::requireFinite;
using detail::requirePositive;
using detail::requireRange;
using detail::requirePosition;
using detail::resolveSheetAttachments;

int resolveAxis(int k, int count, const std::string& field) {
    if (k < -count || k >= count)
        throw InvalidInput(field, "index " + std::to_string(k) + " out of range (the cloth has " + std::to_string(count) +
                                      " vertices along this axis)");
    return k < 0 ? k + count : k;
}

}  // namespace

int ClothDesc::vertex(int i, int j) const {
    const int a = resolveAxis(i, resolution[0], "vertex");
    const int b = resolveAxis(j, resolution[1], "vertex");
    return b * resolution[0] + a;
}

void validate(const ClothDesc& d) {
    for (int k = 0; k < 2; ++k) {
        const std::string f = "resolution[" + std::to_string(k) + "]";
        if (d.resolution[k] < 1 || d.resolution[k] > 2000)
            throw InvalidInput(f, "must be in [1, 2000] (got " + std::to_string(d.resolution[k]) + ")");
    }
    if (d.resolution[0] * d.resolution[1] < 2) throw InvalidInput("resolution", "a cloth needs at least 2 vertices");
    for (int k = 0; k < 2; ++k)
        if (d.resolution[k] > 1) requirePositive("size[" + std::to_string(k) + "]", d.size[k]);
        else requireFinite("size[" + std::to_string(k) + "]", d.size[k]);
    detail::requireSheetPlacement(d.center, d.corner, std::hypot(d.size[0], d.size[1]));
    const Eigen::Vector4d q = d.orientation.coeffs();
    for (int k = 0; k < 4; ++k) requireFinite("orientation", q[k]);
    if (!(q.norm() > 1e-9)) throw InvalidInput("orientation", "must be a non-zero quaternion");
    requireRange("areal_density", d.areal_density, 0.0, 1e6);
    requireRange("density", d.density, 0.0, 1e6);
    if (d.areal_density > 0.0 && d.density > 0.0)
        throw InvalidInput("density", "give areal_density or density, not both (set the other to 0)");
    if (!(d.areal_density > 0.0) && !(d.density > 0.0))
        throw InvalidInput("areal_density", "one of areal_density and density must be greater than 0");
    if (d.areal_density > 0.0 && (d.resolution[0] == 1 || d.resolution[1] == 1))
        throw InvalidInput("areal_density", "a single yarn (resolution 1 along an axis) has no area: give density instead");
    requirePositive("yarn_radius", d.yarn_radius);
    detail::validateMaterial(d.material, "material");
    requireRange("lambda", d.lambda, 0.0, 1.0);
    requireRange("shear_stiffness", d.shear_stiffness, 0.0, 1e9);
    requireRange("bending_stiffness", d.bending_stiffness, 0.0, 1e9);
    requireRange("damping", d.damping, 0.0, 1e3);
    requireRange("plastic_time", d.plastic_time, 0.0, 10.0);
    resolveSheetAttachments(d.attachments, static_cast<std::size_t>(d.vertexCount()), "cloth");
    std::set<std::pair<int, int>> weak;  // (kind, flat index of the first vertex)
    for (std::size_t k = 0; k < d.weak_yarns.size(); ++k) {
        const std::string f = "weak_yarns[" + std::to_string(k) + "]";
        const ClothWeakYarn& w = d.weak_yarns[k];
        const int a = resolveAxis(w.i, d.resolution[0], f + ".i");
        const int b = resolveAxis(w.j, d.resolution[1], f + ".j");
        if (w.kind != YarnKind::Warp && w.kind != YarnKind::Weft) throw InvalidInput(f + ".kind", "must be warp or weft");
        const bool warp = w.kind == YarnKind::Warp;
        if (warp && a + 1 >= d.resolution[0])
            throw InvalidInput(f + ".i", "no warp yarn starts in the last column (" + std::to_string(a) +
                                             "): a warp yarn joins (i, j) and (i + 1, j)");
        if (!warp && b + 1 >= d.resolution[1])
            throw InvalidInput(f + ".j", "no weft yarn starts in the last row (" + std::to_string(b) +
                                             "): a weft yarn joins (i, j) and (i, j + 1)");
        if (!(w.strength > 0.0 && w.strength <= 1.0))
            throw InvalidInput(f + ".strength", "must be in (0, 1] (got " + num(w.strength) + ")");
        if (!weak.insert({warp ? 0 : 1, b * d.resolution[0] + a}).second)
            throw InvalidInput(f, std::string(warp ? "warp" : "weft") + " yarn (" + std::to_string(a) + ", " +
                                      std::to_string(b) + ") is already listed");
    }
}

}  // namespace tearables
