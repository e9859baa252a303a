// The rigid bodies the materials hold and touch, as the host hands them over.
#pragma once

#include "tearables/world.hpp"

#include <cstdint>
#include <vector>

namespace tearables::detail {

/// Table of rigid proxies; slots are reused, `present` false = empty.
struct RigidTable {
    std::vector<RigidState> bodies;
    std::vector<std::uint8_t> used;
    // per-step bookkeeping
    std::vector<Vec3> start_position;
    std::vector<Quat> start_orientation;
    /// 1 for a body added since the last step: what it overlaps where the step starts, it
    /// was placed onto, an overlap the step did not make (pushed out gently, as a string
    /// made inside a body is).
    std::vector<std::uint8_t> fresh;
    bool isFresh(RigidId id) const { return id.valid() && id.index < fresh.size() && fresh[id.index]; }
    /// Whether `id` names a body of the table that the host has not removed.
    bool holds(RigidId id) const {
        return id.valid() && id.index < bodies.size() && used[id.index] && bodies[id.index].present;
    }
    bool movable(RigidId id) const {
        const RigidState& b = bodies[id.index];
        return b.present && b.awake && b.inverse_mass > 0.0;
    }
};

/// World position of a glued particle.
inline Vec3 gluePoint(const RigidState& body, const Vec3& local) {
    return body.position + body.orientation * local;
}

}  // namespace tearables::detail
