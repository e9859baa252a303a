// The rows of a string's contacts with rigid bodies in its Newton system: a stiff
// one-sided penalty k_c min(0, g)^2 / 2 on the gap g to the body's surface plane,
// linearised in the body's motion, and smoothed Coulomb friction mu N f0(|u_t|) on the
// slip with the normal force N lagged (IPC, Li et al. 2020, Sec. 5), with their gradients
// and Hessians in the string's particles and in the body's six unknowns.
#include "string/strain_limit_internal.hpp"

#include <algorithm>
#include <cmath>

namespace tearables::detail {

namespace {

/// Where a contact's surface point is now: on its body (following it), or a fixed world
/// point where it has none. On a ball (spherical) the point under the string stays under
/// it, at the same offset from the centre, while the body's material rolls past it by
/// theta x offset (theta the body's turn since the step started): a shift along the
/// surface, across the normal, that moves the gap not at all and carries the turn into
/// the slip (rigidSlip), as a material point fixed in the ball would.
Vec3 contactPoint(const RigidSegmentContact& c, const RigidTable& rigids) {
    if (!c.body.valid()) return c.local;
    const RigidState& body = rigids.bodies[c.body.index];
    if (!c.spherical) return gluePoint(body, c.local);
    const Eigen::AngleAxisd turn(body.orientation * rigids.start_orientation[c.body.index].conjugate());
    return body.position + c.local + (turn.angle() * turn.axis()).cross(c.local);
}

/// A rigid contact's normal now: it turns with its body. The contact is the body's
/// surface plane at the contact point (point and normal fixed in the body), so that a
/// body that rolls on a rope does not lift off it (a normal fixed in the world lets a box
/// lower its penalty energy by spinning about the rope, and slip through it). On a ball
/// the surface under the string is the same however the ball turns: the normal keeps its
/// direction (a plane turned with a ball spinning at 130 rad/s, 1.3 rad in a 10 ms step,
/// faces along the rope by the end of the step and the rope passes through the ball).
Vec3 contactNormal(const RigidSegmentContact& c, const RigidTable& rigids) {
    if (!c.body.valid()) return c.normal;
    return c.spherical ? c.local_normal : Vec3(rigids.bodies[c.body.index].orientation * c.local_normal);
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
        // Unit to rounding: a host's orientation in single precision turns the local
        // normal into one 5e-8 off unit length, and I - n n^T is then no projector, so a
        // sticking friction's stiff spring (2 mu N / eps) gives the string a normal force
        // the body's tangent rows do not return (a momentum leak of ~1 N).
        c.plane_normal = contactNormal(c, rigids).normalized();
        c.plane_turn.setZero();
        c.plane_arm.setZero();
        c.start_point = c.plane_point;
        if (!c.body.valid()) continue;
        const std::size_t b = c.body.index;
        c.start_point = rigids.start_position[b] + (c.spherical ? c.local : Vec3(rigids.start_orientation[b] * c.local));
        if (c.node < 0) continue;
        // A ball's arm is from its centre to the surface under the string, along the normal.
        c.plane_arm = c.spherical ? c.local : Vec3(c.plane_point - rigids.bodies[b].position);
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

// Friction with rigid bodies is part of the solve: IPC's smoothed Coulomb friction (Li et
// al. 2020, "Incremental Potential Contact", Sec. 5). With u_t the tangential motion of
// the string's contact point relative to the body's over the step and N the contact's
// normal force, lagged (the penalty force at the end of the last pass), the solve adds the
// dissipative potential
//     D(u_t) = mu N f0(|u_t|),   f0(y) = -y^3 / (3 eps^2) + y^2 / eps + eps / 3  (y < eps),
//                                f0(y) = y                                      (y >= eps),
// whose derivative f1 = f0' = 2 y / eps - y^2 / eps^2 below eps and 1 above is C1: its
// force mu N f1(|u_t|) u_t / |u_t| is Coulomb's mu N against sliding, and below eps of
// slip a step a stiff spring (2 mu N / eps at rest) that holds any load under mu N. D is
// convex in u_t (f0 convex and increasing, composed with a norm), so for a fixed N the
// step's energy stays convex and Newton decides stick and slip by minimising it; only N
// moves between passes (weighRigidFriction), which repeat until it settles.

/// Slip of the string on the body this step, per fraction eps of the contact's thickness,
/// below which the contact sticks (IPC's eps_v h).
constexpr double kRigidSlip = 1e-3;

Mollifier mollify(double y, double eps) {
    Mollifier m;
    if (y >= eps) {
        m.f0 = y;
        m.f1_over_y = 1.0 / y;
        m.df1 = 0.0;
    } else {
        const double inv = 1.0 / eps;
        m.f0 = y * y * inv * (1.0 - y * inv / 3.0) + eps / 3.0;
        m.f1_over_y = inv * (2.0 - y * inv);
        m.df1 = 2.0 * inv * (1.0 - y * inv);
    }
    return m;
}

double slipSmoothing(const RigidSegmentContact& c) { return kRigidSlip * std::max(c.gap, 1e-9); }

bool hasFriction(const RigidSegmentContact& c) {
    return c.lagged ? c.friction_weight > 0.0 : c.friction > 0.0 && c.friction_normal > 0.0;
}

double rigidFrictionEnergy(const RigidSegmentContact& c, const Vec3& slip) {
    if (!hasFriction(c)) return 0.0;
    if (c.lagged) return 0.5 * c.friction_weight * slip.squaredNorm();
    return c.friction * c.friction_normal * mollify(slip.norm(), slipSmoothing(c)).f0;
}

Vec3 solvedFrictionForce(const RigidSegmentContact& c, const Vec3& slip) {
    if (c.lagged) return -c.solved_weight * slip;
    if (!(c.friction > 0.0) || !(c.solved_normal > 0.0)) return Vec3::Zero();
    return -(c.friction * c.solved_normal * mollify(slip.norm(), slipSmoothing(c)).f1_over_y) * slip;
}

FrictionTerm rigidFrictionTerm(const RigidSegmentContact& c, const Vec3& slip) {
    FrictionTerm f;
    f.tangent = Mat3::Identity() - c.plane_normal * c.plane_normal.transpose();
    f.slip = slip;
    f.gradient.setZero();
    f.hessian.setZero();
    if (!hasFriction(c)) return f;
    if (c.lagged) {  // w/2 |u_t|^2: gradient w u_t, Hessian w T
        f.gradient = c.friction_weight * slip;
        f.hessian = c.friction_weight * f.tangent;
        return f;
    }
    const double y = slip.norm();
    const Mollifier m = mollify(y, slipSmoothing(c));
    const double muN = c.friction * c.friction_normal;
    f.gradient = (muN * m.f1_over_y) * slip;
    // The Hessian of f0(|u|) on the tangent plane: f1'(y) along the slip, f1(y) / y across
    // it; both >= 0, so it is positive semidefinite as it stands (IPC's projection to PSD
    // has nothing to remove here). At rest (y = 0) both are 2 / eps.
    f.hessian = (muN * m.f1_over_y) * f.tangent;
    // With a movable body (an island's contact) the isotropic part alone: f0(sqrt(t)) is
    // concave in t = y^2 (sqrt(t) above eps; t / eps - t^(3/2) / (3 eps^2) + eps / 3
    // below), so the quadratic of weight f1(y_k) / y_k through the slip y_k lies above
    // f0 (iteratively reweighted least squares). With the exact Hessian's f1' = 0 along a
    // sliding slip, full steps in an island's coupled system leave the stick range and
    // cycle (a rope on a movable drum slides at 0.95 of the capstan ratio); the
    // majoriser's steps do not overshoot, at a linear rate near the verge of slipping.
    if (y > 0.0 && c.node < 0) {
        const Vec3 along = slip / y;
        f.hessian += (muN * (m.df1 - m.f1_over_y)) * (along * along.transpose());
    }
    return f;
}

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

/// Gradient dD/dx = w_end grad and Hessian w_end^2 H (grad and H of rigidFrictionTerm,
/// w_end the end's share 1 - s or s).
FrictionTerm addFrictionRows(StringState& s, const RigidSegmentContact& c, bool fa, bool fb) {
    const std::size_t j = c.segment;
    const double wa = 1.0 - c.s, wb = c.s;
    const FrictionTerm f = rigidFrictionTerm(c, rigidSlip(s, c, (1.0 - c.s) * s.x[j] + c.s * s.x[j + 1]));
    if (c.lagged) {
        // w/2 |u_t|^2: gradient w T rel, Hessian w T (the products in this order, as the
        // island's solve has always taken them).
        const double w = c.friction_weight;
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
    if (fa) {
        s.scratch.blk_diag[j] += (wa * wa) * f.hessian;
        s.scratch.blk_rhs[j] -= wa * f.gradient;
    }
    if (fb) {
        s.scratch.blk_diag[j + 1] += (wb * wb) * f.hessian;
        s.scratch.blk_rhs[j + 1] -= wb * f.gradient;
    }
    if (fa && fb) s.scratch.blk_off[j] += (wa * wb) * f.hessian;
    return f;
}

/// A contact's friction misses Coulomb's law by a fraction of its own bound mu N, or of
/// this fraction of the string's largest mu N where that is more (weighRigidFriction): a
/// contact that barely touches, or has just let go and still drags by a lagged weight's
/// millinewtons, does not keep the passes going.
constexpr double kNegligibleFriction = 0.1;

double coulombMiss(double applied, double bound, double slip, double eps, double largest_bound) {
    const double miss = slip >= eps ? std::abs(applied - bound) : std::max(0.0, applied - bound);
    const double scale = std::max(bound, kNegligibleFriction * largest_bound);
    return scale > 0.0 ? miss / scale : 0.0;
}

bool predictContacts(StringState& s, const std::vector<Vec3>* held_step) {
    bool changed = false;
    auto moved = [&](std::size_t p) { return steppedPosition(s, p, held_step); };
    for (RigidSegmentContact& c : s.contacts) {
        const std::size_t j = c.segment;
        if ((c.active && !c.predicted) || s.broken[j]) continue;
        const Vec6 step = c.node >= 0 ? s.scratch.node_step[static_cast<std::size_t>(c.node)] : Vec6::Zero();
        const bool runs_into = rigidGap(s, c, (1.0 - c.s) * moved(j) + c.s * moved(j + 1), &step) < 0.0;
        if (runs_into != c.active) {
            c.active = c.predicted = runs_into;
            changed = true;
        }
    }
    return changed;
}

double weighRigidFriction(StringState& s, bool in_island) {
    double largest_bound = 0.0;
    for (RigidSegmentContact& c : s.contacts) {
        const std::size_t j = c.segment;
        const Vec3 xs = (1.0 - c.s) * s.x[j] + c.s * s.x[j + 1];
        c.force = s.broken[j] ? 0.0 : c.stiffness * std::max(0.0, -rigidGap(s, c, xs));
        largest_bound = std::max(largest_bound, c.friction * c.force);
    }
    double change = 0.0;
    for (RigidSegmentContact& c : s.contacts) {
        c.lagged = in_island && c.node < 0;
        const double normal = c.friction > 0.0 ? c.force : 0.0;
        const std::size_t j = c.segment;
        const Vec3 xs = (1.0 - c.s) * s.x[j] + c.s * s.x[j + 1];
        const Vec3 slip_vector = c.friction > 0.0 ? rigidSlip(s, c, xs) : Vec3::Zero();
        const double slip = slip_vector.norm();
        const double eps = slipSmoothing(c);
        // The friction force the pass applied, against Coulomb's law with the normal force
        // it found: a sliding contact must carry mu N, a sticking one at most mu N. Where
        // every contact does (to kFrictionSettled of mu N, or of kNegligibleFriction of the
        // string's largest mu N), the state is a Coulomb solution and the passes end: a load
        // shared among contacts in a way the stiff penalties decide to the micron (a crate
        // on a rope on the floor) may move between them, as long as each stays in its cone.
        const double applied = rigidFrictionTerm(c, slip_vector).gradient.norm();
        change = std::max(change, coulombMiss(applied, c.friction * normal, slip, eps, largest_bound));
        c.solved_normal = c.friction_normal;
        c.friction_normal = normal;
        if (c.lagged) {
            // IPC's lagged weight: at the fixed point of the passes, mu F against sliding, or
            // a stiff spring below eps of slip (sticking).
            double w = 0.0;
            if (c.friction > 0.0 && c.force > 0.0) w = c.friction * c.force / std::max(slip, eps);
            c.solved_weight = c.friction_weight;
            c.friction_weight = w;
        }
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
    // Their friction, with the normal forces of the string's own solve (the bodies held).
    for (const RigidSegmentContact& c : s.contacts) {
        const std::size_t j = c.segment;
        if (!hasFriction(c) || s.broken[j]) continue;
        addFrictionRows(s, c, freeParticle(s, j), freeParticle(s, j + 1));
    }
}

}  // namespace tearables::detail
