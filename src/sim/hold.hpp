// What holds a particle or vertex of any material: nothing, a pin or a body.
#pragma once

#include "tearables/events.hpp"
#include "tearables/world.hpp"

#include <algorithm>
#include <cstdint>
#include <string>
#include <vector>

namespace tearables::detail {

/// What holds a particle.
struct ParticleHold {
    enum class Kind : std::uint8_t { Free, Pin, Glue };
    Kind kind = Kind::Free;
    Vec3 point = Vec3::Zero();  ///< Pin: world target, m; Glue: point in the body frame, m
    RigidId body;               ///< Glue: the body

    bool gluedTo(RigidId b) const { return kind == Kind::Glue && body == b; }
};

/// Whether any of `holds` glues its particle to `body`.
inline bool holdsBody(const std::vector<ParticleHold>& holds, RigidId body) {
    return std::any_of(holds.begin(), holds.end(), [body](const ParticleHold& h) { return h.gluedTo(body); });
}

/// Frees hold `i` of the object named `object` and appends its Release event; a free hold
/// is left as it is. Returns whether it appended the event.
inline bool releaseHold(std::vector<ParticleHold>& holds, std::size_t i, const std::string& object, EventCause cause,
                        double time, std::int64_t step, std::vector<Event>& out) {
    if (holds[i].kind == ParticleHold::Kind::Free) return false;
    holds[i] = ParticleHold{};
    Event e;
    e.type = EventType::Release;
    e.cause = cause;
    e.object = object;
    e.particle = static_cast<int>(i);
    e.time = time;
    e.step = step;
    out.push_back(e);
    return true;
}

}  // namespace tearables::detail
