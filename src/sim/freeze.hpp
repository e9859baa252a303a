// An object whose state went non-finite (a diverged solve, a host's bad input) stops being
// simulated, every material alike: its velocities are zero, it is flagged frozen, and a
// Freeze event (cause NonFinite) names it. Where its positions stay is the material's.
#pragma once

#include "sim/step_context.hpp"
#include "tearables/events.hpp"

#include <string>
#include <vector>

namespace tearables::detail {

/// Stops an object (velocities `v`, flag `frozen`) and returns its Freeze event, stamped
/// with this step; the caller places its positions, names its id and reports the event.
inline Event freezeNonFinite(std::vector<Vec3>& v, bool& frozen, const std::string& object, const StepContext& ctx) {
    for (Vec3& velocity : v) velocity.setZero();
    frozen = true;
    Event e;
    e.type = EventType::Freeze;
    e.cause = EventCause::NonFinite;
    e.object = object;
    e.time = ctx.time;
    e.step = ctx.step;
    return e;
}

}  // namespace tearables::detail
