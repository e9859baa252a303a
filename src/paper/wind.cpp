// Air drag on sheets (paper and cloth), face by face.
//
// A flat plate in a flow feels, to first order, the pressure drag of the flow's component
// along its normal: F = 1/2 rho C_d A (w . n) |w . n| n, with w the air's velocity relative
// to the plate (Hoerner, Fluid-Dynamic Drag, 1965, ch. 3: C_d ~ 1.2 for a plate normal to
// the flow). A face edge-on to the wind (w . n = 0) feels nothing; the friction drag along
// the face is two orders smaller for paper and cloth and is neglected. It is the strings'
// wind (demos/scene_runner.cpp: the component of w normal to a segment, on its projected
// area 2 r l) applied to a face: the component normal to the face, on its area.
#include "tearables/cloth.hpp"
#include "tearables/types.hpp"
#include "tearables/paper.hpp"

#include <cmath>
#include <map>
#include <string>

namespace tearables {

void addFaceDrag(const std::vector<Vec3>& positions, const std::vector<Vec3>& velocities,
                 const std::vector<std::array<std::uint32_t, 3>>& triangles, const Vec3& wind, double air_density,
                 double drag_coefficient, std::vector<Vec3>& force) {
    if (!wind.allFinite()) throw InvalidInput("wind", "must be finite");
    if (!std::isfinite(air_density) || air_density < 0.0) throw InvalidInput("air_density", "must be finite and >= 0");
    if (!std::isfinite(drag_coefficient) || drag_coefficient < 0.0) throw InvalidInput("drag_coefficient", "must be finite and >= 0");
    if (velocities.size() != positions.size()) throw InvalidInput("velocities", "must have one entry per position");
    force.resize(positions.size(), Vec3::Zero());
    for (std::size_t t = 0; t < triangles.size(); ++t) {
        const auto& tri = triangles[t];
        for (std::uint32_t v : tri)
            if (v >= positions.size()) throw InvalidInput("triangles[" + std::to_string(t) + "]", "names a vertex past the positions");
        const Vec3& a = positions[tri[0]];
        const Vec3 cross = (positions[tri[1]] - a).cross(positions[tri[2]] - a);  // 2 A n
        const double twice_area = cross.norm();
        if (!(twice_area > 0.0)) continue;  // degenerate: no normal, no area
        const Vec3 n = cross / twice_area;
        const Vec3 w = wind - (velocities[tri[0]] + velocities[tri[1]] + velocities[tri[2]]) / 3.0;
        const double wn = w.dot(n);
        // 1/2 rho C_d A (w.n)|w.n| n, A = twice_area / 2; a third to each corner.
        const Vec3 f = (0.25 * air_density * drag_coefficient * twice_area * wn * std::abs(wn) / 3.0) * n;
        for (std::uint32_t v : tri) force[v] += f;
    }
}

std::vector<std::array<std::uint32_t, 3>> clothFaces(const ClothView& view) {
    const int nx = view.resolution[0], nz = view.resolution[1];
    std::map<std::pair<std::uint32_t, std::uint32_t>, bool> intact;  // yarn edge (low, high) -> not torn
    for (std::size_t e = 0; e < view.edges->size(); ++e) {
        auto [a, b] = (*view.edges)[e];
        if (a > b) std::swap(a, b);
        intact[{a, b}] = !(*view.broken)[e];
    }
    auto whole = [&](std::uint32_t a, std::uint32_t b) {
        if (a > b) std::swap(a, b);
        const auto it = intact.find({a, b});
        return it != intact.end() && it->second;
    };
    std::vector<std::array<std::uint32_t, 3>> faces;
    for (int k = 0; k + 1 < nz; ++k)
        for (int i = 0; i + 1 < nx; ++i) {
            const auto v00 = static_cast<std::uint32_t>(k * nx + i), v10 = v00 + 1;
            const auto v01 = static_cast<std::uint32_t>((k + 1) * nx + i), v11 = v01 + 1;
            // A cell of the weave carries air load only while its four yarns hold it.
            if (!whole(v00, v10) || !whole(v10, v11) || !whole(v01, v11) || !whole(v00, v01)) continue;
            faces.push_back({v00, v01, v11});
            faces.push_back({v00, v11, v10});
        }
    return faces;
}

}  // namespace tearables
