// The host's narrow phase as the materials' collision stages ask it. World builds it from
// its ContactProvider each step; a host that throws gives no contacts that step.
#pragma once

#include "tearables/world.hpp"

#include <functional>
#include <vector>

namespace tearables::detail {

/// Finds the contacts of a PointQuery (mesh vertices, sheets' triangles) with rigid bodies.
using PointContactFinder = std::function<void(const PointQuery&, std::vector<PointContact>&)>;
/// Finds the contacts of a CollisionQuery (strings' swept segments) with rigid bodies.
using SegmentContactFinder = std::function<void(const CollisionQuery&, std::vector<RigidContact>&)>;

struct HostContacts {
    /// Strings' segments; empty without a host or with rigid contacts off. Unchecked: the
    /// string system drops what does not name a live segment and body.
    SegmentContactFinder segments;
    /// Mesh vertices; the answers are checked (World::Impl::findPointContacts).
    PointContactFinder points;
};

}  // namespace tearables::detail
