// Read-only reports of a world's strings for hosts: each string-body contact's force at the
// end of the last step (tearables/queries.hpp) and what holds a particle.
#include "tearables/queries.hpp"

#include "base/validate.hpp"
#include "string/strain_limit_internal.hpp"
#include "world/world_access.hpp"

#include <algorithm>

namespace tearables {

// The contacts are the ones the collision stage kept (StringState::contacts, linearised by
// the last solve); their gaps are read where the solve left the particles and the bodies
// (each contact's body node holds the body's displacement of the step), so the force is
// the one the solve balanced, not a new estimate.
void lastContactForces(const World& world, std::vector<ContactForce>& out) {
    out.clear();
    const detail::WorldParts parts = detail::WorldAccess::parts(const_cast<World&>(world));
    const std::vector<detail::StringState>& strings = *parts.strings;
    for (std::size_t i = 0; i < strings.size(); ++i) {
        const detail::StringState& s = strings[i];
        if (!s.alive || s.frozen) continue;
        for (const detail::RigidSegmentContact& c : s.contacts) {
            const std::size_t j = c.segment;
            // A segment torn in this step keeps the contact it carried in the solve.
            if (j >= s.segments() || !(c.stiffness > 0.0)) continue;
            const Vec3 xs = (1.0 - c.s) * s.x[j] + c.s * s.x[j + 1];
            const double force = c.stiffness * std::max(0.0, -detail::rigidGap(s, c, xs));
            if (!(force > 0.0)) continue;
            ContactForce f;
            f.string = StringId{static_cast<std::uint32_t>(i), s.generation};
            f.segment = c.segment;
            f.s = c.s;
            f.body = c.body;
            f.normal = c.plane_normal;
            f.point = xs - c.gap * c.plane_normal;
            f.normal_force = force;
            f.friction_force = detail::solvedFrictionForce(c, detail::rigidSlip(s, c, xs));
            out.push_back(f);
        }
    }
}

RigidId gluedBody(const World& world, StringId id, int particle) {
    const int p = world.resolveParticle(id, particle);
    const detail::WorldParts parts = detail::WorldAccess::parts(const_cast<World&>(world));
    const detail::ParticleHold& hold = (*parts.strings)[id.index].hold[static_cast<std::size_t>(p)];
    return hold.kind == detail::ParticleHold::Kind::Glue ? hold.body : RigidId{};
}

}  // namespace tearables
