// What holds a particle or vertex of any material: nothing, a pin or a body.
#pragma once

#include "tearables/world.hpp"

#include <algorithm>
#include <cstdint>
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

}  // namespace tearables::detail
