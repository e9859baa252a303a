// Paper sheets: topology helpers (append-only vertices and springs) and the validity check
// that the tests run after every change of topology.
#include "paper/sheet.hpp"

#include <algorithm>
#include <cmath>
#include <tuple>

namespace tearables::detail {

std::uint32_t addVertex(PaperSheet& s, const Vec3& x, const Vec3& v, double mass) {
    s.x.push_back(x);
    s.x_pred.push_back(x);
    s.v.push_back(v);
    s.force.push_back(Vec3::Zero());
    s.mass.push_back(mass);
    s.hold.push_back(VertexHold{});
    return static_cast<std::uint32_t>(s.x.size() - 1);
}

std::uint32_t addSpring(PaperSheet& s, std::uint32_t a, std::uint32_t b, double rest, double k, PaperSpringKind kind) {
    PaperSpring sp;
    sp.a = a;
    sp.b = b;
    sp.rest = rest;
    sp.stiffness = k;
    sp.kind = kind;
    s.springs.push_back(sp);
    s.survived.push_back(0.0);
    return static_cast<std::uint32_t>(s.springs.size() - 1);
}

void trianglesOf(const PaperSheet& s, std::uint32_t v, std::vector<std::uint32_t>& out) {
    out.clear();
    for (std::size_t t = 0; t < s.triangles.size(); ++t) {
        const auto& tri = s.triangles[t];
        if (tri[0] == v || tri[1] == v || tri[2] == v) out.push_back(static_cast<std::uint32_t>(t));
    }
}

void trianglesWithEdge(const PaperSheet& s, std::uint32_t a, std::uint32_t b, std::vector<std::uint32_t>& out) {
    out.clear();
    for (std::size_t t = 0; t < s.triangles.size(); ++t) {
        const auto& tri = s.triangles[t];
        const bool ha = tri[0] == a || tri[1] == a || tri[2] == a;
        const bool hb = tri[0] == b || tri[1] == b || tri[2] == b;
        if (ha && hb) out.push_back(static_cast<std::uint32_t>(t));
    }
}

std::uint32_t thirdVertex(const std::array<std::uint32_t, 3>& t, std::uint32_t a, std::uint32_t b) {
    for (std::uint32_t v : t)
        if (v != a && v != b) return v;
    return UINT32_MAX;
}

Vec3 triangleNormal(const PaperSheet& s, const std::array<std::uint32_t, 3>& t) {
    const Vec3 c = (s.x[t[1]] - s.x[t[0]]).cross(s.x[t[2]] - s.x[t[0]]);
    const double len = c.norm();
    return len > 0.0 ? Vec3(c / len) : Vec3(Vec3::Zero());
}

std::string checkMesh(const PaperSheet& s, double min_area) {
    const auto n = static_cast<std::uint32_t>(s.x.size());
    if (s.v.size() != n || s.mass.size() != n || s.hold.size() != n || s.force.size() != n || s.x_pred.size() != n)
        return "per-vertex arrays differ in size";
    if (s.survived.size() != s.springs.size()) return "per-spring arrays differ in size";
    PaperView v;
    v.positions = &s.x;
    v.velocities = &s.v;
    v.masses = &s.mass;
    v.triangles = &s.triangles;
    v.springs = &s.springs;
    return checkMesh(v, s.total_mass, min_area);
}

std::string checkMesh(const PaperView& view, double total_mass, double min_area) {
    struct {
        const std::vector<Vec3>& x;
        const std::vector<double>& mass;
        const std::vector<std::array<std::uint32_t, 3>>& triangles;
        const std::vector<PaperSpring>& springs;
        double total_mass;
    } s{*view.positions, *view.masses, *view.triangles, *view.springs, total_mass};
    const auto n = static_cast<std::uint32_t>(s.x.size());
    if (s.mass.size() != n) return "per-vertex arrays differ in size";
    double total = 0.0;
    for (std::uint32_t v = 0; v < n; ++v) {
        if (!(s.mass[v] > 0.0)) return "vertex " + std::to_string(v) + " has no mass";
        total += s.mass[v];
    }
    if (std::abs(total - s.total_mass) > 1e-9 * s.total_mass) return "mass not conserved";
    std::vector<std::tuple<std::uint32_t, std::uint32_t, std::uint32_t>> directed;  // (from, to, triangle)
    for (std::size_t t = 0; t < s.triangles.size(); ++t) {
        const auto& tri = s.triangles[t];
        for (std::uint32_t v : tri)
            if (v >= n) return "triangle " + std::to_string(t) + " has a vertex out of range";
        if (tri[0] == tri[1] || tri[1] == tri[2] || tri[0] == tri[2]) return "triangle " + std::to_string(t) + " repeats a vertex";
        const double area = 0.5 * (s.x[tri[1]] - s.x[tri[0]]).cross(s.x[tri[2]] - s.x[tri[0]]).norm();
        if (!(area > min_area)) return "triangle " + std::to_string(t) + " is degenerate";
        for (int e = 0; e < 3; ++e) directed.emplace_back(tri[e], tri[(e + 1) % 3], static_cast<std::uint32_t>(t));
    }
    std::sort(directed.begin(), directed.end());
    for (std::size_t i = 1; i < directed.size(); ++i)
        if (std::get<0>(directed[i]) == std::get<0>(directed[i - 1]) && std::get<1>(directed[i]) == std::get<1>(directed[i - 1]))
            return "triangles " + std::to_string(std::get<2>(directed[i - 1])) + " and " + std::to_string(std::get<2>(directed[i])) +
                   " share a directed edge (inconsistent orientation or a non-manifold edge)";
    // Undirected edges: at most two triangles each (with the directed check, exactly the
    // manifold condition), and each one a live structural spring.
    std::vector<std::pair<std::uint32_t, std::uint32_t>> edges;
    for (const auto& [a, b, t] : directed) edges.emplace_back(std::min(a, b), std::max(a, b));
    std::sort(edges.begin(), edges.end());
    for (std::size_t i = 2; i < edges.size(); ++i)
        if (edges[i] == edges[i - 2]) return "an edge is shared by more than two triangles";
    edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
    std::vector<std::pair<std::uint32_t, std::uint32_t>> structural;
    for (std::size_t i = 0; i < s.springs.size(); ++i) {
        const PaperSpring& sp = s.springs[i];
        if (sp.a >= n || sp.b >= n || sp.a == sp.b) return "spring " + std::to_string(i) + " dangles (bad vertices)";
        if (sp.broken) continue;
        if (!(sp.rest > 0.0) || !std::isfinite(sp.rest)) return "spring " + std::to_string(i) + " has a bad rest length";
        if (sp.kind == PaperSpringKind::Structural) structural.emplace_back(std::min(sp.a, sp.b), std::max(sp.a, sp.b));
    }
    std::sort(structural.begin(), structural.end());
    for (std::size_t i = 1; i < structural.size(); ++i)
        if (structural[i] == structural[i - 1]) return "two live structural springs on one edge";
    if (structural != edges) return "live structural springs and mesh edges differ (a dangling spring or an edge without one)";
    // Vertices used by no triangle: only allowed for none (every vertex has mass from a triangle).
    std::vector<std::uint8_t> used(n, 0);
    for (const auto& tri : s.triangles)
        for (std::uint32_t v : tri) used[v] = 1;
    for (std::uint32_t v = 0; v < n; ++v)
        if (!used[v]) return "vertex " + std::to_string(v) + " belongs to no triangle";
    return "";
}

}  // namespace tearables::detail

namespace tearables::detail {

namespace {

bool hasTriangle(const PaperSheet& s, std::uint32_t a, std::uint32_t b, std::uint32_t c) {
    for (const auto& t : s.triangles) {
        const bool ha = t[0] == a || t[1] == a || t[2] == a;
        const bool hb = t[0] == b || t[1] == b || t[2] == b;
        const bool hc = t[0] == c || t[1] == c || t[2] == c;
        if (ha && hb && hc) return true;
    }
    return false;
}

bool hasEdge(const PaperSheet& s, std::uint32_t a, std::uint32_t b) {
    for (const auto& t : s.triangles)
        for (int e = 0; e < 3; ++e)
            if ((t[e] == a && t[(e + 1) % 3] == b) || (t[e] == b && t[(e + 1) % 3] == a)) return true;
    return false;
}

}  // namespace

bool springHolds(const PaperSheet& s, const PaperSpring& sp) {
    switch (sp.kind) {
        case PaperSpringKind::Structural: return true;
        case PaperSpringKind::Auxiliary: return hasEdge(s, sp.a, sp.hinge[0]) && hasEdge(s, sp.hinge[0], sp.b);
        case PaperSpringKind::Bending:
        case PaperSpringKind::Hinge:
            return hasTriangle(s, sp.hinge[0], sp.hinge[1], sp.a) && hasTriangle(s, sp.hinge[0], sp.hinge[1], sp.b);
    }
    return false;
}

void revalidateSprings(PaperSheet& s, std::uint32_t vertex, std::uint32_t twin) {
    for (PaperSpring& sp : s.springs) {
        if (sp.broken || sp.kind == PaperSpringKind::Structural) continue;
        // The four names a spring uses: its ends and what it spans.
        std::uint32_t* names[4] = {&sp.a, &sp.b, &sp.hinge[0], &sp.hinge[1]};
        int uses = 0;
        for (std::uint32_t* n : names) uses += (*n == vertex || (twin != UINT32_MAX && *n == twin)) ? 1 : 0;
        if (uses == 0) continue;
        if (springHolds(s, sp)) continue;
        bool fixed = false;
        if (twin != UINT32_MAX) {
            // Try every renaming of `vertex` to `twin` among the names (at most 2^4).
            std::uint32_t* slots[4];
            int count = 0;
            for (std::uint32_t* n : names)
                if (*n == vertex) slots[count++] = n;
            for (int mask = 1; mask < (1 << count) && !fixed; ++mask) {
                for (int i = 0; i < count; ++i) *slots[i] = (mask >> i) & 1 ? twin : vertex;
                fixed = sp.a != sp.b && springHolds(s, sp);
            }
            if (!fixed)
                for (int i = 0; i < count; ++i) *slots[i] = vertex;
        }
        if (!fixed) sp.broken = true;
    }
}

}  // namespace tearables::detail
