// tearables: queries on a world's strings (ray tests), read-only.
#pragma once

#include "tearables/world.hpp"

#include <optional>

namespace tearables {

/// Where a ray met a string.
struct RayHit {
    StringId string;       ///< the string hit
    int segment = -1;      ///< its segment
    double along = 0.0;    ///< fraction along the segment of the hit's axis point, [0, 1]
    double fraction = 0.0; ///< fraction along the ray, [0, 1]
    Vec3 point = Vec3::Zero();   ///< on the capsule's surface, m
    Vec3 normal = Vec3::UnitY(); ///< the surface normal there
};

/// The first string capsule the ray from `from` to `to` meets (broken segments are
/// skipped), or nothing. O(segments); for games that shoot or cut ropes.
std::optional<RayHit> rayTest(const World& world, const Vec3& from, const Vec3& to);

/// Ray against one capsule (axis a-b, radius r): the entry fraction along the ray in
/// [0, 1] and the axis fraction of the hit, or nothing. A ray starting inside hits at 0.
std::optional<std::pair<double, double>> rayCapsule(const Vec3& from, const Vec3& to, const Vec3& a, const Vec3& b, double r);

}  // namespace tearables
