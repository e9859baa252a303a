// tearables: events, read after a step (never callbacks from inside it).
#pragma once

#include "tearables/ids.hpp"

#include <cstdint>
#include <string>

namespace tearables {

/// What happened.
enum class EventType {
    Tear,      ///< a segment broke
    Yield,     ///< a segment passed its yield point for the first time
    Release,   ///< an attachment was removed (by request, or because its body left the world)
    Freeze,    ///< an object reached a non-finite state and was frozen; the rest goes on
    Crease,    ///< (paper) a spring broke under compression
    Hinge,     ///< (paper) a hinge spring was inserted
    Overlap,   ///< a string made overlapping a body is being pushed out of it (once per string and body)
};

/// Why it happened.
enum class EventCause {
    None,
    Tension,
    Torsion,
    Compression,
    Request,       ///< the user asked (release driver, detach call)
    BodyRemoved,   ///< the attached rigid body left the Bullet world
    NonFinite,     ///< NaN or infinity appeared
};

/// One event of a step.
struct Event {
    EventType type = EventType::Tear;
    EventCause cause = EventCause::None;
    StringId string;        ///< the object
    std::string object;     ///< its name
    int segment = -1;       ///< segment index, or -1
    int particle = -1;      ///< particle index, or -1
    double stress = 0.0;    ///< Pa (tension) or torsional strain (torsion), where it applies
    double time = 0.0;      ///< simulated time at the end of the step, s
    std::int64_t step = 0;  ///< step number (1 = the first step)
    RigidId rigid;          ///< Overlap: the body the string was made inside (its core id); else invalid
    double depth = 0.0;     ///< Overlap: the deepest overlap at the step's start, m; else 0
};

/// "tear", "yield", "release", "freeze", "crease", "hinge", "overlap".
const char* toString(EventType type);
/// "none", "tension", "torsion", "compression", "request", "body_removed", "non_finite".
const char* toString(EventCause cause);

}  // namespace tearables
