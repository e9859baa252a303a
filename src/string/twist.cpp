// The twist stage (after strain limiting, so that it sees this step's geometry).
//
// Strings Sec. 4: segment j has a twist angle theta_j between its twist-free (Bishop) and
// material frames. The paper spreads twist by averaging increments over regions of
// half-width w_twist (Eq. 1-3), whose fixed point is the same linear twist whatever the
// widths and so cannot give Fig. 6e (a more rigid range twists less). We solve the balance
// the averaging approximates, implicitly (backward Euler, stable at any stiffness):
//
//   minimise  sum_j I_j/(2h^2) (theta_j - theta'_j)^2 + sum_k k_k/2 (theta_{k+1} - theta_k - tau0_k)^2
//
// theta'_j = theta_j + h omega_j (Eq. 5), I_j = m_j r^2 / 2 (a solid cylinder), k_k =
// G J w_k / (2 l_k), J = pi r^4 / 2, l_k between the segments' centres, tau0_k the joint's
// rest twist (plasticity). w/2 is a rigidity factor: w_twist = 2 (the paper's default) is
// the material's G J, twice the width twice as rigid (Fig. 6d-e). Tridiagonal, O(n); then
// omega_j = (theta_j - theta_j^old) / h (Eq. 4).
// Ends: a pinned end clamps its segment's twist (twist drivers turn it), a free end is
// torque-free, a glued end turns with its body, whose inertia about the axis joins the solve.
#include "base/constants.hpp"
#include "linalg/tridiagonal.hpp"
#include "string/string_state.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>

namespace tearables::detail {

namespace {

bool clamped(const StringState& s, std::size_t particle) { return s.hold[particle].kind == ParticleHold::Kind::Pin; }

/// Whether every value is +0 (bit for bit: -0 is not): all bits of all values zero, by
/// or-ing them (a loop the compiler vectorises).
bool positiveZeros(const std::vector<double>& v) {
    std::uint64_t bits = 0;
    for (double x : v) {
        std::uint64_t b;
        std::memcpy(&b, &x, sizeof b);
        bits |= b;
    }
    return bits == 0;
}

/// See solveTwist: nothing twists the string and nothing of it is twisted.
bool untwisted(const StringState& s) {
    const std::size_t n = s.particles();
    for (const std::size_t p : {std::size_t{0}, n - 1})
        if (s.hold[p].kind == ParticleHold::Kind::Glue) return false;
    for (int end = 0; end < 2; ++end)
        if (clamped(s, end == 0 ? 0 : n - 1) && (s.end_twist[end] != 0.0 || std::signbit(s.end_twist[end]))) return false;
    return positiveZeros(s.twist) && positiveZeros(s.twist_velocity) && positiveZeros(s.rest_twist);
}

/// Unit vector normal to unit t: the coordinate axis least aligned with it, made normal.
Vec3 normalTo(const Vec3& t) {
    Eigen::Index i = 0;
    t.cwiseAbs().minCoeff(&i);
    return (Vec3::Unit(i) - t[i] * t).normalized();
}

/// v carried from unit direction a to unit direction b by the rotation about a x b that
/// takes a to b (parallel transport; Rodrigues' formula with cos = a.b, sin = |a x b|).
/// Opposite directions: the half turn about a normal of a.
Vec3 transport(const Vec3& v, const Vec3& a, const Vec3& b) {
    const Vec3 axis = a.cross(b);
    const double sine = axis.norm(), cosine = a.dot(b);
    if (!(sine > 1e-14)) {
        if (cosine > 0.0) return v;
        const Vec3 k = normalTo(a);
        return 2.0 * k.dot(v) * k - v;
    }
    const Vec3 k = axis / sine;
    return cosine * v + sine * k.cross(v) + (1.0 - cosine) * k.dot(v) * k;
}

/// u made unit and normal to unit t (a fresh normal where u lies along t).
Vec3 normalPart(const Vec3& u, const Vec3& t) {
    const Vec3 n = u - u.dot(t) * t;
    const double len = n.norm();
    return len > 1e-9 ? Vec3(n / len) : normalTo(t);
}

/// Segment j's unit direction between particles a and b, or `fallback` where it has none.
Vec3 direction(const Vec3& a, const Vec3& b, const Vec3& fallback) {
    const Vec3 d = b - a;
    const double len = d.norm();
    return len > 0.0 && std::isfinite(len) ? Vec3(d / len) : fallback;
}

/// The twist-free frames follow the centreline in time (Bergou, Audoly, Vouga, Wardetzky,
/// Grinspun, "Discrete Viscous Threads", SIGGRAPH 2010, Sec. 4.2: the time-parallel
/// reference frame). theta_j is the angle of segment j's material frame from its Bishop
/// frame: the frame carried from the first segment along the string without turning about
/// any segment (space-parallel). Over a step each segment's frames are carried in time
/// from its old direction to its new one without turning about it (only the twist solve
/// turns the material); the Bishop frame of the new centreline then differs from the
/// carried one by the holonomy of the move, the writhe it made between the first segment
/// and segment j (Fuller), and theta_j takes that up:
///   theta_j += angle from the new Bishop director to the carried one, about t_j.
/// The first segment's Bishop frame is its carried frame (no change); a clamped last
/// segment holds its material frame against its own carried frame, so its held angle
/// takes the same change. Without this, theta kept its value in a frame rebuilt each step,
/// and a clamped rod that coils kept all its twist while it gained writhe: link
/// (twist + writhe) was not conserved. First call (or after the string was untwisted, or
/// its segments changed): the frames of the current centreline, theta unchanged.
void followFrames(StringState& s) {
    const std::size_t m = s.segments();
    const std::size_t n = s.particles();
    if (s.twist_frame.size() != m) {
        s.twist_frame.resize(m);
        Vec3 prev = direction(s.x[0], s.x[1], Vec3::UnitX());
        Vec3 u = normalTo(prev);
        for (std::size_t j = 0; j < m; ++j) {
            const Vec3 t = direction(s.x[j], s.x[j + 1], prev);
            u = normalPart(transport(u, prev, t), t);
            s.twist_frame[j] = u;
            prev = t;
        }
        return;
    }
    Vec3 prev = Vec3::Zero(), bishop = Vec3::Zero();
    double last_turn = 0.0;
    for (std::size_t j = 0; j < m; ++j) {
        const Vec3 t_old = direction(s.x_prev[j], s.x_prev[j + 1], j == 0 ? Vec3::UnitX() : prev);
        const Vec3 t = direction(s.x[j], s.x[j + 1], t_old);
        const Vec3 carried = normalPart(transport(normalPart(s.twist_frame[j], t_old), t_old, t), t);
        bishop = j == 0 ? carried : normalPart(transport(bishop, prev, t), t);
        const double turn = std::atan2(bishop.cross(carried).dot(t), bishop.dot(carried));
        if (std::isfinite(turn)) {
            s.twist[j] += turn;
            last_turn = turn;
        }
        s.twist_frame[j] = bishop;
        prev = t;
    }
    if (clamped(s, n - 1)) s.end_twist[1] += last_turn;
}

}  // namespace

void updateTwistStiffness(StringState& s) {
    const std::size_t m = s.segments();
    for (std::size_t k = 0; k + 1 < m; ++k) {
        if (s.broken[k] || s.broken[k + 1]) {
            s.joint_stiffness[k] = 0.0;
            continue;
        }
        const double r = 0.5 * (s.radius[k] + s.radius[k + 1]);
        const double polar = 0.5 * kPi * r * r * r * r;
        const double g = 0.5 * (s.material[k].shear_modulus + s.material[k + 1].shear_modulus);
        const double w = 0.5 * (s.twist_width[k] + s.twist_width[k + 1]);
        const double l = 0.5 * (s.rest_length[k] + s.rest_length[k + 1]);
        s.joint_stiffness[k] = g * polar * (w / 2.0) / l;
    }
}

void solveTwist(StringState& s, RigidTable& rigids, const StepContext& ctx) {
    const std::size_t m = s.segments();
    const std::size_t n = s.particles();
    s.scratch.twist_skipped = false;
    if (m < 2 && !(clamped(s, 0) || clamped(s, n - 1))) {
        // A single free segment: nothing resists its spin but its own inertia.
        for (std::size_t j = 0; j < m; ++j) s.twist[j] += ctx.h * s.twist_velocity[j];
        return;
    }
    // An untwisted string that nothing twists (the common rope): every angle, velocity,
    // rest twist and clamped end angle +0, no end glued. The solve would give +0 everywhere,
    // so it is skipped: the same bits. The joint stiffnesses it leaves stale are read only by
    // computeTwistForces, whose moments are zero whatever they hold.
    s.scratch.twist_skipped = untwisted(s);
    if (s.scratch.twist_skipped) {
        std::copy(s.twist.begin(), s.twist.end(), s.twist_old.begin());
        s.twist_glued_axis_inertia[0] = s.twist_glued_axis_inertia[1] = 0.0;
        s.twist_frame.clear();
        return;
    }
    followFrames(s);
    updateTwistStiffness(s);
    const double inv_h2 = ctx.inv_h * ctx.inv_h;
    // Rows: inertia about the axis (or fixed for a clamped end), springs between joints.
    for (std::size_t j = 0; j < m; ++j) {
        s.twist_old[j] = s.twist[j];
        s.scratch.diag[j] = s.twist_inertia[j] * inv_h2;
        s.scratch.rhs[j] = s.twist_inertia[j] * inv_h2 * (s.twist[j] + ctx.h * s.twist_velocity[j]);
        s.scratch.off[j] = 0.0;
    }
    // Ends glued to a body: the segment turns with the body; the body's moment of
    // inertia about the segment axis joins the row.
    for (int end = 0; end < 2; ++end) {
        s.twist_glued_axis_inertia[end] = 0.0;
        const std::size_t p = end == 0 ? 0 : n - 1;
        const std::size_t j = end == 0 ? 0 : m - 1;
        const ParticleHold& hold = s.hold[p];
        if (hold.kind != ParticleHold::Kind::Glue) continue;
        const RigidState& b = rigids.bodies[hold.body.index];
        const Vec3& e = s.scratch.dir[j];
        const double predicted = s.twist[j] + ctx.h * b.angular_velocity.dot(e);  // turned with the body
        s.twist_glued_pred[end] = predicted;
        if (!s.glue_movable[p]) {
            s.scratch.diag[j] = 1.0;
            s.scratch.rhs[j] = predicted;
            continue;
        }
        const double inv_axis = e.dot(b.inverseInertiaWorld() * e);
        const double axis_inertia = inv_axis > 0.0 ? 1.0 / inv_axis : 0.0;
        s.twist_glued_axis_inertia[end] = axis_inertia;
        s.scratch.diag[j] = (s.twist_inertia[j] + axis_inertia) * inv_h2;
        s.scratch.rhs[j] = s.scratch.diag[j] * predicted;
    }
    for (std::size_t k = 0; k + 1 < m; ++k) {
        const double kk = s.joint_stiffness[k];
        if (kk <= 0.0) continue;
        s.scratch.diag[k] += kk;
        s.scratch.diag[k + 1] += kk;
        s.scratch.off[k] = -kk;
        s.scratch.rhs[k] -= kk * s.rest_twist[k];
        s.scratch.rhs[k + 1] += kk * s.rest_twist[k];
    }
    // Clamped ends hold their angle (set by twist drivers).
    if (clamped(s, 0)) {
        s.scratch.diag[0] = 1.0;
        s.scratch.rhs[0] = s.end_twist[0];
        s.scratch.off[0] = 0.0;
        if (m > 1) s.scratch.rhs[1] += s.joint_stiffness[0] * s.end_twist[0];
    }
    if (clamped(s, n - 1)) {
        const std::size_t j = m - 1;
        s.scratch.diag[j] = 1.0;
        s.scratch.rhs[j] = s.end_twist[1];
        if (j > 0) {
            s.scratch.off[j - 1] = 0.0;
            s.scratch.rhs[j - 1] += s.joint_stiffness[j - 1] * s.end_twist[1];
        }
    }
    // The clamped rows were decoupled above by moving their known angle to the right.
    if (clamped(s, 0) && m > 1) s.scratch.off[0] = 0.0;
    solveSymmetricTridiagonal(s.scratch.diag, s.scratch.off, s.scratch.rhs, s.scratch.segment_work);
    for (std::size_t j = 0; j < m; ++j) {
        s.twist[j] = s.scratch.rhs[j];
        s.twist_velocity[j] = (s.twist[j] - s.twist_old[j]) * ctx.inv_h;
    }
    // The string's torque back on glued bodies: the body turns by what the solve moved its
    // end away from where the body alone would have taken it (World's applyBodyVelocities
    // turns that rotation into angular velocity, like the strain limiter's corrections).
    for (int end = 0; end < 2; ++end) {
        const double axis_inertia = s.twist_glued_axis_inertia[end];
        if (axis_inertia <= 0.0) continue;
        const std::size_t p = end == 0 ? 0 : n - 1;
        const std::size_t j = end == 0 ? 0 : m - 1;
        RigidState& b = rigids.bodies[s.hold[p].body.index];
        const Vec3 rotation =
            b.inverseInertiaWorld() * (axis_inertia * (s.twist[j] - s.twist_glued_pred[end]) * s.scratch.dir[j]);
        const double angle = rotation.norm();
        if (angle > 0.0 && std::isfinite(angle))
            b.orientation = (Quat(Eigen::AngleAxisd(angle, rotation / angle)) * b.orientation).normalized();
    }
}

// The twist force (Strings Eq. 6): the gradient of the same energy with respect to the
// positions, in the general form of Bergou et al. 2008, with m_p = theta_p - theta_{p-1}
// and M_p = k (m_p - tau0) at interior particle p, and kb_p = 2 e_{p-1} x e_p /
// (|e_{p-1}||e_p| + e_{p-1}.e_p) (Eq. 7). The joint's twist changes with the centreline
// by the holonomy followFrames applies: dm_p/dx_{p-1} = -kb_p / (2|e_{p-1}|),
// dm_p/dx_{p+1} = kb_p / (2|e_p|), dm_p/dx_p = -(the sum) (checked against followFrames'
// increments by finite differences; the signs are those of the reference implementations'
// gradTwist, opposite to how the 2008 paper's text prints them). The force, -M_p dm_p/dx,
// is then the exact gradient, and a rod's link (twist + writhe) is kept. It acts in the
// next step's prediction.
void computeTwistForces(StringState& s) {
    const std::size_t n = s.particles();
    // After a skipped twist solve every moment is zero: the forces are zero, and already
    // are where they were cleared before.
    if (s.scratch.twist_skipped) {
        if (!s.scratch.twist_force_zero) std::fill(s.twist_force.begin(), s.twist_force.end(), Vec3::Zero());
        s.scratch.twist_force_zero = true;
        return;
    }
    s.scratch.twist_force_zero = false;
    std::fill(s.twist_force.begin(), s.twist_force.end(), Vec3::Zero());
    for (std::size_t p = 1; p + 1 < n; ++p) {
        const std::size_t a = p - 1, b = p;  // segments meeting at particle p (joint a)
        if (s.broken[a] || s.broken[b] || s.joint_stiffness[a] <= 0.0) continue;
        // An untwisted joint (most of a rope that nothing twists) exerts nothing: skipped
        // before its two square roots and nine divisions.
        const double moment = s.joint_stiffness[a] * (s.twist[b] - s.twist[a] - s.rest_twist[a]);
        if (moment == 0.0) continue;
        const Vec3 ea = s.x[p] - s.x[p - 1];
        const Vec3 eb = s.x[p + 1] - s.x[p];
        const double la = ea.norm(), lb = eb.norm();
        const double denom = la * lb + ea.dot(eb);
        if (!(denom > 1e-12 * la * lb)) continue;  // folded back on itself: undefined
        const Vec3 kb = 2.0 * ea.cross(eb) / denom;
        const Vec3 d_prev = -kb / (2.0 * la);
        const Vec3 d_next = kb / (2.0 * lb);
        s.twist_force[p - 1] -= moment * d_prev;
        s.twist_force[p + 1] -= moment * d_next;
        s.twist_force[p] += moment * (d_prev + d_next);
    }
}

}  // namespace tearables::detail
