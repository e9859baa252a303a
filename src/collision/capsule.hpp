// Closest points of two line segments, the narrow phase of the string-string capsule test
// (Strings, Sec. 6: every segment is a capsule; two capsules overlap when the distance
// between their axes is below the sum of their radii).
#pragma once

#include "tearables/types.hpp"

namespace tearables::detail {

/// The closest points p = p0 + s (p1 - p0) and q = q0 + t (q1 - q0) of two segments, with
/// s, t in [0, 1], and distance = |p - q|. When the closest points are not unique
/// (parallel segments that overlap along their common direction) the pair in the middle
/// of the overlap is returned, so that a contact response pushes both segments evenly.
struct SegmentClosest {
    double s = 0.0;         ///< fraction along the first segment (0 at p0, 1 at p1)
    double t = 0.0;         ///< fraction along the second segment (0 at q0, 1 at q1)
    Vec3 p = Vec3::Zero();  ///< closest point on the first segment
    Vec3 q = Vec3::Zero();  ///< closest point on the second segment
    double distance = 0.0;  ///< |p - q|
};

/// Closest points of the segments [p0, p1] and [q0, q1] (Ericson, Real-Time Collision
/// Detection, Sec. 5.1.9, with a relative parallel test and a midpoint rule for parallel
/// overlaps). Robust for parallel, anti-parallel, collinear and zero-length segments; never
/// divides by zero and never returns NaN for finite input. Deterministic: the same
/// arguments always give bit-identical results. The cost is a few dozen flops, no branches
/// on data beyond the clamping.
SegmentClosest closestPointsOfSegments(const Vec3& p0, const Vec3& p1, const Vec3& q0, const Vec3& q1);

}  // namespace tearables::detail
