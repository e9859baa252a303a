// Paper sheets: descriptor validation and the rest mesh (vertices, lumped masses,
// structural and bending springs).
#include "paper/sheet.hpp"

#include "base/validate.hpp"
#include "sim/sheet_attachments.hpp"

#include <algorithm>
#include <cmath>
#include <tuple>

namespace tearables {

namespace {

void requireRange(double value, double lo, double hi, const char* field, const char* range) {
    if (!std::isfinite(value) || value < lo || value > hi) throw InvalidInput(field, std::string("must be in ") + range);
}

}  // namespace

void validate(const PaperDesc& d) {
    if (d.vertices.empty()) {
        if (!d.orientation.coeffs().allFinite() || d.orientation.coeffs().norm() < 1e-9)
            throw InvalidInput("orientation", "must be a finite, non-zero quaternion");
        for (int a = 0; a < 2; ++a) {
            if (!std::isfinite(d.size[a]) || !(d.size[a] > 0.0)) throw InvalidInput("size", "both extents must be finite and > 0 m");
            if (d.resolution[a] < 2 || d.resolution[a] > 1024) throw InvalidInput("resolution", "each must be 2..1024 vertices");
        }
        detail::requireSheetPlacement(d.center, d.corner, std::hypot(d.size[0], d.size[1]));
        if (!d.triangles.empty()) throw InvalidInput("triangles", "given without vertices");
    } else {
        if (d.center) throw InvalidInput("center", "belongs to a rectangle: this sheet gives vertices");
        if (d.corner) throw InvalidInput("corner", "belongs to a rectangle: this sheet gives vertices");
        for (std::size_t i = 0; i < d.vertices.size(); ++i)
            detail::requirePosition("vertices[" + std::to_string(i) + "]", d.vertices[i]);
        if (d.triangles.empty()) throw InvalidInput("triangles", "a mesh needs at least one triangle");
        const auto n = static_cast<std::uint32_t>(d.vertices.size());
        std::vector<std::uint8_t> used(n, 0);
        // Directed edges: each may appear once (consistent orientation), and an undirected
        // edge at most twice (a manifold).
        std::vector<std::tuple<std::uint32_t, std::uint32_t, std::size_t>> directed;
        for (std::size_t t = 0; t < d.triangles.size(); ++t) {
            const auto& tri = d.triangles[t];
            const std::string field = "triangles[" + std::to_string(t) + "]";
            for (std::uint32_t v : tri)
                if (v >= n) throw InvalidInput(field, "vertex index " + std::to_string(v) + " out of range");
            if (tri[0] == tri[1] || tri[1] == tri[2] || tri[0] == tri[2]) throw InvalidInput(field, "repeats a vertex");
            const Vec3 c = (d.vertices[tri[1]] - d.vertices[tri[0]]).cross(d.vertices[tri[2]] - d.vertices[tri[0]]);
            if (!(c.norm() > 1e-14)) throw InvalidInput(field, "is degenerate (zero area)");
            for (int e = 0; e < 3; ++e) {
                used[tri[e]] = 1;
                directed.emplace_back(tri[e], tri[(e + 1) % 3], t);
            }
        }
        std::sort(directed.begin(), directed.end());
        for (std::size_t i = 1; i < directed.size(); ++i)
            if (std::get<0>(directed[i]) == std::get<0>(directed[i - 1]) && std::get<1>(directed[i]) == std::get<1>(directed[i - 1]))
                throw InvalidInput("triangles[" + std::to_string(std::get<2>(directed[i])) + "]",
                                   "orientation is not consistent with its neighbour, or an edge is shared by more than two triangles");
        for (std::uint32_t v = 0; v < n; ++v)
            if (!used[v]) throw InvalidInput("vertices[" + std::to_string(v) + "]", "is used by no triangle");
    }
    requireRange(d.areal_density, 1e-9, 1e6, "areal_density", "[1e-9, 1e6] kg/m^2");
    if (!std::isfinite(d.stiffness) || !(d.stiffness > 0.0) || d.stiffness > 1e12) throw InvalidInput("stiffness", "must be in (0, 1e12] N/m");
    requireRange(d.bending, 0.0, 1.0, "bending", "[0, 1] (fraction of stiffness)");
    requireRange(d.damping, 0.0, 1.0, "damping", "[0, 1] s");
    if (d.solver != PaperSolver::ConjugateGradient && d.solver != PaperSolver::Paper && d.solver != PaperSolver::Multigrid)
        throw InvalidInput("solver", "must be Paper, ConjugateGradient or Multigrid");
    if (!std::isfinite(d.tolerance) || d.tolerance < 1e-12 || d.tolerance > 1e-1) throw InvalidInput("tolerance", "must be in [1e-12, 1e-1]");
    if (d.jacobi_iterations < 1 || d.jacobi_iterations > 256) throw InvalidInput("jacobi_iterations", "must be 1..256");
    if (!std::isfinite(d.phi) || !(d.phi > 0.0) || d.phi > 1e3) throw InvalidInput("phi", "must be in (0, 1000]");
    requireRange(d.psi, 0.0, 4.0, "psi", "[0, 4]");
    if (!std::isfinite(d.hinge_threshold) || d.hinge_threshold < 0.0 || !(d.hinge_threshold < 1.0))
        throw InvalidInput("hinge_threshold", "must be in [0, 1) (fraction of the rest distance)");
    if (!std::isfinite(d.rupture_stretch) || !(d.rupture_stretch > 0.0) || d.rupture_stretch > 100.0)
        throw InvalidInput("rupture_stretch", "must be in (0, 100] (relative stretch)");
    if (!std::isfinite(d.thickness) || !(d.thickness > 0.0) || d.thickness > 1.0) throw InvalidInput("thickness", "must be in (0, 1] m");
    requireRange(d.friction, 0.0, 100.0, "friction", "[0, 100]");
    const std::size_t n = d.vertices.empty() ? static_cast<std::size_t>(d.resolution[0]) * d.resolution[1] : d.vertices.size();
    detail::resolveSheetAttachments(d.attachments, n, "sheet");
}

namespace detail {

void restMesh(const PaperDesc& d, std::vector<Vec3>& x, std::vector<std::array<std::uint32_t, 3>>& triangles) {
    if (!d.vertices.empty()) {
        x = d.vertices;
        triangles = d.triangles;
        return;
    }
    const int nx = d.resolution[0], nz = d.resolution[1];
    const Quat q = d.orientation.normalized();
    x.resize(static_cast<std::size_t>(nx) * nz);
    // Vertex (i, k) from the corner: (i size[0] / (nx - 1), 0, k size[1] / (nz - 1)) in the
    // sheet's frame; from the centre, the same less half the size along each axis (the
    // cloth's grid, cloth/mesh.cpp, places its vertices the same way).
    const bool from_corner = d.corner.has_value();
    const Vec3 anchor = from_corner ? *d.corner : d.center.value_or(defaultSheetCenter());
    for (int k = 0; k < nz; ++k)
        for (int i = 0; i < nx; ++i) {
            const Vec3 local = from_corner ? Vec3(i * (d.size[0] / (nx - 1)), 0.0, k * (d.size[1] / (nz - 1)))
                                           : Vec3(-0.5 * d.size[0] + d.size[0] * i / (nx - 1), 0.0, -0.5 * d.size[1] + d.size[1] * k / (nz - 1));
            x[static_cast<std::size_t>(d.gridVertex(i, k))] = anchor + q * local;
        }
    triangles.clear();
    // Counter-clockwise seen from the local +y normal; the diagonals alternate in a
    // checkerboard so that the sheet has no preferred shear direction.
    for (int k = 0; k + 1 < nz; ++k)
        for (int i = 0; i + 1 < nx; ++i) {
            const auto p00 = static_cast<std::uint32_t>(d.gridVertex(i, k)), p10 = static_cast<std::uint32_t>(d.gridVertex(i + 1, k));
            const auto p01 = static_cast<std::uint32_t>(d.gridVertex(i, k + 1)), p11 = static_cast<std::uint32_t>(d.gridVertex(i + 1, k + 1));
            if ((i + k) % 2 == 0) {
                triangles.push_back({p00, p01, p11});
                triangles.push_back({p00, p11, p10});
            } else {
                triangles.push_back({p00, p01, p10});
                triangles.push_back({p10, p01, p11});
            }
        }
}

PaperSheet buildSheet(const PaperDesc& desc) {
    PaperSheet s;
    s.desc = desc;
    s.desc.orientation.normalize();
    s.rng.seed(desc.seed);
    restMesh(desc, s.x, s.triangles);
    const std::size_t n = s.x.size();
    s.v.assign(n, Vec3::Zero());
    s.x_pred = s.x;
    s.force.assign(n, Vec3::Zero());
    s.mass.assign(n, 0.0);
    s.hold.assign(n, ParticleHold{});
    s.crack_tip.assign(n, 0);
    // Lumped masses: a third of each triangle's mass to each corner.
    for (const auto& t : s.triangles) {
        const double area = 0.5 * (s.x[t[1]] - s.x[t[0]]).cross(s.x[t[2]] - s.x[t[0]]).norm();
        for (std::uint32_t v : t) s.mass[v] += desc.areal_density * area / 3.0;
    }
    s.total_mass = 0.0;
    for (double m : s.mass) s.total_mass += m;
    // Structural springs on the edges; bending springs between the two vertices opposite
    // each inner edge (the usual mass-spring flexural springs; Paper Sec. III.B's hinge
    // springs are inserted across the same pairs when an edge folds).
    struct Half {
        std::uint32_t lo, hi, opposite;
        bool operator<(const Half& o) const { return std::tie(lo, hi, opposite) < std::tie(o.lo, o.hi, o.opposite); }
    };
    std::vector<Half> halves;
    for (const auto& t : s.triangles)
        for (int e = 0; e < 3; ++e) {
            const std::uint32_t a = t[e], b = t[(e + 1) % 3];
            halves.push_back({std::min(a, b), std::max(a, b), t[(e + 2) % 3]});
        }
    std::sort(halves.begin(), halves.end());
    buildAdjacency(s);
    const double k = desc.stiffness;
    for (std::size_t i = 0; i < halves.size();) {
        std::size_t j = i + 1;
        while (j < halves.size() && halves[j].lo == halves[i].lo && halves[j].hi == halves[i].hi) ++j;
        addSpring(s, halves[i].lo, halves[i].hi, (s.x[halves[i].lo] - s.x[halves[i].hi]).norm(), k, PaperSpringKind::Structural);
        if (j - i == 2 && desc.bending > 0.0) {
            const std::uint32_t a = halves[i].opposite, b = halves[i + 1].opposite;
            const std::uint32_t sp = addSpring(s, a, b, (s.x[a] - s.x[b]).norm(), desc.bending * k, PaperSpringKind::Bending);
            setSpringName(s, sp, 2, halves[i].lo);
            setSpringName(s, sp, 3, halves[i].hi);
        }
        i = j;
    }
    return s;
}

}  // namespace detail
}  // namespace tearables
