// The velocities of a string's particles, set from outside (tearables/controls.hpp).
#include "tearables/controls.hpp"

#include "world/world_access.hpp"

#include <string>

namespace tearables {

void setVelocities(World& world, StringId id, const std::vector<Vec3>& velocities) {
    (void)world.desc(id);  // InvalidInput("string"), a stale id named as such
    detail::StringState& s = (*detail::WorldAccess::parts(world).strings)[id.index];
    const std::size_t n = s.particles();
    if (velocities.size() != 1 && velocities.size() != n)
        throw InvalidInput("velocities", "needs one velocity or one per particle (" + std::to_string(n) + "), got " +
                                             std::to_string(velocities.size()));
    const double max_speed = world.settings().max_speed;
    for (std::size_t i = 0; i < velocities.size(); ++i) {
        const std::string field = "velocities[" + std::to_string(i) + "]";
        if (!velocities[i].allFinite()) throw InvalidInput(field, "must be finite");
        if (velocities[i].norm() > max_speed)
            throw InvalidInput(field, "faster than WorldSettings::max_speed (" + std::to_string(max_speed) + " m/s)");
    }
    for (std::size_t p = 0; p < n; ++p) {
        if (s.hold[p].kind != detail::ParticleHold::Kind::Free) continue;
        s.v[p] = velocities.size() == 1 ? velocities[0] : velocities[p];
        s.v_prev[p] = s.v[p];  // a uniform history: BDF2 starts from it
    }
}

}  // namespace tearables
