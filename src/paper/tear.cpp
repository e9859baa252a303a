// Paper sheets: tearing (beyond Paper).
//
// Stress measure (PaperDesc::tension, tension.cpp). Stretch, the default: the edge's
// relative stretch l/l0 - 1 at the end of the step, i.e. its spring force over k l0: for
// this implicitly integrated mass-spring model the spring force is the tension the solve
// balanced. Momentum: Yarn's momentum-balance least squares (the tensions that explain
// each free vertex's momentum change), compared as the equivalent stretch T / (k l0);
// it also sees what the truncated Jacobi solve really applied, at the cost of a sparse
// solve per step.
//
// Separation. An edge stretched past rupture_stretch opens a crack perpendicular to it: at
// an end on the sheet's boundary (or on an earlier cut), the fan of triangles around that
// vertex is cut along its inner edge most perpendicular to the stretched edge, and the
// vertex is duplicated (the copy: mass shared by area, velocity copied, the same hold).
// The cut edge's spring is duplicated; springs spanning the cut are renamed to the side
// where they still span an edge, or retired. A crack runs inward one vertex per step while
// the stress stays above rupture; each cut's far end is a crack tip, torn first, and at
// most one new crack starts per step. Held vertices are never split. An edge with both
// ends inside starts a slit there: its first free end is split along two of its fan
// edges, the ones pointing furthest either way across the stretched edge (an inner
// vertex's fan is closed, so one cut separates nothing), and the slit's two far ends are
// crack tips. One split per vertex and step.
#include "paper/sheet.hpp"

#include <algorithm>
#include <cmath>

namespace tearables::detail {

namespace {

/// The triangles of `fan` (all around `vertex`) connected to triangle `start` through
/// edges (vertex, x) with x != `cut` and x != `cut2`.
void fanComponent(const PaperSheet& s, const std::vector<std::uint32_t>& fan, std::uint32_t vertex, std::uint32_t cut,
                  std::uint32_t cut2, std::uint32_t start, std::vector<std::uint8_t>& in) {
    in.assign(fan.size(), 0);
    std::vector<std::size_t> stack;
    for (std::size_t i = 0; i < fan.size(); ++i)
        if (fan[i] == start) {
            in[i] = 1;
            stack.push_back(i);
        }
    while (!stack.empty()) {
        const std::size_t cur = stack.back();
        stack.pop_back();
        const auto& a = s.triangles[fan[cur]];
        for (std::size_t o = 0; o < fan.size(); ++o) {
            if (in[o]) continue;
            const auto& b = s.triangles[fan[o]];
            // Shared vertex other than `vertex` and `cut`.
            bool shared = false;
            for (std::uint32_t x : a)
                if (x != vertex && x != cut && x != cut2 && (b[0] == x || b[1] == x || b[2] == x)) shared = true;
            if (shared) {
                in[o] = 1;
                stack.push_back(o);
            }
        }
    }
}

bool onBoundary(const PaperSheet& s, std::uint32_t v, std::vector<std::uint32_t>& scratch) {
    trianglesOf(s, v, scratch);
    // An edge (v, x) used by a single triangle of the fan is a boundary edge.
    for (std::uint32_t t : scratch)
        for (std::uint32_t x : s.triangles[t]) {
            if (x == v) continue;
            int count = 0;
            for (std::uint32_t u : scratch) {
                const auto& o = s.triangles[u];
                if (o[0] == x || o[1] == x || o[2] == x) ++count;
            }
            if (count == 1) return true;
        }
    return false;
}

/// The event of a tear at edge k through vertex v; its stress is the edge's relative
/// stretch.
Event tearEvent(const PaperSheet& s, std::size_t k, std::uint32_t v, double stretch, const PaperStep& ctx) {
    Event e;
    e.type = EventType::Tear;
    e.cause = EventCause::Tension;
    e.object = s.desc.name;
    e.segment = static_cast<int>(k);
    e.particle = static_cast<int>(v);
    e.stress = stretch;
    e.time = ctx.time;
    e.step = ctx.step;
    return e;
}

}  // namespace

std::uint32_t splitVertex(PaperSheet& s, std::uint32_t vertex, std::uint32_t across, std::uint32_t across2) {
    if (across2 == across) return UINT32_MAX;
    std::vector<std::uint32_t> fan;
    trianglesOf(s, vertex, fan);
    // The two triangles of the cut edge; side B is the one that has vertex -> across
    // counter-clockwise.
    std::uint32_t side_a = UINT32_MAX, side_b = UINT32_MAX;
    for (std::uint32_t t : fan) {
        const auto& tri = s.triangles[t];
        for (int c = 0; c < 3; ++c) {
            if (tri[c] == vertex && tri[(c + 1) % 3] == across) side_b = t;
            if (tri[c] == across && tri[(c + 1) % 3] == vertex) side_a = t;
        }
    }
    if (side_a == UINT32_MAX || side_b == UINT32_MAX) return UINT32_MAX;
    if (across2 != UINT32_MAX) {  // the second cut must be an inner fan edge too
        int sides = 0;
        for (std::uint32_t t : fan) {
            const auto& tri = s.triangles[t];
            for (int c = 0; c < 3; ++c)
                sides += (tri[c] == vertex && tri[(c + 1) % 3] == across2) || (tri[c] == across2 && tri[(c + 1) % 3] == vertex);
        }
        if (sides != 2) return UINT32_MAX;
    }
    std::vector<std::uint8_t> in_b, in_a;
    fanComponent(s, fan, vertex, across, across2, side_b, in_b);
    fanComponent(s, fan, vertex, across, across2, side_a, in_a);
    for (std::size_t i = 0; i < fan.size(); ++i)
        if (in_a[i] && in_b[i]) return UINT32_MAX;  // a closed fan: the cut separates nothing
    double area_a = 0.0, area_b = 0.0;
    for (std::size_t i = 0; i < fan.size(); ++i) {
        const auto& t = s.triangles[fan[i]];
        const double area = 0.5 * (s.x[t[1]] - s.x[t[0]]).cross(s.x[t[2]] - s.x[t[0]]).norm();
        (in_b[i] ? area_b : area_a) += area;
    }
    const double fraction = area_a + area_b > 0.0 ? area_b / (area_a + area_b) : 0.5;
    const double mass_b = s.mass[vertex] * std::clamp(fraction, 0.1, 0.9);
    s.mass[vertex] -= mass_b;
    const std::uint32_t twin = addVertex(s, s.x[vertex], s.v[vertex], mass_b);
    s.hold[twin] = s.hold[vertex];
    s.x_pred[twin] = s.x_pred[vertex];
    for (std::size_t i = 0; i < fan.size(); ++i)
        if (in_b[i])
            for (int c = 0; c < 3; ++c)
                if (s.triangles[fan[i]][c] == vertex) setCorner(s, fan[i], c, twin);
    // Structural springs at the vertex follow their edge; a cut edge's is duplicated.
    const std::vector<std::uint32_t> at_vertex = s.vertex_springs[vertex];  // a copy: renames change the list
    for (const std::uint32_t k : at_vertex) {
        PaperSpring& sp = s.springs[k];
        if (sp.broken || sp.kind != PaperSpringKind::Structural) continue;
        if (sp.a != vertex && sp.b != vertex) continue;
        const std::uint32_t other = sp.a == vertex ? sp.b : sp.a;
        if (other == across || (across2 != UINT32_MAX && other == across2)) {
            const PaperSpring copy = sp;
            const std::uint32_t dup = addSpring(s, twin, other, copy.rest, copy.stiffness, PaperSpringKind::Structural);
            s.survived[dup] = s.survived[k];
            continue;
        }
        bool in_side_b = false;
        for (std::size_t i = 0; i < fan.size(); ++i) {
            const auto& t = s.triangles[fan[i]];
            if (in_b[i] && (t[0] == other || t[1] == other || t[2] == other)) in_side_b = true;
        }
        if (in_side_b) setSpringName(s, k, sp.a == vertex ? 0 : 1, twin);
    }
    revalidateSprings(s, vertex, twin);
    revalidateSprings(s, across, UINT32_MAX);
    if (across2 != UINT32_MAX) revalidateSprings(s, across2, UINT32_MAX);
    return twin;
}

void tear(PaperSheet& s, PaperId id, const PaperStep& ctx, std::vector<Event>& events) {
    if (!s.desc.tearable) return;
    std::vector<std::pair<double, std::uint32_t>> over;
    for (std::size_t k = 0; k < s.springs.size(); ++k) {
        const PaperSpring& sp = s.springs[k];
        if (sp.broken || sp.kind != PaperSpringKind::Structural) continue;
        // The stress measure: the edge's stretch, or its momentum-balance tension as the
        // stretch that would carry it (T / (k l0)).
        const double stretch = s.desc.tension == PaperTension::Momentum && k < s.tension.size()
                                   ? s.tension[k] / (sp.stiffness * sp.rest)
                                   : (s.x[sp.b] - s.x[sp.a]).norm() / sp.rest - 1.0;
        if (stretch > s.desc.rupture_stretch) over.emplace_back(stretch, static_cast<std::uint32_t>(k));
    }
    if (over.empty()) return;
    // Edges at a crack tip first (a crack runs on), then the most stretched; ties by
    // index (deterministic). At most kNewCracks new cracks start per step: under an even
    // load (a pulled edge) every boundary vertex would start one at once and the sheet
    // would be notched all along instead of torn.
    auto atTip = [&](std::uint32_t k) { return s.crack_tip[s.springs[k].a] || s.crack_tip[s.springs[k].b]; };
    std::sort(over.begin(), over.end(), [&](const auto& a, const auto& b) {
        const bool ta = atTip(a.second), tb = atTip(b.second);
        if (ta != tb) return ta;
        return a.first != b.first ? a.first > b.first : a.second < b.second;
    });
    constexpr int kNewCracks = 1;
    int started = 0;
    std::vector<std::uint8_t> touched(s.vertices(), 0);
    std::vector<std::uint32_t> scratch, fan;
    for (const auto& [stretch, k] : over) {
        const PaperSpring sp = s.springs[k];
        if (sp.broken || touched[sp.a] || touched[sp.b]) continue;
        const Vec3 dir = (s.x[sp.b] - s.x[sp.a]).normalized();
        const std::uint32_t first = s.crack_tip[sp.b] && !s.crack_tip[sp.a] ? sp.b : sp.a;
        for (std::uint32_t v : {first, first == sp.a ? sp.b : sp.a}) {
            if (!s.crack_tip[v] && started >= kNewCracks) continue;
            // A held vertex is not split: both halves would stay at the pin (or glue), and
            // the crack would open nothing. The crack starts next to it instead.
            if (s.hold[v].kind != ParticleHold::Kind::Free) continue;
            const bool inside = !onBoundary(s, v, scratch);
            trianglesOf(s, v, fan);
            if (inside) {
                // A slit through an inner vertex, across the stretched edge: cut the fan
                // edge that points furthest along t = n x dir and the one furthest along -t
                // (n the fan's normal), one each side of the edge; both far ends are tips.
                Vec3 normal = Vec3::Zero();
                for (std::uint32_t t : fan) {
                    const auto& tri = s.triangles[t];
                    normal += (s.x[tri[1]] - s.x[tri[0]]).cross(s.x[tri[2]] - s.x[tri[0]]);
                }
                const Vec3 across = normal.cross(dir);
                if (!(across.norm() > 0.0)) continue;
                std::uint32_t plus = UINT32_MAX, minus = UINT32_MAX;
                double most = -2.0, least = 2.0;
                for (std::uint32_t t : fan)
                    for (std::uint32_t w : s.triangles[t]) {
                        if (w == v) continue;
                        const Vec3 e = s.x[w] - s.x[v];
                        if (!(e.norm() > 0.0)) continue;
                        const double c = e.normalized().dot(across.normalized());
                        if (c > most + 1e-12 || (std::abs(c - most) <= 1e-12 && w < plus)) {
                            most = c;
                            plus = w;
                        }
                        if (c < least - 1e-12 || (std::abs(c - least) <= 1e-12 && w < minus)) {
                            least = c;
                            minus = w;
                        }
                    }
                if (plus == UINT32_MAX || minus == UINT32_MAX || plus == minus) continue;
                const std::uint32_t twin = splitVertex(s, v, plus, minus);
                if (twin == UINT32_MAX) continue;
                touched.resize(s.vertices(), 0);
                touched[v] = touched[twin] = touched[plus] = touched[minus] = 1;
                ++started;
                s.crack_tip[v] = s.crack_tip[twin] = 0;
                s.crack_tip[plus] = s.crack_tip[minus] = 1;
                ++s.counters.tears;
                events.push_back(tearEvent(s, k, v, stretch, ctx));
                break;
            }
            // The inner fan edge most perpendicular to the stretched edge.
            std::uint32_t best = UINT32_MAX;
            double best_sine = -1.0;
            for (std::uint32_t t : fan)
                for (std::uint32_t w : s.triangles[t]) {
                    if (w == v || w == best) continue;
                    int shared = 0;
                    for (std::uint32_t u : fan) {
                        const auto& o = s.triangles[u];
                        if (o[0] == w || o[1] == w || o[2] == w) ++shared;
                    }
                    if (shared != 2) continue;  // a boundary edge: nothing to cut
                    const Vec3 e = s.x[w] - s.x[v];
                    const double sine = e.norm() > 0.0 ? e.normalized().cross(dir).norm() : 0.0;
                    if (sine > best_sine + 1e-12 || (std::abs(sine - best_sine) <= 1e-12 && w < best)) {
                        best_sine = sine;
                        best = w;
                    }
                }
            if (best == UINT32_MAX) continue;
            const std::uint32_t twin = splitVertex(s, v, best);
            if (twin == UINT32_MAX) continue;
            touched.resize(s.vertices(), 0);
            touched[v] = touched[twin] = touched[best] = 1;
            if (!s.crack_tip[v]) ++started;
            s.crack_tip[v] = s.crack_tip[twin] = 0;  // both sides are open boundary now
            s.crack_tip[best] = 1;                    // the cut ends here
            ++s.counters.tears;
            events.push_back(tearEvent(s, k, v, stretch, ctx));
            break;
        }
    }
    (void)id;
}

}  // namespace tearables::detail
