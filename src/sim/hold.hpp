// What holds a particle or vertex of any material: nothing, a pin or a body.
#pragma once

#include "tearables/world.hpp"

#include <cstdint>

namespace tearables::detail {

/// What holds a particle.
struct ParticleHold {
    enum class Kind : std::uint8_t { Free, Pin, Glue };
    Kind kind = Kind::Free;
    Vec3 point = Vec3::Zero();  ///< Pin: world target, m; Glue: point in the body frame, m
    RigidId body;               ///< Glue: the body
};

}  // namespace tearables::detail
