// Stage: material response of the yarns to their least-squares tension (Yarn Sec. 3.3-3.4),
// with the strings' tensile curve (sim/material_curve.hpp).
//  - Stress sigma = max(0, T) / (pi r^2) (Sec. 3.2: engineering stress, no compression);
//    L_max = L_rest (1 + sigma / E) (Sec. 3.3) is met by the strain-limit solve, reported.
//  - Yield (Sec. 3.4): the peak stress sets eps_perm = eps_curve(peak) - peak / E and the
//    rest length grows to L0 (1 + eps_perm); a Yield event the first time.
//  - Strain rate (Sec. 3.4, "the more time is taken to break a yarn, the less vigorous the
//    breakage"): with plastic_time tau > 0 the rest length approaches its target as
//    L += (L_target - L) (1 - exp(-h / tau)): a slow pull lengthens the yarn plastically
//    and spreads the load, a fast one ruptures it with the rest length lagging. tau = 0
//    follows the curve at once, as strings do; the update is explicit, so rate independent
//    only while a step adds little stress against rupture - yield (tests/cloth).
//  - Rupture: a tearable yarn whose stress reaches rupture breaks: the edge goes (its
//    vertices stay) with the soft springs that depend on it, and a Tear event is emitted.
//    Only the most overloaded yarn per cloth and step breaks; the next step's tensions say
//    whether its neighbours follow (Yarn: "tears where the stress is highest").
#include "base/constants.hpp"
#include "cloth/cloth_state.hpp"
#include "sim/material_curve.hpp"

#include <algorithm>
#include <cmath>

namespace tearables::detail {

void respondClothMaterial(ClothState& c, const StepContext& ctx, std::vector<Event>& events) {
    const double area = kPi * c.desc.yarn_radius * c.desc.yarn_radius;
    const double flow = c.desc.plastic_time > 0.0 ? 1.0 - std::exp(-ctx.h / c.desc.plastic_time) : 1.0;
    int worst = -1;
    double worst_ratio = 0.0, worst_stress = 0.0;
    auto event = [&](EventType type, int edge, double stress) {
        Event e;
        e.type = type;
        e.cause = EventCause::Tension;
        e.object = c.desc.name;
        e.segment = edge;
        e.stress = stress;
        e.time = ctx.time;
        e.step = ctx.step;
        events.push_back(e);
    };
    for (std::size_t e = 0; e < c.edgeCount(); ++e) {
        if (c.broken[e]) continue;
        const SegmentMaterial& mat = c.material[e];
        const double stress = std::max(0.0, c.tension[e]) / area;
        if (c.desc.tearable && stress >= mat.rupture) {
            const double ratio = stress / mat.rupture;
            if (ratio > worst_ratio) {
                worst_ratio = ratio;
                worst = static_cast<int>(e);
                worst_stress = stress;
            }
            continue;
        }
        if (stress > mat.yield) {
            if (!c.yielded[e]) {
                c.yielded[e] = 1;
                event(EventType::Yield, static_cast<int>(e), stress);
            }
            c.peak_stress[e] = std::max(c.peak_stress[e], std::min(stress, mat.rupture));
        }
        if (c.yielded[e]) {
            const double target = c.original_length[e] * (1.0 + permanentStrain(mat, c.peak_stress[e]));
            if (target > c.rest_length[e]) {
                c.rest_length[e] += (target - c.rest_length[e]) * flow;
                c.stiffness[e] = mat.young * area / c.rest_length[e];
            }
        }
        c.max_length[e] = c.rest_length[e] * (1.0 + stress / mat.young);
    }
    if (worst >= 0) {
        c.broken[worst] = 1;
        c.tension[worst] = 0.0;
        for (std::uint32_t s : c.edge_springs[worst]) c.springs[s].alive = false;
        ++c.topology;
        event(EventType::Tear, worst, worst_stress);
    }
}

void applyClothFriction(ClothState& c, RigidTable& rigids, const StepContext& ctx) {
    // Coulomb friction per contact at the velocity level, after the velocities are known
    // (it is not yarn tension, and a position correction after the strain limit would
    // stretch the inextensible yarns, which the next step's solve would yank back: energy
    // pumped into a box resting on the cloth). The vertex's tangential velocity relative
    // to the body's surface point is reduced by at most mu F_n h / m; the body gets the
    // opposite impulse (linear and angular).
    for (const VertexContact& vc : c.contacts) {
        if (!(vc.force > 0.0) || c.hold[vc.vertex].kind != ParticleHold::Kind::Free) continue;
        RigidState& b = rigids.bodies[vc.body.index];
        const std::size_t i = vc.body.index;
        const Vec3 now = b.position + b.orientation * vc.local;
        const Vec3 before = rigids.start_position[i] + rigids.start_orientation[i] * vc.local;
        const std::size_t p = vc.vertex;
        Vec3 slip = c.v[p] - (now - before) * ctx.inv_h;
        slip -= vc.normal * vc.normal.dot(slip);
        const double len = slip.norm();
        if (!(len > 0.0)) continue;
        const double reach = vc.friction * vc.force * ctx.h / c.mass[p];
        const Vec3 dv = -slip * std::min(1.0, reach / len);
        c.v[p] += dv;
        if (rigids.movable(vc.body)) {
            const Vec3 impulse = -c.mass[p] * dv;  // N s
            b.linear_velocity += b.inverse_mass * impulse;
            b.angular_velocity += b.inverseInertiaWorld() * (now - b.position).cross(impulse);
            b.impulse += impulse;
        }
    }
}

}  // namespace tearables::detail
