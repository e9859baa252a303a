// Paper sheets: topology helpers (append-only vertices and springs) and the validity check
// that the tests run after every change of topology.
#include "paper/sheet.hpp"

#include <algorithm>
#include <cmath>
#include <tuple>

namespace tearables::detail {

namespace {

void link(std::vector<std::uint32_t>& list, std::uint32_t item) { list.push_back(item); }
void unlink(std::vector<std::uint32_t>& list, std::uint32_t item) {
    const auto it = std::find(list.begin(), list.end(), item);
    if (it != list.end()) list.erase(it);
}
std::uint32_t* springSlot(PaperSpring& sp, int slot) {
    switch (slot) {
        case 0: return &sp.a;
        case 1: return &sp.b;
        case 2: return &sp.hinge[0];
        default: return &sp.hinge[1];
    }
}

}  // namespace

void buildAdjacency(PaperSheet& s) {
    s.vertex_triangles.assign(s.x.size(), {});
    s.vertex_springs.assign(s.x.size(), {});
    for (std::size_t t = 0; t < s.triangles.size(); ++t)
        for (std::uint32_t v : s.triangles[t]) link(s.vertex_triangles[v], static_cast<std::uint32_t>(t));
    for (std::size_t k = 0; k < s.springs.size(); ++k)
        for (int slot = 0; slot < 4; ++slot) {
            const std::uint32_t v = *springSlot(s.springs[k], slot);
            if (v < s.x.size()) link(s.vertex_springs[v], static_cast<std::uint32_t>(k));
        }
}

std::uint32_t addTriangle(PaperSheet& s, const std::array<std::uint32_t, 3>& t) {
    s.triangles.push_back(t);
    const auto index = static_cast<std::uint32_t>(s.triangles.size() - 1);
    for (std::uint32_t v : t) link(s.vertex_triangles[v], index);
    return index;
}

void setCorner(PaperSheet& s, std::uint32_t t, int c, std::uint32_t v) {
    std::uint32_t& corner = s.triangles[t][c];
    if (corner == v) return;
    unlink(s.vertex_triangles[corner], t);
    corner = v;
    link(s.vertex_triangles[v], t);
}

void setSpringName(PaperSheet& s, std::uint32_t k, int slot, std::uint32_t v) {
    std::uint32_t* name = springSlot(s.springs[k], slot);
    if (*name == v) return;
    if (*name < s.vertex_springs.size()) unlink(s.vertex_springs[*name], k);
    *name = v;
    if (v < s.vertex_springs.size()) link(s.vertex_springs[v], k);
}

// x and v by value: callers pass the sheet's own entries (a tear's twin starts where its
// vertex is), which the first push_back below may move.
std::uint32_t addVertex(PaperSheet& s, Vec3 x, Vec3 v, double mass) {
    s.vertex_triangles.emplace_back();
    s.vertex_springs.emplace_back();
    s.x.push_back(x);
    s.x_pred.push_back(x);
    s.v.push_back(v);
    s.force.push_back(Vec3::Zero());
    s.mass.push_back(mass);
    s.hold.push_back(ParticleHold{});
    s.crack_tip.push_back(0);
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
    const auto index = static_cast<std::uint32_t>(s.springs.size() - 1);
    if (a < s.vertex_springs.size()) link(s.vertex_springs[a], index);
    if (b < s.vertex_springs.size()) link(s.vertex_springs[b], index);
    return index;
}

void trianglesOf(const PaperSheet& s, std::uint32_t v, std::vector<std::uint32_t>& out) {
    out = s.vertex_triangles[v];
    std::sort(out.begin(), out.end());  // deterministic, whatever order the updates left
}

void trianglesWithEdge(const PaperSheet& s, std::uint32_t a, std::uint32_t b, std::vector<std::uint32_t>& out) {
    out.clear();
    for (std::uint32_t t : s.vertex_triangles[a]) {
        const auto& tri = s.triangles[t];
        if (tri[0] == b || tri[1] == b || tri[2] == b) out.push_back(t);
    }
    std::sort(out.begin(), out.end());
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
    if (s.v.size() != n || s.mass.size() != n || s.hold.size() != n || s.force.size() != n || s.x_pred.size() != n ||
        s.crack_tip.size() != n)
        return "per-vertex arrays differ in size";
    if (s.survived.size() != s.springs.size()) return "per-spring arrays differ in size";
    if (s.vertex_triangles.size() != n || s.vertex_springs.size() != n) return "adjacency lists differ in size";
    std::size_t listed = 0;
    for (std::uint32_t v = 0; v < n; ++v) {
        listed += s.vertex_triangles[v].size();
        for (std::uint32_t t : s.vertex_triangles[v]) {
            const auto& tri = s.triangles[t];
            if (tri[0] != v && tri[1] != v && tri[2] != v) return "adjacency: triangle listed at a vertex it does not use";
        }
    }
    if (listed != 3 * s.triangles.size()) return "adjacency: triangle lists incomplete";
    for (std::size_t k = 0; k < s.springs.size(); ++k)
        for (std::uint32_t name : {s.springs[k].a, s.springs[k].b}) {
            const auto& list = s.vertex_springs[name];
            if (std::find(list.begin(), list.end(), k) == list.end()) return "adjacency: spring not listed at its end";
        }
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
    if (a >= s.vertex_triangles.size()) return false;
    for (std::uint32_t index : s.vertex_triangles[a]) {
        const auto& t = s.triangles[index];
        const bool ha = t[0] == a || t[1] == a || t[2] == a;
        const bool hb = t[0] == b || t[1] == b || t[2] == b;
        const bool hc = t[0] == c || t[1] == c || t[2] == c;
        if (ha && hb && hc) return true;
    }
    return false;
}

bool hasEdge(const PaperSheet& s, std::uint32_t a, std::uint32_t b) {
    if (a >= s.vertex_triangles.size()) return false;
    for (std::uint32_t index : s.vertex_triangles[a]) {
        const auto& t = s.triangles[index];
        if (t[0] == b || t[1] == b || t[2] == b) return true;  // two corners of a triangle share an edge
    }
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
    std::vector<std::uint32_t> candidates = s.vertex_springs[vertex];
    if (twin != UINT32_MAX) candidates.insert(candidates.end(), s.vertex_springs[twin].begin(), s.vertex_springs[twin].end());
    std::sort(candidates.begin(), candidates.end());
    candidates.erase(std::unique(candidates.begin(), candidates.end()), candidates.end());
    for (std::uint32_t k : candidates) {
        PaperSpring& sp = s.springs[k];
        if (sp.broken || sp.kind == PaperSpringKind::Structural) continue;
        if (springHolds(s, sp)) continue;
        int chosen = -1;
        int slots[4];
        int count = 0;
        if (twin != UINT32_MAX) {
            // Try every renaming of `vertex` to `twin` among the four names (ends, span).
            for (int slot = 0; slot < 4; ++slot)
                if (*springSlot(sp, slot) == vertex) slots[count++] = slot;
            for (int mask = 1; mask < (1 << count) && chosen < 0; ++mask) {
                PaperSpring trial = sp;
                for (int i = 0; i < count; ++i) *springSlot(trial, slots[i]) = (mask >> i) & 1 ? twin : vertex;
                if (trial.a != trial.b && springHolds(s, trial)) chosen = mask;
            }
        }
        if (chosen < 0) {
            sp.broken = true;
            continue;
        }
        for (int i = 0; i < count; ++i)
            if ((chosen >> i) & 1) setSpringName(s, k, slots[i], twin);
    }
}

}  // namespace tearables::detail
