// Paper sheets: breakable hinge springs (Paper Sec. III.B-C).
//
// A compressed structural spring (l < l0) breaks with probability P = (1 - l/l0)^phi
// (Eq. 7). The paper does not say how often P is drawn; drawn every step, a spring held at
// one compression would break given time, at a rate set by the time step. We draw only
// against the increase: a spring that survived compression c_s and is now at c > c_s
// breaks with probability (c^phi - c_s^phi) / (1 - c_s^phi), so it has broken by c with
// probability exactly c^phi, in any number of steps.
//
// Breaking inserts a mass point at the spring's middle (a quarter of each end's mass),
// lifted along the normal by h = psi/2 sqrt(l0^2 - l^2) (Eq. 8): psi = 1 leaves the halves
// (rest l0/2) at rest, smaller psi compressed (bank notes), larger stretched (card board).
// The lift goes to the side the edge already bulges to, else a side drawn with the sheet's
// generator. The edge's triangles are split at the new point, an unbreakable auxiliary
// spring between the old ends keeps the crease (Fig. 3-4), and the bending springs that no
// longer span an edge are retired: the crease bends freely.
//
// Hinges (Fig. 5): a bending spring whose vertices come closer than hinge_threshold times
// their rest distance is replaced by an unbreakable hinge spring at the folded distance.
#include "paper/sheet.hpp"

#include <algorithm>
#include <cmath>

namespace tearables::detail {

bool drawBreak(double ratio, double survived, double phi, std::mt19937_64& rng) {
    const double c = std::clamp(1.0 - ratio, 0.0, 1.0);
    if (!(c > survived)) return false;
    const double before = survived > 0.0 ? std::pow(survived, phi) : 0.0;
    const double now = std::pow(c, phi);
    const double p = before >= 1.0 ? 1.0 : (now - before) / (1.0 - before);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    return u(rng) < p;
}

double creaseLift(double rest, double length, double psi) {
    return 0.5 * psi * std::sqrt(std::max(0.0, rest * rest - length * length));
}

std::uint32_t breakSpring(PaperSheet& s, std::uint32_t index) {
    PaperSpring& sp = s.springs[index];
    if (sp.broken || sp.kind != PaperSpringKind::Structural) return UINT32_MAX;
    const std::uint32_t i = sp.a, j = sp.b;
    std::vector<std::uint32_t> tris;
    trianglesWithEdge(s, i, j, tris);
    if (tris.empty() || tris.size() > 2) return UINT32_MAX;
    const double rest = sp.rest, k = sp.stiffness;
    const double length = (s.x[j] - s.x[i]).norm();
    Vec3 normal = Vec3::Zero();
    Vec3 opposite = Vec3::Zero();
    for (std::uint32_t t : tris) {
        normal += triangleNormal(s, s.triangles[t]);
        opposite += s.x[thirdVertex(s.triangles[t], i, j)];
    }
    opposite /= static_cast<double>(tris.size());
    if (!(normal.norm() > 1e-12)) normal = (s.x[j] - s.x[i]).unitOrthogonal();
    normal.normalize();
    const Vec3 mid = 0.5 * (s.x[i] + s.x[j]);
    const double bulge = normal.dot(mid - opposite);
    double side;
    if (std::abs(bulge) > 1e-6 * rest) {
        side = bulge > 0.0 ? 1.0 : -1.0;
    } else {
        std::uniform_int_distribution<int> coin(0, 1);
        side = coin(s.rng) ? 1.0 : -1.0;
    }
    const double lift = creaseLift(rest, length, s.desc.psi);
    const double share = 0.25 * (s.mass[i] + s.mass[j]);
    s.mass[i] *= 0.75;
    s.mass[j] *= 0.75;
    const std::uint32_t m = addVertex(s, mid + side * lift * normal, 0.5 * (s.v[i] + s.v[j]), share);
    // `sp` may dangle after addSpring (the vector grows): use the index from here on.
    s.springs[index].broken = true;
    for (std::uint32_t t : tris) {
        std::array<std::uint32_t, 3> second = s.triangles[t];
        for (int c = 0; c < 3; ++c)
            if (second[c] == i) second[c] = m;  // (m, j, o)
        for (int c = 0; c < 3; ++c)
            if (s.triangles[t][c] == j) setCorner(s, t, c, m);  // (i, m, o): keeps the orientation
        const std::uint32_t o = thirdVertex(s.triangles[t], i, m);
        addTriangle(s, second);
        addSpring(s, m, o, (s.x[o] - s.x[m]).norm(), k, PaperSpringKind::Structural);
    }
    addSpring(s, i, m, 0.5 * rest, k, PaperSpringKind::Structural);
    addSpring(s, m, j, 0.5 * rest, k, PaperSpringKind::Structural);
    const std::uint32_t aux = addSpring(s, i, j, std::max(length, 1e-6 * rest), k, PaperSpringKind::Auxiliary);
    setSpringName(s, aux, 2, m);
    revalidateSprings(s, i, UINT32_MAX);
    revalidateSprings(s, j, UINT32_MAX);
    return m;
}

void creaseAndFold(PaperSheet& s, PaperId id, const PaperStep& ctx, std::vector<Event>& events) {
    if (!s.desc.breakable) return;
    const std::size_t count = s.springs.size();  // springs made in this stage wait for the next step
    const std::size_t vertices = s.vertices();
    for (std::size_t k = 0; k < count; ++k) {
        const PaperSpring sp = s.springs[k];
        if (sp.broken) continue;
        if (sp.a >= vertices || sp.b >= vertices) continue;  // touches a vertex made in this stage
        const double length = (s.x[sp.b] - s.x[sp.a]).norm();
        if (sp.kind == PaperSpringKind::Structural) {
            const double ratio = length / sp.rest;
            if (ratio >= 1.0) continue;
            const bool breaks = drawBreak(ratio, s.survived[k], s.desc.phi, s.rng);
            s.survived[k] = std::max(s.survived[k], 1.0 - ratio);
            if (!breaks) continue;
            const std::uint32_t m = breakSpring(s, static_cast<std::uint32_t>(k));
            if (m == UINT32_MAX) continue;
            ++s.counters.creases;
            Event e;
            e.type = EventType::Crease;
            e.cause = EventCause::Compression;
            e.object = s.desc.name;
            e.segment = static_cast<int>(k);
            e.particle = static_cast<int>(m);
            e.stress = 1.0 - ratio;  // the compression it broke at
            e.time = ctx.time;
            e.step = ctx.step;
            events.push_back(e);
        } else if (sp.kind == PaperSpringKind::Bending) {
            if (!(length < s.desc.hinge_threshold * sp.rest)) continue;
            s.springs[k].broken = true;
            const std::uint32_t hinge = addSpring(s, sp.a, sp.b, std::max(length, 1e-6 * sp.rest), s.desc.stiffness, PaperSpringKind::Hinge);
            setSpringName(s, hinge, 2, sp.hinge[0]);
            setSpringName(s, hinge, 3, sp.hinge[1]);
            ++s.counters.hinges;
            Event e;
            e.type = EventType::Hinge;
            e.cause = EventCause::Compression;
            e.object = s.desc.name;
            e.segment = static_cast<int>(hinge);
            e.stress = length / sp.rest;
            e.time = ctx.time;
            e.step = ctx.step;
            events.push_back(e);
        }
    }
}

}  // namespace tearables::detail
