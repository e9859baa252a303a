#include "tearables/events.hpp"

namespace tearables {

const char* toString(EventType type) {
    switch (type) {
        case EventType::Tear: return "tear";
        case EventType::Yield: return "yield";
        case EventType::Release: return "release";
        case EventType::Freeze: return "freeze";
        case EventType::Crease: return "crease";
        case EventType::Hinge: return "hinge";
        case EventType::Overlap: return "overlap";
    }
    return "unknown";
}

const char* toString(EventCause cause) {
    switch (cause) {
        case EventCause::None: return "none";
        case EventCause::Tension: return "tension";
        case EventCause::Torsion: return "torsion";
        case EventCause::Compression: return "compression";
        case EventCause::Request: return "request";
        case EventCause::BodyRemoved: return "body_removed";
        case EventCause::NonFinite: return "non_finite";
    }
    return "unknown";
}

}  // namespace tearables
