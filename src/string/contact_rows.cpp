// The rows of a string's contacts with rigid bodies in its Newton system: a stiff
// one-sided penalty k_c min(0, g)^2 / 2 on the gap g to the body's surface plane,
// linearised in the body's motion, and lagged Coulomb friction w/2 |u_t|^2 on the slip
// (IPC, Li et al. 2020), with their gradients in the string's particles and in the body's
// six unknowns.
#include "string/strain_limit_internal.hpp"

#include <algorithm>
#include <cmath>

namespace tearables::detail {

namespace {

/// Where a contact's surface point is now: on its body (following it), or a fixed world
/// point where it has none.
Vec3 contactPoint(const RigidSegmentContact& c, const RigidTable& rigids) {
    return c.body.valid() ? gluePoint(rigids.bodies[c.body.index], c.local) : c.local;
}

/// A rigid contact's normal now: it turns with its body. The contact is the body's
/// surface plane at the contact point (point and normal fixed in the body), so that a
/// body that rolls on a rope does not lift off it (a normal fixed in the world lets a box
/// lower its penalty energy by spinning about the rope, and slip through it).
Vec3 contactNormal(const RigidSegmentContact& c, const RigidTable& rigids) {
    return c.body.valid() ? Vec3(rigids.bodies[c.body.index].orientation * c.local_normal) : c.normal;
}

/// How far contact c's movable body has moved since its planes were linearised, plus
/// `extra` (a trial step) when given.
Vec6 bodyMotion(const StringState& s, const RigidSegmentContact& c, const Vec6* extra) {
    const BodyNode& node = s.body_nodes[static_cast<std::size_t>(c.node)];
    Vec6 u = node.displacement - node.linearised_at;
    if (extra) u += *extra;
    return u;
}

}  // namespace

/// A contact is the body's surface plane through p with normal n, both fixed in the body;
/// for the body's displacement (u, theta) from here its gap is, to first order,
///     g = n . (x(s) - p) - r  -  n . u  +  theta . (n x (p - c))
/// (c the body's centre): the rigid-body contact Jacobian, as Bullet's own solver uses
/// it. The term theta . (n x (x(s) - p)) is dropped: it vanishes while the string lies
/// along the normal from p, and it would make the energy nonconvex. Without it the solve
/// minimises a convex energy (inertia, the springs, penalties on linear gaps), so Newton
/// with a line search converges from any start. The plane's second-order motion is met
/// by the next step's contacts, found at the new pose.
void linearisePlanes(StringState& s, const RigidTable& rigids) {
    for (RigidSegmentContact& c : s.contacts) {
        c.plane_point = contactPoint(c, rigids);
        c.plane_normal = contactNormal(c, rigids);
        c.plane_turn.setZero();
        c.plane_arm.setZero();
        c.start_point = c.plane_point;
        if (!c.body.valid()) continue;
        const std::size_t b = c.body.index;
        c.start_point = rigids.start_position[b] + rigids.start_orientation[b] * c.local;
        if (c.node < 0) continue;
        c.plane_arm = c.plane_point - rigids.bodies[b].position;
        c.plane_turn = c.plane_normal.cross(c.plane_arm);
    }
    for (BodyNode& node : s.body_nodes) node.linearised_at = node.displacement;
}

double rigidGap(const StringState& s, const RigidSegmentContact& c, const Vec3& xs, const Vec6* extra) {
    double g = c.plane_normal.dot(xs - c.plane_point) - c.gap;
    if (c.node >= 0) {
        const Vec6 u = bodyMotion(s, c, extra);
        g += c.plane_turn.dot(u.tail<3>()) - c.plane_normal.dot(u.head<3>());
    }
    return g;
}

Vec6 rigidGapBodyGradient(const RigidSegmentContact& c) {
    Vec6 a;
    a.head<3>() = -c.plane_normal;
    a.tail<3>() = c.plane_turn;
    return a;
}

// Friction with rigid bodies is part of the solve (IPC's lagged Coulomb friction): with
// u_t the tangential motion of the string's contact point relative to the body's over the
// step and F the contact's normal force at the start of a pass, the pass adds w/2 |u_t|^2,
// w = mu F / max(|u_t|, eps). At the fixed point of the passes that is mu F against
// sliding, or a stiff spring below eps of slip (sticking).

/// Slip of the string on the body this step, per fraction eps of the contact's thickness,
/// below which the contact sticks.
constexpr double kRigidSlip = 1e-3;

Vec3 rigidSlip(const StringState& s, const RigidSegmentContact& c, const Vec3& xs, const Vec6* extra) {
    const std::size_t j = c.segment;
    const Vec3 xs0 = (1.0 - c.s) * s.x_prev[j] + c.s * s.x_prev[j + 1];
    Vec3 body_point = c.plane_point;
    if (c.node >= 0) {
        const Vec6 u = bodyMotion(s, c, extra);
        body_point += u.head<3>() + u.tail<3>().cross(c.plane_arm);
    }
    const Vec3 rel = (xs - xs0) - (body_point - c.start_point);
    return rel - c.plane_normal * c.plane_normal.dot(rel);
}

Mat36 rigidSlipBodyJacobian(const RigidSegmentContact& c, const Mat3& tangent) {
    Mat36 j;
    j.leftCols<3>() = -tangent;
    j.rightCols<3>() = tangent * cross(c.plane_arm);
    return j;
}

/// Gradient k_c g u and Hessian k_c u u^T with u = dg/dx.
void addPenaltyRows(StringState& s, const RigidSegmentContact& c, double g, bool fa, bool fb) {
    const std::size_t j = c.segment;
    const Vec3& nrm = c.plane_normal;
    const double kc = c.stiffness;
    const Mat3 nnt = nrm * nrm.transpose();
    const double wa = 1.0 - c.s, wb = c.s;
    if (fa) {
        s.scratch.blk_diag[j] += kc * wa * wa * nnt;
        s.scratch.blk_rhs[j] -= kc * g * wa * nrm;
    }
    if (fb) {
        s.scratch.blk_diag[j + 1] += kc * wb * wb * nnt;
        s.scratch.blk_rhs[j + 1] -= kc * g * wb * nrm;
    }
    if (fa && fb) s.scratch.blk_off[j] += kc * wa * wb * nnt;
}

/// Gradient w T rel and Hessian w T.
FrictionTerm addFrictionRows(StringState& s, const RigidSegmentContact& c, bool fa, bool fb) {
    const std::size_t j = c.segment;
    const double w = c.friction_weight, wa = 1.0 - c.s, wb = c.s;
    const FrictionTerm f{Mat3::Identity() - c.plane_normal * c.plane_normal.transpose(),
                         rigidSlip(s, c, (1.0 - c.s) * s.x[j] + c.s * s.x[j + 1])};
    if (fa) {
        s.scratch.blk_diag[j] += (w * wa * wa) * f.tangent;
        s.scratch.blk_rhs[j] -= (w * wa) * f.slip;
    }
    if (fb) {
        s.scratch.blk_diag[j + 1] += (w * wb * wb) * f.tangent;
        s.scratch.blk_rhs[j + 1] -= (w * wb) * f.slip;
    }
    if (fa && fb) s.scratch.blk_off[j] += (w * wa * wb) * f.tangent;
    return f;
}

double weighRigidFriction(StringState& s) {
    double change = 0.0;
    for (RigidSegmentContact& c : s.contacts) {
        const std::size_t j = c.segment;
        double w = 0.0;
        const Vec3 xs = (1.0 - c.s) * s.x[j] + c.s * s.x[j + 1];
        c.force = s.broken[j] ? 0.0 : c.stiffness * std::max(0.0, -rigidGap(s, c, xs));
        if (c.friction > 0.0 && c.force > 0.0)
            w = c.friction * c.force / std::max(rigidSlip(s, c, xs).norm(), kRigidSlip * c.gap);
        const double scale = std::max(w, c.friction_weight);
        if (scale > 0.0) change = std::max(change, std::abs(w - c.friction_weight) / scale);
        c.solved_weight = c.friction_weight;
        c.friction_weight = w;
    }
    return change;
}

double stiffestTerm(const StringState& s, double inv_h2) {
    double heaviest = 0.0;
    for (double mass : s.mass) heaviest = std::max(heaviest, mass);
    return std::max({1.0 / *std::min_element(s.compliance.begin(), s.compliance.end()), heaviest * inv_h2, 1e-12});
}

/// The stiffness is the one limitStrain set.
void assembleRigidContacts(StringState& s) {
    for (RigidSegmentContact& c : s.contacts) {
        const std::size_t j = c.segment;
        const double g = rigidGap(s, c, (1.0 - c.s) * s.x[j] + c.s * s.x[j + 1]);
        c.active = !s.broken[j] && c.stiffness > 0.0 && g < 0.0;
        if (c.active) addPenaltyRows(s, c, g, freeParticle(s, j), freeParticle(s, j + 1));
    }
    // Their friction, with the weights of the string's own solve (the bodies held).
    for (const RigidSegmentContact& c : s.contacts) {
        const std::size_t j = c.segment;
        if (!(c.friction_weight > 0.0) || s.broken[j]) continue;
        addFrictionRows(s, c, freeParticle(s, j), freeParticle(s, j + 1));
    }
}

}  // namespace tearables::detail
