// The lines along which a sheet is creased or folded, for drawing (the --png renderer and
// BulletWorld::debugDraw).
#include "tearables/paper.hpp"

#include <algorithm>
#include <cmath>

namespace tearables {

std::vector<std::array<std::uint32_t, 2>> paperCreaseLines(const PaperView& v) {
    std::vector<std::array<std::uint32_t, 2>> lines;
    if (!v.positions || !v.triangles || !v.springs) return lines;
    const std::vector<Vec3>& x = *v.positions;
    const std::size_t n = x.size();
    // The mesh's neighbours of each vertex (from the triangles: the springs also join
    // vertices across edges).
    std::vector<std::vector<std::uint32_t>> neighbours(n);
    for (const auto& t : *v.triangles)
        for (int c = 0; c < 3; ++c) {
            const std::uint32_t a = t[c], b = t[(c + 1) % 3];
            if (a >= n || b >= n) continue;
            neighbours[a].push_back(b);
            neighbours[b].push_back(a);
        }
    for (auto& list : neighbours) {
        std::sort(list.begin(), list.end());
        list.erase(std::unique(list.begin(), list.end()), list.end());
    }
    for (const PaperSpring& sp : *v.springs) {
        if (sp.kind == PaperSpringKind::Hinge && !sp.broken) {
            // A hinge spans a folded edge: the fold is that edge.
            if (sp.hinge[0] < n && sp.hinge[1] < n) lines.push_back({sp.hinge[0], sp.hinge[1]});
            continue;
        }
        if (sp.kind != PaperSpringKind::Auxiliary) continue;
        // A crease: the spring a-b broke under compression and the vertex c = hinge[0] was
        // inserted between them (src/paper/hinge.cpp). The paper folds along a line across
        // a-b through c: its edges to the vertices that were opposite a-b. Drawn are c's
        // edges more across a-b than along it (within 60 degrees of perpendicular), which
        // also holds after later creases split those edges.
        const std::uint32_t c = sp.hinge[0];
        if (c >= n || sp.a >= n || sp.b >= n) continue;
        const Vec3 along = x[sp.b] - x[sp.a];
        if (!(along.norm() > 0.0)) continue;
        const Vec3 axis = along.normalized();
        for (std::uint32_t o : neighbours[c]) {
            const Vec3 e = x[o] - x[c];
            const double len = e.norm();
            if (len > 0.0 && std::abs(axis.dot(e)) < 0.5 * len) lines.push_back({c, o});
        }
    }
    return lines;
}

}  // namespace tearables
