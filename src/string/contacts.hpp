// The two kinds of string contact a step solves: a segment against a rigid body
// (contact_rows.cpp, strain_limit.cpp) and a segment against a segment of a string
// (string_pairs.cpp, cluster_solve.cpp), and the key that names such a pair.
#pragma once

#include "sim/rigid_table.hpp"
#include "tearables/types.hpp"

#include <cstdint>
#include <tuple>
#include <utility>

namespace tearables::detail {

/// A contact of one segment with a rigid body for this step (from RigidContact).
struct RigidSegmentContact {
    std::uint32_t segment = 0;
    double s = 0.0;              ///< fraction along the segment
    Vec3 normal = Vec3::UnitY(); ///< from the body toward the string (at collection; see local_normal)
    /// The normal in the body's frame: it turns with the body. Spherical: in the world's
    /// axes (a ball's surface under the string does not turn with it).
    Vec3 local_normal = Vec3::UnitY();
    /// The contact point in the body's frame (follows the body); spherical: its offset from
    /// the body's centre in the world's axes (follows the centre, does not turn); a world
    /// point without a body.
    Vec3 local = Vec3::Zero();
    bool spherical = false;      ///< RigidContact::spherical
    RigidId body;                ///< invalid: a fixed world point
    double gap = 0.0;            ///< required clearance along the normal, m (the radius for bodies)
    double friction = 0.5;
    int node = -1;               ///< index into body_nodes when the body is movable
    double depth = 0.0;          ///< penetration of the predicted position, m (>= 0)
    double start_depth = 0.0;    ///< penetration where the step started, m (>= 0)
    double stiffness = 0.0;      ///< penalty k_c used by the last solve, N/m
    bool active = false;         ///< held as an equality in the current pass
    /// Active only because the Newton step would run into it (an island's solve): its
    /// penalty's model carries its gap, positive now (assembleContactCoupling).
    bool predicted = false;
    double force = 0.0;          ///< normal force of the last solve, N (friction bound)
    // The plane, linearised where the solve starts (contact_rows.cpp, rigidGap): its point
    // and normal in the world, and d(gap)/d(rotation) of the body.
    Vec3 plane_point = Vec3::Zero();
    Vec3 plane_normal = Vec3::UnitY();
    Vec3 plane_turn = Vec3::Zero();
    Vec3 plane_arm = Vec3::Zero();    ///< plane_point minus the body's centre
    Vec3 start_point = Vec3::Zero();  ///< the body's contact point where the step started
    /// Friction's normal force N, lagged: the penalty force at the end of the last pass
    /// (0 in a step's first pass), N. In a string's own solve friction is mu N f0(|u_t|)
    /// (contact_rows.cpp).
    double friction_normal = 0.0;
    /// The N the last solve balanced (weighRigidFriction moves friction_normal on after
    /// each solve).
    double solved_normal = 0.0;
    /// Friction as a lagged quadratic w/2 |u_t|^2 (an island's members) rather than
    /// mu N f0(|u_t|) (a string's own solve): set by weighRigidFriction.
    bool lagged = false;
    double friction_weight = 0.0;     ///< the lagged form's weight mu F / max(slip, eps), N/m
    double solved_weight = 0.0;       ///< the weight the last solve balanced, N/m
    /// The segment touched this body, facing the same way, at the end of the last step:
    /// friction starts from that step's normal force (ContactMemory) in the first pass.
    bool remembered = false;
};

/// A string's contact with a body at the end of a step, for the next step's contact of
/// the same segment with the same body facing the same way (StringSystem::collideBodies):
/// friction's first pass takes the normal force N from the end of the last step, as IPC
/// lags it (Li et al. 2020, Sec. 5.2: lambda^n and T^n from the previous time step), so a
/// resting or sliding contact has Coulomb's friction from the step's first pass, and where
/// N has not changed the passes end after one.
struct ContactMemory {
    std::uint32_t segment = 0;
    double s = 0.0;               ///< where along the segment (0, 1: at its particles)
    RigidId body;
    Vec3 normal = Vec3::UnitY();  ///< the contact's normal in the body's frame
    double force = 0.0;           ///< its normal force at the end of the step, N

    /// Ordered by (segment, body): the entries of one segment and body are adjacent.
    friend bool operator<(const ContactMemory& a, const ContactMemory& b) {
        return std::tie(a.segment, a.body.index) < std::tie(b.segment, b.body.index);
    }
    /// A total order (ties of (segment, body) by normal): the same order from any sort.
    static bool before(const ContactMemory& a, const ContactMemory& b) {
        return std::make_tuple(a.segment, a.body.index, a.normal.x(), a.normal.y(), a.normal.z()) <
               std::make_tuple(b.segment, b.body.index, b.normal.x(), b.normal.y(), b.normal.z());
    }
};

/// One pair of segments, named from one side: segment `segment` of string `string` against
/// segment `partner_segment` of string `partner` (may be the same string). Ordered by
/// (string, segment, partner, partner_segment).
struct PairKey {
    std::uint32_t string = 0;
    std::uint32_t segment = 0;
    std::uint32_t partner = 0;
    std::uint32_t partner_segment = 0;

    /// The same pair named from the side with the lower (string, segment): one key for
    /// both namings.
    PairKey unordered() const {
        if (std::make_pair(partner, partner_segment) < std::make_pair(string, segment))
            return {partner, partner_segment, string, segment};
        return *this;
    }
    friend bool operator<(const PairKey& a, const PairKey& b) {
        return std::tie(a.string, a.segment, a.partner, a.partner_segment) <
               std::tie(b.string, b.segment, b.partner, b.partner_segment);
    }
    friend bool operator==(const PairKey& a, const PairKey& b) {
        return a.string == b.string && a.segment == b.segment && a.partner == b.partner &&
               a.partner_segment == b.partner_segment;
    }
};

/// A string-string contact (string_pairs.cpp, cluster_solve.cpp): this side is segment
/// `segment` at `s` of string `string`, the other side segment `partner_segment` at
/// `partner_s` of string `partner`. `normal` points from the other side toward this one,
/// `gap` is the axis distance to keep (the sum of the radii).
struct StringPairContact {
    std::uint32_t string = 0;
    std::uint32_t segment = 0;
    std::uint32_t partner = 0;
    std::uint32_t partner_segment = 0;
    double s = 0.0;                     ///< fraction along this side's segment
    double partner_s = 0.0;             ///< fraction along the other side's segment
    Vec3 normal = Vec3::UnitY();
    double gap = 0.0;                   ///< m
    double friction = 0.5;
    Vec3 start_normal = Vec3::UnitX();  ///< the normal at the start of the step
    double start_distance = 0.0;        ///< the axes' distance at the start of the step, m
    double stiffness = 0.0;             ///< penalty k_c used by the last solve, N/m
    bool active = false;                ///< held as an equality in the current pass
    double force = 0.0;                 ///< normal force of the last solve, N (friction bound, warm start)

    PairKey key() const { return {string, segment, partner, partner_segment}; }
};

}  // namespace tearables::detail
