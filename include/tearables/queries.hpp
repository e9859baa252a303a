// tearables: queries on a world's strings (ray tests, contact forces, holds), read-only.
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

/// A string's contact with a rigid body in the last step and the force it carried: the
/// strain-limit solve's penalty k_c max(0, -g) at the gap g where the solve stopped (its
/// Lagrange multiplier: the solve minimises inertia + springs + k_c g^2 / 2, so at its
/// minimum the penalty's gradient is the contact's normal force), and the lagged Coulomb
/// friction -w u_t (w = mu F / max(|u_t|, eps), contact_rows.cpp: the weight of the last
/// solve) on the slip u_t.
struct ContactForce {
    StringId string;                     ///< the string
    std::uint32_t segment = 0;           ///< its segment
    double s = 0.0;                      ///< fraction along the segment, [0, 1] (0 = its first particle)
    RigidId body;                        ///< the body's proxy
    Vec3 point = Vec3::Zero();           ///< world, m: the string's surface point facing the body
    Vec3 normal = Vec3::UnitY();         ///< unit, from the body toward the string
    double normal_force = 0.0;           ///< N, > 0
    Vec3 friction_force = Vec3::Zero();  ///< N, on the string, tangent to the body
};

/// Replaces `out` with the last step's string-body contacts that pressed (normal force
/// > 0), by string slot, then in the order the host reported them. Valid until the next
/// step or change (as the views).
void lastContactForces(const World& world, std::vector<ContactForce>& out);

/// The body a string's particle is glued to (negative counts from the end), or an invalid
/// id when it is free or pinned to a world point. Throws InvalidInput ("string", "particle").
RigidId gluedBody(const World& world, StringId id, int particle);

/// A string's twist and writhe, in turns (link = twist + writhe is what a rod whose end
/// tangents are held keeps as it coils; tearables/queries.hpp, src/string/link.cpp).
struct LinkMeasure {
    double twist = 0.0;   ///< sum over intact joints of the material frame's turn (theta_{k+1} - theta_k) / 2 pi
    double writhe = 0.0;  ///< the Gauss double integral of the centreline over pairs of intact segments / 4 pi
};
/// Twist and writhe of a string as it is now: the writhe summed exactly over pairs of
/// non-adjacent intact segments (Klenin and Langowski 2000, method 1a; O(segments^2)), of
/// the open centreline (no closure: an open curve's writhe is not an integer). Throws
/// InvalidInput ("string") for an unknown id.
LinkMeasure linkMeasure(const World& world, StringId id);
/// The writhe of the polyline through `points` (turns), by the same sum over pairs of
/// non-adjacent segments: for a rod measured with straight tails added along its held
/// ends, whose writhe with the twist makes its link.
double polylineWrithe(const std::vector<Vec3>& points);

}  // namespace tearables
