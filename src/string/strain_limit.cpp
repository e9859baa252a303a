// Stage 5: strain limiting and rigid attachments, solved directly for the whole chain.
//
// Strings, Sec. 5.2 limits every segment to L <= L_max by sweeping position corrections
// from a clamped end (one end clamped), back and forth (both ends), or per piece between
// clamps (several points). Those sweeps move one particle at a time and need many passes
// when masses differ; a rope holding a body 1000x heavier than itself then stretches
// (this is why Bullet's anchored soft-body ropes do). We choose an exact, mass-weighted
// projection instead, which covers all three cases at once:
//
//   x = argmin  sum_p m_p/(2h^2) |x_p - x'_p|^2  +  sum_j k_j/2 max(0, |x_{j+1}-x_j| - L_j)^2
//
// i.e. backward Euler on segments of the material's own stiffness k_j = E A / L_j (the
// compliance form of strain limiting: the limit L_max = L (1 + sigma/E) of Strings Sec.
// 5.4 is met implicitly in the solve instead of lagging a step behind the stress, which
// would make a loaded rope alternate between slack and caught). At fibre moduli this is
// inextensible to within sigma/E. Newton's method on it, with the geometric stiffness of
// each stretched segment, gives a symmetric block-tridiagonal system (3x3 blocks, a
// segment couples two neighbouring particles) solved directly in O(n); 2-4 iterations
// converge. Without the geometric term (plain Gauss-Newton / XPBD) a light rope under a
// heavy load converges so slowly that it stretches without bound.
//
// The geometric term's tension. Its exact value at an iterate, k C, is a poor guide for
// the next step: the spring is so stiff that a transverse move of d stretches it by
// ~d^2 / 2L to second order and reads as a tension far above the real one (the segment at
// a swinging rope's pin: 3e4 N at the prediction, 150 N at the solution), and the step
// after it treats the particle as held by a rod of that tension and barely moves it across.
// Where a chain has no contacts, the geometric term takes instead the tension the last
// step predicted to first order, k (C + e . (dx_{j+1} - dx_j)) (the dual update of a
// primal-dual Newton method; at the first iteration, the last time step's final tension),
// or k C where that is smaller. The gradient is exact, so the solution is the same; on
// Strings' Table 1 rope the iterations fall from 5 to 3-4 a step, and a catenary at rest
// converges in 4 instead of stopping unconverged at 8.
//
// The start. A chain without contacts, taut along its whole length, starts where the last
// step's correction (its end less its prediction) moves its prediction, where that is a
// better start (warmStart): a rope holding a load is pulled back by about as much every
// step, so its iterations begin next to the solution (Strings' Table 1 rope, 746
// segments, swinging: 3.6 -> 2.0 iterations a step; a rope hanging still: 2 -> 1). The
// solution is the same (the energy is convex), only the iterations differ.
//
// Chord iterations. After the first Newton iteration from a warm start, a contact-free
// chain of free and pinned particles solves its next steps with the factorisation it has
// (the pivots' inverses kept by solveChain): only the gradient is assembled, and the solve
// is products, with no pivot chain of divisions (about a third of an iteration's time).
// The Hessian it reuses is that of the first iteration, so the iterations converge
// linearly, at a rate of about 2 m_c / m_N (m_N the Newton move, m_c the first chord move:
// the Hessian changes by O(m_N) over that move, and m_c ~ C m_N^2 / 2 gives C), and the
// solve stops where the next move, predicted as 2 m_c^2 / m_last with the margin of 100,
// is within tolerance. Only from a warm start: its first Hessian's geometric term takes
// the last step's converged tension. After cold iterations the term's tension is a
// first-order estimate, off by the second-order stretch of the last move (a rope swinging
// down: the move after a chord move was as long as the chord move, 3.7e-8 after 3.8e-8 m,
// where the rate predicted 2%, and the solves took one more Newton iteration a step). A chord iteration follows another only
// where that one's move fell by kQuadraticRegime or more, and it is refused (a Newton
// iteration from the same state made instead) where a segment went slack or taut since
// the factorisation, or where its step is not below kQuadraticRegime times the last move
// (a rope yanked by a huge force made chord steps 18x the Newton step before them).
// Strings' Table 1 rope, 746 segments swinging: 2.0 factorisations a step -> 1.0, and 1.2
// chord iterations. Chains of kParallelChainParticles or more have none: their iterations
// must be the same on one thread as on two (parallelChainStep).
//
// Clamped particles are fixed rows, which splits the system into independent pieces as
// case 3 of the paper prescribes. A particle glued to a rigid body carries the body's
// effective mass at the glue point, K^-1 with K = 1/M - [r]x I^-1 [r]x, so the rope holds
// the body with its real mass and inertia, and the body, moved by the same impulses,
// pulls the rope (two-way). Strings that share a body are coupled by Gauss-Seidel sweeps
// over the strings in World::step.
#include "collision/capsule.hpp"
#include "base/lanes.hpp"
#include "base/thread_pool.hpp"
#include "linalg/tridiagonal.hpp"
#include "string/string_state.hpp"

#include <Eigen/Cholesky>
#include <Eigen/SparseCholesky>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>

namespace tearables::detail {

namespace {

/// A segment shorter than its rest length by less than this fraction counts as taut.
constexpr double kTautSlack = 1e-4;
/// Contact penalty over the stiffest spring, particle and body inertia it competes with.
constexpr double kContactStiffnessFactor = 100.0;
/// Passes of the contact solves (rigid friction's weights; the joint string solve's
/// closest points and friction), and the iteration budget of a pass with contacts
/// relative to WorldSettings::strain_iterations.
constexpr int kContactPasses = 4;
constexpr int kContactIterationFactor = 4;
/// The iteration budget of a contact-free chain relative to WorldSettings::strain_iterations
/// (the setting is the cloth's budget too). A taut rope converges in 3-5 iterations; a
/// sagging one whose segments go slack and taut takes up to ~12 in its transients (a
/// catenary falling into place), and steps that stop unconverged there feed a slow
/// oscillation instead of letting the rope come to rest.
constexpr int kChainIterationFactor = 2;
/// A contact-free chain stops when its moves fall by this factor or more per iteration and
/// the next move, predicted quadratically and times kPredictionMargin, is within tolerance.
constexpr double kQuadraticRegime = 0.1;
constexpr double kPredictionMargin = 100.0;
/// A contact-free chain of at least this many particles and no glued ones is split over
/// two threads where the world has them (limitStrain, parallelChainStep): each half's
/// assembly, sweep and back substitution on one. An iteration of 4096 particles is about
/// 250 us of work on one thread; the pool's two hand-overs an iteration cost a few us.
constexpr std::size_t kParallelChainParticles = kParallelItems;
/// A segment within this fraction of its radius of a body counts as touching it.
constexpr double kContactSlop = 0.1;
/// Halvings of a Newton step before the line search gives up (the energy is at its
/// minimum to rounding along the step).
constexpr int kLineSearchHalvings = 30;
/// Times per Newton iteration that contacts the step would run into are added and the
/// step solved again.
constexpr int kPredictRounds = 3;
/// Friction's passes end when no weight changed by more than this fraction.
constexpr double kFrictionSettled = 1e-2;

using Vec6 = Eigen::Matrix<double, 6, 1>;
using Mat6 = Eigen::Matrix<double, 6, 6>;
using Mat36 = Eigen::Matrix<double, 3, 6>;

Mat3 cross(const Vec3& r) {
    Mat3 m;
    m << 0.0, -r.z(), r.y(), r.z(), 0.0, -r.x(), -r.y(), r.x(), 0.0;
    return m;
}

/// Moves a body by a position-level impulse P (kg m) applied at lever arm r.
void applyBodyImpulse(RigidState& body, const Vec3& r, const Vec3& impulse) {
    body.position += body.inverse_mass * impulse;
    const Vec3 rotation = body.inverseInertiaWorld() * r.cross(impulse);
    const Quat dq(0.0, 0.5 * rotation.x(), 0.5 * rotation.y(), 0.5 * rotation.z());
    body.orientation.coeffs() += (dq * body.orientation).coeffs();
    body.orientation.normalize();
}

/// Inverse-mass operator of particle p: isotropic w, or a body's 3x3 K at the glue point.
struct Mobility {
    double w = 0.0;
    bool matrix = false;
    Mat3 K = Mat3::Zero();
    double along(const Vec3& a, const Vec3& b) const { return matrix ? a.dot(K * b) : w * a.dot(b); }
};

Mobility mobility(const StringState& s, const RigidTable& rigids, std::size_t p) {
    Mobility m;
    const ParticleHold& hold = s.hold[p];
    if (hold.kind == ParticleHold::Kind::Free) {
        m.w = s.inv_mass[p];
    } else if (hold.kind == ParticleHold::Kind::Glue && rigids.movable(hold.body)) {
        const RigidState& b = rigids.bodies[hold.body.index];
        const Mat3 rx = cross(s.x[p] - b.position);
        m.matrix = true;
        m.K = b.inverse_mass * Mat3::Identity() - rx * b.inverseInertiaWorld() * rx;
    }
    return m;
}

/// Where a contact's surface point is now: on its body (following it), or a fixed point
/// (another string's segment, for string-string contacts).
Vec3 contactPoint(const SegmentContact& c, const RigidTable& rigids) {
    return c.body.valid() ? gluePoint(rigids.bodies[c.body.index], c.local) : c.local;
}

/// A rigid contact's normal now: it turns with its body. The contact is the body's
/// surface plane at the contact point (point and normal fixed in the body), so a body
/// that rolls on a rope does not lift off it: with the normal held fixed in the world, a
/// box slammed onto a taut rope found a lower penalty energy by spinning 60 degrees about
/// the rope in one step (its face point rose, the fixed normal saw the overlap vanish),
/// and the crate slipped through (the fast-crate test).
Vec3 contactNormal(const SegmentContact& c, const RigidTable& rigids) {
    return c.body.valid() ? Vec3(rigids.bodies[c.body.index].orientation * c.local_normal) : c.normal;
}

/// Linearises the string's contact planes where the bodies are now (the start of a
/// solve). A contact is the body's surface plane through p with normal n, both fixed in
/// the body; for the body's displacement (u, theta) from here its gap is, to first order,
///     g = n . (x(s) - p) - r  -  n . u  +  theta . (n x (p - c))
/// (c the body's centre): the rigid-body contact Jacobian, as Bullet's own solver uses
/// it. The term theta . (n x (x(s) - p)) is dropped: it vanishes while the string lies
/// along the normal from p, and it is what made the energy nonconvex. With it, the solve
/// minimises a convex energy (inertia, the springs, penalties on linear gaps), so Newton
/// with a line search converges from any start, even a crate predicted 8 cm into a rope.
/// Following the turning plane exactly within the solve (as this code did before) gave
/// poor Gauss-Newton steps, passes that ended unconverged, and leftover penalty that came
/// out as kinetic energy: a box thrown at a free rope gained up to 10x its energy. The
/// plane's second-order motion is met by the next step's contacts, found at the new pose.
void linearisePlanes(StringState& s, const RigidTable& rigids) {
    for (SegmentContact& c : s.contacts) {
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

/// How far contact c's movable body has moved since its planes were linearised, plus
/// `extra` (a trial step) when given.
Vec6 bodyMotion(const StringState& s, const SegmentContact& c, const Vec6* extra) {
    const BodyNode& node = s.body_nodes[static_cast<std::size_t>(c.node)];
    Vec6 u = node.displacement - node.linearised_at;
    if (extra) u += *extra;
    return u;
}

/// The gap of contact c (linearised by linearisePlanes) at string point xs: >= 0 when the
/// string is clear of the plane. `extra`: a further displacement of the body (a trial step).
double rigidGap(const StringState& s, const SegmentContact& c, const Vec3& xs, const Vec6* extra = nullptr) {
    double g = c.plane_normal.dot(xs - c.plane_point) - c.gap;
    if (c.node >= 0) {
        const Vec6 u = bodyMotion(s, c, extra);
        g += c.plane_turn.dot(u.tail<3>()) - c.plane_normal.dot(u.head<3>());
    }
    return g;
}

/// The gradient of rigidGap with respect to the body's displacement (u, theta).
Vec6 rigidGapBodyGradient(const SegmentContact& c) {
    Vec6 a;
    a.head<3>() = -c.plane_normal;
    a.tail<3>() = c.plane_turn;
    return a;
}

// Friction with rigid bodies is part of the solve, as for string contacts (below; IPC's
// lagged Coulomb friction): with u_t the tangential motion of the string's contact point
// relative to the body's over the step and F the contact's normal force at the start of
// a pass, the pass adds w/2 |u_t|^2, w = mu F / max(|u_t|, eps). At the fixed point of the
// passes that is mu F against sliding, or a stiff spring below eps of slip (sticking).
// A position correction after the solve (as this code did before) moved particles one
// contact at a time: it stretched the segments between them, and the strain limit of
// the next step returned that stretch as kinetic energy (a rope laid over a cylinder
// climbed up it instead of sliding off its long side).

/// Slip of the string on the body this step, per fraction eps of the contact's thickness,
/// below which the contact sticks.
constexpr double kRigidSlip = 1e-3;

/// The tangential motion u_t of contact c over the step (relative to the body), with the
/// string's contact point at xs and the body moved by `extra` beyond its displacement.
Vec3 rigidSlip(const StringState& s, const SegmentContact& c, const Vec3& xs, const Vec6* extra = nullptr) {
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

/// d(u_t)/d(body displacement): T [-I, [arm]x], T the tangent projector.
Mat36 rigidSlipBodyJacobian(const SegmentContact& c, const Mat3& tangent) {
    Mat36 j;
    j.leftCols<3>() = -tangent;
    j.rightCols<3>() = tangent * cross(c.plane_arm);
    return j;
}

/// Rigid contact c's penalty k_c g^2 / 2 on the string's own rows (g: its gap, or 0 where
/// it only joins the Hessian): gradient k_c g u and Hessian k_c u u^T with u = dg/dx, at
/// the segment's ends that move (`fa`, `fb`).
void addPenaltyRows(StringState& s, const SegmentContact& c, double g, bool fa, bool fb) {
    const std::size_t j = c.segment;
    const Vec3& nrm = c.plane_normal;
    const double kc = c.stiffness;
    const Mat3 nnt = nrm * nrm.transpose();
    const double wa = 1.0 - c.s, wb = c.s;
    if (fa) {
        s.blk_diag[j] += kc * wa * wa * nnt;
        s.blk_rhs[j] -= kc * g * wa * nrm;
    }
    if (fb) {
        s.blk_diag[j + 1] += kc * wb * wb * nnt;
        s.blk_rhs[j + 1] -= kc * g * wb * nrm;
    }
    if (fa && fb) s.blk_off[j] += kc * wa * wb * nnt;
}

/// Rigid contact c's friction on the string's own rows, w/2 |T rel|^2: gradient w T rel
/// and Hessian w T at the segment's ends that move (`fa`, `fb`). Returns T and T rel.
struct FrictionTerm {
    Mat3 tangent;
    Vec3 slip;
};
FrictionTerm addFrictionRows(StringState& s, const SegmentContact& c, bool fa, bool fb) {
    const std::size_t j = c.segment;
    const double w = c.friction_weight, wa = 1.0 - c.s, wb = c.s;
    const FrictionTerm f{Mat3::Identity() - c.plane_normal * c.plane_normal.transpose(),
                         rigidSlip(s, c, (1.0 - c.s) * s.x[j] + c.s * s.x[j + 1])};
    if (fa) {
        s.blk_diag[j] += (w * wa * wa) * f.tangent;
        s.blk_rhs[j] -= (w * wa) * f.slip;
    }
    if (fb) {
        s.blk_diag[j + 1] += (w * wb * wb) * f.tangent;
        s.blk_rhs[j + 1] -= (w * wb) * f.slip;
    }
    if (fa && fb) s.blk_off[j] += (w * wa * wb) * f.tangent;
    return f;
}

/// The friction weights of a pass, from each contact's penalty force and slip now.
/// Returns the largest relative change of a weight.
double weighRigidFriction(StringState& s) {
    double change = 0.0;
    for (SegmentContact& c : s.contacts) {
        const std::size_t j = c.segment;
        double w = 0.0;
        const Vec3 xs = (1.0 - c.s) * s.x[j] + c.s * s.x[j + 1];
        c.force = s.broken[j] ? 0.0 : c.stiffness * std::max(0.0, -rigidGap(s, c, xs));
        if (c.friction > 0.0 && c.force > 0.0)
            w = c.friction * c.force / std::max(rigidSlip(s, c, xs).norm(), kRigidSlip * c.gap);
        const double scale = std::max(w, c.friction_weight);
        if (scale > 0.0) change = std::max(change, std::abs(w - c.friction_weight) / scale);
        c.friction_weight = w;
    }
    return change;
}

/// The stiffest spring or particle inertia (m / h^2) of a string, N/m: what its contact
/// penalties are scaled from.
double stiffestTerm(const StringState& s, double inv_h2) {
    double heaviest = 0.0;
    for (double mass : s.mass) heaviest = std::max(heaviest, mass);
    return std::max({1.0 / *std::min_element(s.compliance.begin(), s.compliance.end()), heaviest * inv_h2, 1e-12});
}

/// Segment j's stretch C with the material's rate term (Kelvin-Voigt, see springTerm):
/// C + (tau/h) (C - C_prev), the stretch its force and energy take.
inline double effectiveStretch(const StringState& s, std::size_t j, double stretch, double rate_gain) {
    return stretch + rate_gain * (stretch - s.prev_stretch[j]);
}

/// Whether segment j, at stretch C and effective stretch `effective`, is slack: shorter
/// than kTautSlack of its rest length and not stretching. A slack segment carries nothing
/// and takes no part in the solve (springTerm).
inline bool slackSegment(const StringState& s, std::size_t j, double stretch, double effective) {
    return stretch <= -kTautSlack * s.rest_length[j] && effective <= 0.0;
}

/// True when particle p does not move in the solve (pinned, or glued to an immovable body).
bool fixedRow(const StringState& s, std::size_t p) {
    const ParticleHold& hold = s.hold[p];
    return hold.kind == ParticleHold::Kind::Pin || (hold.kind == ParticleHold::Kind::Glue && !s.glue_movable[p]);
}

/// Factorises the symmetric block-tridiagonal system (3x3 blocks blk_diag, blk_off):
/// block Thomas algorithm, O(n). The blocks are mass/h^2 plus spring and contact
/// Hessians, symmetric positive definite, so no pivoting is needed.
///
/// The recursion is one dependency chain along the string, bounded by the divider (the
/// pivots' square roots and divisions). Bit for bit as before (the rigid-contact tests
/// react to the last bit: a solve multiplying by reciprocals instead of dividing let the
/// fast crate through the rope, and an explicit D'^-1 lost the stiff direction of a
/// contact block), so only work that gives the same bits was removed: the solve with U
/// uses the pivot's stored reciprocals (Cholesky3::solve), and only the lower triangle of
/// U^T W is formed.
void factorBlockTridiagonal(StringState& s) {
    const std::size_t n = s.particles();
    s.blk_factor.resize(n);
    s.blk_coupled.resize(n);
    s.blk_factor[0].compute(s.blk_diag[0]);
    s.blk_coupled[0] = 0;
    for (std::size_t i = 1; i < n; ++i) {
        const Mat3& u = s.blk_off[i - 1];  // couples i-1 and i
        Mat3 d = s.blk_diag[i];
        const bool coupled = !u.isZero(0.0);
        s.blk_coupled[i] = coupled;
        if (coupled) {
            const Mat3 w = s.blk_factor[i - 1].solve(u);  // D'^-1 U
            // d -= U^T W, lower triangle only (the Cholesky reads no more); each entry
            // the same dot product, so the same bits.
            for (int c = 0; c < 3; ++c)
                for (int r = c; r < 3; ++r) d(r, c) -= u.col(r).dot(w.col(c));
            s.blk_factor_gain[i] = w.transpose();
        } else {
            s.blk_factor_gain[i].setZero();
        }
        s.blk_factor[i].compute(d);
    }
}

/// Solves the factorised system for `rhs` in place.
void solveFactored(const StringState& s, std::vector<Vec3>& rhs) {
    const std::size_t n = s.particles();
    for (std::size_t i = 1; i < n; ++i)
        if (s.blk_coupled[i]) rhs[i] -= s.blk_factor_gain[i] * rhs[i - 1];
    rhs[n - 1] = s.blk_factor[n - 1].solve(rhs[n - 1]);
    for (std::size_t i = n - 1; i-- > 0;) rhs[i] = s.blk_factor[i].solve(Vec3(rhs[i] - s.blk_off[i] * rhs[i + 1]));
}


/// A segment's spring in the chain's Newton system: Hessian and force, and to which of its
/// particles they apply (a fixed particle's row takes neither).
struct SpringTerm {
    Mat3 hess = Mat3::Zero();
    Vec3 force = Vec3::Zero();  // pulls j toward j+1
    bool to_a = false;  // applies to particle j
    bool to_b = false;  // applies to particle j+1
};

/// Adds to a particle's block d and right-hand side rhs its share of the spring before it
/// (the segment it ends) and then of the spring after it (the segment it starts): the
/// order of assembleSprings' sums.
[[gnu::always_inline]] inline void addSprings(const SpringTerm& before, const SpringTerm& after, Mat3& d, Vec3& rhs) {
    if (before.to_b) {
        d += before.hess;
        rhs -= before.force;
    }
    if (after.to_a) {
        d += after.hess;
        rhs += after.force;
    }
}

// The contact-free chain's solve (solveChain, and its halves on two threads in
// parallelChainStep) runs two sweeps of the block Thomas algorithm at once, one from each
// end. Their arithmetic is written once, for a lane type T: double for one sweep, Lanes2
// (GCC's vector of two doubles, one SSE2 register) for both, the sweep from the top in lane
// 0. A sweep's step is a dependency chain (one 3x3 inverse, three divisions, and small
// products per particle); in lanes, both chains' steps are the same instructions, where the
// two chains interleaved as scalar code (~500 instructions a step) filled the core's window
// and overlapped little. On Strings' rope (747 particles) a solve in the step went from 58k
// to 49k ticks of the TSC (-16%; alone, on a system dumped from the step, 1.4x). Each lane
// computes exactly what the scalar code computes (no FMA: the default x86-64 target has
// none), so the two threads' halves give the bits of the serial solve. Where the sweeps
// held Eigen's 3x3 products, the summation order was Eigen's: the bits of a chain's solve
// changed with this code, by rounding.
namespace chain {

/// v where m holds, else 0 (also where v is not finite).
inline double keep(bool m, double v) { return m ? v : 0.0; }
inline Lanes2 keep(LaneMask2 m, Lanes2 v) { return maskLanes(m, v); }
/// Whether any of the n values is not zero, lane by lane. One sweep stops at the first
/// (a predictable branch; a mask of every value cost the two-thread halves' sweeps 50
/// instructions a particle and their registers).
template <int n> inline bool anyNonzero(const double* v) {
    for (int k = 0; k < n; ++k)
        if (v[k] != 0.0) return true;
    return false;
}
template <int n> inline LaneMask2 anyNonzero(const Lanes2* v) {
    LaneMask2 m = nonzeroLanes(v[0]);
    for (int k = 1; k < n; ++k) m = eitherLane(m, nonzeroLanes(v[k]));
    return m;
}
/// Whether no lane of m holds.
inline bool none(bool m) { return !m; }
inline bool none(LaneMask2 m) { return noLane(m); }

/// A symmetric 3x3 matrix by its lower triangle: 00 10 20 11 21 22.
template <class T> struct Sym {
    T e[6];
    T operator()(int r, int c) const { return e[kIndex[r][c]]; }
    static constexpr int kIndex[3][3] = {{0, 1, 2}, {1, 3, 4}, {2, 4, 5}};
};
inline Sym<double> lower(const Mat3& a) { return {{a(0, 0), a(1, 0), a(2, 0), a(1, 1), a(2, 1), a(2, 2)}}; }
inline Sym<Lanes2> lower(const Mat3& a, const Mat3& b) {
    Sym<Lanes2> m;
    for (int c = 0, k = 0; c < 3; ++c)
        for (int r = c; r < 3; ++r) m.e[k++] = Lanes2{a(r, c), b(r, c)};
    return m;
}

/// What a sweep carries to the next particle: the Schur complement U^T D^-1 U of the
/// particle it eliminated (D its pivot, U its coupling block) and U^T y, both zero where
/// U is zero (nothing crosses it: a pin, a broken segment), whatever D^-1 holds.
template <class T> struct Carry {
    Sym<T> schur{};
    T rhs[3] = {};
};

/// The inverse of a symmetric positive definite 3x3 matrix from its root-free Cholesky
/// factorisation A = L D L^T: A^-1 = L^-T D^-1 L^-1, three divisions. As accurate as the
/// Cholesky solve (an adjugate inverse, one division, lost ~k h^2 / m of the digits in the
/// Schur complements of a stiff light cord, and a twisted cord coiled differently).
template <class T> [[gnu::always_inline]] inline Sym<T> inverseSymmetric(const Sym<T>& a) {
    const T one = T{} + 1.0;
    const T r0 = one / a.e[0];
    const T l10 = a.e[1] * r0, l20 = a.e[2] * r0;
    const T r1 = one / (a.e[3] - l10 * a.e[1]);
    const T b21 = a.e[4] - l20 * a.e[1];
    const T l21 = b21 * r1;
    const T r2 = one / (a.e[5] - l20 * a.e[2] - l21 * b21);
    const T m20 = l10 * l21 - l20;  // row 2 of L^-1: (m20, -l21, 1)
    const T i20 = r2 * m20, i21 = -r2 * l21;
    const T i10 = -r1 * l10 + i21 * m20;
    return {{r0 + r1 * l10 * l10 + i20 * m20, i10, i20, r1 + i21 * -l21, i21, r2}};
}

/// The forward substitution of one particle, its pivot's inverse `inv` given: y = D^-1 (rhs
/// less the carry's U^T y), and the carry's U^T y for the next particle (zero, with the
/// Schur complement, where the symmetric coupling block `out` = U is zero). Part of
/// eliminate, and alone a chord iteration's forward step (chordSolveChain).
/// Returns whether `out` couples, lane by lane.
template <class T>
[[gnu::always_inline]] inline auto eliminateAgain(Carry<T>& carry, const Sym<T>& inv, const T (&rhs)[3], const Sym<T>& out, T (&y)[3]) {
    T r[3];
    for (int i = 0; i < 3; ++i) r[i] = rhs[i] - carry.rhs[i];
    for (int i = 0; i < 3; ++i) y[i] = inv(i, 0) * r[0] + inv(i, 1) * r[1] + inv(i, 2) * r[2];
    const auto coupled = anyNonzero<6>(out.e);
    if (none(coupled)) {
        carry = Carry<T>{};
        return coupled;
    }
    for (int i = 0; i < 3; ++i) carry.rhs[i] = keep(coupled, out(i, 0) * y[0] + out(i, 1) * y[1] + out(i, 2) * y[2]);
    return coupled;
}

/// Eliminates one particle: its block `diag` and right-hand side `rhs`, less what the
/// carry brings from the particle before, give the pivot D; y = D^-1 r, D^-1 into `inv`
/// and the gain W = D^-1 U (column-major) towards the next particle, coupled by the
/// symmetric block `out` = U; the carry is then this particle's, for the next.
template <class T>
[[gnu::always_inline]] inline auto eliminate(Carry<T>& carry, const Sym<T>& diag, const T (&rhs)[3], const Sym<T>& out, T (&y)[3], T (&gain)[9], Sym<T>& inv) {
    Sym<T> pivot;
    for (int k = 0; k < 6; ++k) pivot.e[k] = diag.e[k] - carry.schur.e[k];
    inv = inverseSymmetric(pivot);
    for (int c = 0; c < 3; ++c)
        for (int i = 0; i < 3; ++i) gain[i + 3 * c] = inv(i, 0) * out(0, c) + inv(i, 1) * out(1, c) + inv(i, 2) * out(2, c);
    const auto coupled = eliminateAgain(carry, inv, rhs, out, y);
    if (none(coupled)) return coupled;
    for (int c = 0; c < 3; ++c)
        for (int i = c; i < 3; ++i)
            carry.schur.e[Sym<T>::kIndex[i][c]] = keep(coupled, out(i, 0) * gain[3 * c] + out(i, 1) * gain[1 + 3 * c] + out(i, 2) * gain[2 + 3 * c]);
    return coupled;
}

/// Back substitution of one particle: x = y - W x_next, where the gain W is not zero (a
/// zero gain, nothing crossing, leaves y whatever x_next holds).
template <class T> [[gnu::always_inline]] inline void substitute(const T (&gain)[9], const T (&next)[3], T (&x)[3]) {
    const auto coupled = anyNonzero<9>(gain);
    if (none(coupled)) return;
    for (int i = 0; i < 3; ++i) x[i] = x[i] - keep(coupled, gain[i] * next[0] + gain[i + 3] * next[1] + gain[i + 6] * next[2]);
}

/// A particle's vector into a sweep's lanes (one, or the top's and the bottom's), and back.
inline void load(const Vec3& v, double (&out)[3]) {
    for (int i = 0; i < 3; ++i) out[i] = v[i];
}
inline void load(const Vec3& a, const Vec3& b, Lanes2 (&out)[3]) {
    for (int i = 0; i < 3; ++i) out[i] = Lanes2{a[i], b[i]};
}
inline void store(const double (&v)[3], Vec3& out) {
    for (int i = 0; i < 3; ++i) out[i] = v[i];
}
inline void store(const Lanes2 (&v)[3], Vec3& a, Vec3& b) {
    for (int i = 0; i < 3; ++i) {
        a[i] = v[i][0];
        b[i] = v[i][1];
    }
}

/// The middle particle, where the two sweeps meet: its block less both sides' Schur
/// complements, solved into x.
inline Carry<double> meet(const Carry<double>& top, const Carry<double>& bottom) {
    Carry<double> both;
    for (int k = 0; k < 6; ++k) both.schur.e[k] = top.schur.e[k] + bottom.schur.e[k];
    for (int i = 0; i < 3; ++i) both.rhs[i] = top.rhs[i] + bottom.rhs[i];
    return both;
}
inline void solveMiddle(const Carry<double>& top, const Carry<double>& bottom, const Mat3& diag, Vec3& rhs, Sym<double>& inv) {
    Carry<double> both = meet(top, bottom);
    double r[3], x[3], unused[9];
    load(rhs, r);
    eliminate(both, lower(diag), r, Sym<double>{}, x, unused, inv);
    store(x, rhs);
}

/// The lanes of a carry, as the two sweeps' own.
inline void split(const Carry<Lanes2>& both, Carry<double>& top, Carry<double>& bottom) {
    for (int k = 0; k < 6; ++k) {
        top.schur.e[k] = both.schur.e[k][0];
        bottom.schur.e[k] = both.schur.e[k][1];
    }
    for (int k = 0; k < 3; ++k) {
        top.rhs[k] = both.rhs[k][0];
        bottom.rhs[k] = both.rhs[k][1];
    }
}

}  // namespace chain

/// solveChain's back substitution, outward from the middle particle, with the gains it
/// left in blk_factor_gain.
void substituteChain(StringState& s) {
    const std::size_t n = s.particles();
    const std::size_t mid = n / 2;
    const std::size_t below = n - 1 - mid;
    Vec3* rhs = s.blk_rhs.data();
    const double* gains = s.blk_factor_gain.data()->data();
    if (below < mid) {
        double gain[9], x[3], next[3];
        std::memcpy(gain, gains + 18 * below, sizeof gain);
        chain::load(rhs[mid - 1], x);
        chain::load(rhs[mid], next);
        chain::substitute(gain, next, x);
        chain::store(x, rhs[mid - 1]);
    }
    if (below == 0) return;
    Lanes2 next[3];  // the pair's neighbours towards the middle: carried, not read back
    chain::load(rhs[below], rhs[mid], next);
    for (std::size_t p = below; p-- > 0;) {
        const std::size_t i = n - 1 - p;
        // Lane by lane, x = y where the pair's coupling block was zero (solveChain's
        // flags: then so are its gains, and the neighbour is not read, whatever it holds).
        // The gains straight from memory: held in registers for a test of all nine, they
        // pushed the carried neighbour out to the stack, on the loop's dependency chain.
        Lanes2 x[3];
        chain::load(rhs[p], rhs[i], x);
        if (const int coupled = s.chain_coupled[p]) {
            const LaneMask2 m = bitLanes(coupled);
            const double* g = gains + 18 * p;
            for (int r = 0; r < 3; ++r)
                x[r] = x[r] - maskLanes(m, loadLanes(g + 2 * r) * next[0] + loadLanes(g + 2 * (r + 3)) * next[1] +
                                              loadLanes(g + 2 * (r + 6)) * next[2]);
        }
        chain::store(x, rhs[p], rhs[i]);
        std::copy(x, x + 3, next);
    }
}

/// Solves the chain's system (blk_diag, blk_off, blk_rhs) in place, for a chain without
/// contacts or body unknowns: the block Thomas algorithm with each pivot inverted
/// explicitly, run from both ends at once (a twisted factorisation), the two sweeps in the
/// two lanes of one register (chain::eliminate). Each sweep folds factor, forward
/// substitution and y_i = D_i^-1 r_i into one pass; the two meet at the middle particle,
/// whose pivot takes both sides' Schur complements, and the back substitution
/// x_i = y_i - W_i x_{i+-1} runs outward from there (substituteChain). The coupling blocks
/// are symmetric (their lower triangle is read). The pair of particles (t, n-1-t), lane by
/// lane: its gains W go into blk_factor_gain's storage at doubles [18 t, 18 t + 18) (the
/// pairs and the top sweep's last particle take at most 9 n, its size), and where
/// `inverses` is given (6 n + 12 doubles), its pivots' inverses at [12 t, 12 t + 12),
/// the top sweep's last one and the middle one's after them, for chordSolveChain.
///
/// The pivots are inertia m/h^2 plus springs: conditioned ~k h^2 / m (1e6 for Strings'
/// rope), so the explicit inverse is good to ~1e-10 relative, which the Newton iteration
/// (exact gradient) does not notice. Contacts' blocks are 1e8 stiffer in one direction,
/// where the explicit inverse lost that direction: they keep the Cholesky
/// (factorBlockTridiagonal).
void solveChain(StringState& s, double* inverses = nullptr) {
    const std::size_t n = s.particles();
    if (n == 0) return;
    const std::size_t mid = n / 2;
    const std::size_t below = n - 1 - mid;  // particles the sweep from the far end takes
    const Mat3* diag = s.blk_diag.data();
    const Mat3* off = s.blk_off.data();
    Vec3* rhs = s.blk_rhs.data();
    double* gains = s.blk_factor_gain.data()->data();
    chain::Carry<Lanes2> both;
    std::size_t t = 0;
    for (; t < below; ++t) {
        const std::size_t i = n - 1 - t;
        Lanes2 r[3], y[3], gain[9];
        chain::Sym<Lanes2> inv;
        chain::load(rhs[t], rhs[i], r);
        s.chain_coupled[t] = static_cast<std::uint8_t>(
            laneBits(chain::eliminate(both, chain::lower(diag[t], diag[i]), r, chain::lower(off[t], off[i - 1]), y, gain, inv)));
        chain::store(y, rhs[t], rhs[i]);
        std::memcpy(gains + 18 * t, gain, sizeof gain);
        if (inverses) std::memcpy(inverses + 12 * t, inv.e, sizeof inv.e);
    }
    chain::Carry<double> top, bottom;
    chain::split(both, top, bottom);
    if (t < mid) {  // an even count leaves the top sweep one more, t = mid - 1
        double r[3], y[3], gain[9];
        chain::Sym<double> inv;
        chain::load(rhs[t], r);
        chain::eliminate(top, chain::lower(diag[t]), r, chain::lower(off[t]), y, gain, inv);
        chain::store(y, rhs[t]);
        std::memcpy(gains + 18 * t, gain, sizeof gain);
        if (inverses) std::memcpy(inverses + 12 * below, inv.e, sizeof inv.e);
    }
    chain::Sym<double> middle;
    chain::solveMiddle(top, bottom, diag[mid], rhs[mid], middle);
    if (inverses) std::memcpy(inverses + 12 * below + 6, middle.e, sizeof middle.e);
    substituteChain(s);
}

/// A chord iteration's solve: the system solveChain factorised last (its coupling blocks
/// still in blk_off, its gains in blk_factor_gain, its pivots' inverses in `inverses`)
/// for a new right-hand side in blk_rhs, in place. Only products: no pivot, no division.
void chordSolveChain(StringState& s, const double* inverses) {
    const std::size_t n = s.particles();
    if (n == 0) return;
    const std::size_t mid = n / 2;
    const std::size_t below = n - 1 - mid;
    const Mat3* off = s.blk_off.data();
    Vec3* rhs = s.blk_rhs.data();
    chain::Carry<Lanes2> both;
    std::size_t t = 0;
    for (; t < below; ++t) {
        const std::size_t i = n - 1 - t;
        Lanes2 r[3], y[3];
        chain::Sym<Lanes2> inv;
        std::memcpy(inv.e, inverses + 12 * t, sizeof inv.e);
        chain::load(rhs[t], rhs[i], r);
        chain::eliminateAgain(both, inv, r, chain::lower(off[t], off[i - 1]), y);
        chain::store(y, rhs[t], rhs[i]);
    }
    chain::Carry<double> top, bottom;
    chain::split(both, top, bottom);
    if (t < mid) {
        double r[3], y[3];
        chain::Sym<double> inv;
        std::memcpy(inv.e, inverses + 12 * below, sizeof inv.e);
        chain::load(rhs[t], r);
        chain::eliminateAgain(top, inv, r, chain::lower(off[t]), y);
        chain::store(y, rhs[t]);
    }
    {
        chain::Carry<double> middle = chain::meet(top, bottom);
        chain::Sym<double> inv;
        std::memcpy(inv.e, inverses + 12 * below + 6, sizeof inv.e);
        double r[3], y[3];
        chain::load(rhs[mid], r);
        chain::eliminateAgain(middle, inv, r, chain::Sym<double>{}, y);
        chain::store(y, rhs[mid]);
    }
    substituteChain(s);
}

/// Generalised mass of a body (translation, rotation about its centre), world frame.
Mat6 bodyMass(const RigidState& b) {
    Mat6 m = Mat6::Zero();
    m.topLeftCorner<3, 3>() = Mat3::Identity() / b.inverse_mass;
    m.bottomRightCorner<3, 3>() = b.inverseInertiaWorld().inverse();
    return m;
}

/// The rotation by a rotation vector.
Quat rotationBy(const Vec3& v) {
    const double angle = v.norm();
    return angle > 0.0 ? Quat(Eigen::AngleAxisd(angle, v / angle)) : Quat::Identity();
}

/// Moves a body whose displacement in the solve goes from `before` to `after`
/// (translation, rotation vector; from where its planes were linearised). The rotation is
/// set from the total, not composed from the iterations' steps: rotations do not commute,
/// and Newton iterates that turned a light box by 0.6 rad and back left it turned by a
/// tenth of a radian that no contact saw (it spun up to 180 rad/s).
void displaceBody(RigidState& b, const Vec6& before, const Vec6& after) {
    b.position += after.head<3>() - before.head<3>();
    b.orientation = (rotationBy(after.tail<3>()) * rotationBy(before.tail<3>()).conjugate() * b.orientation).normalized();
}

/// The energy the Newton iteration minimises, at the current state moved by alpha times
/// the step held in blk_rhs (particles) and node_step (bodies): inertia of particles,
/// glued bodies and touched bodies, the material's springs and the contact penalties.
double stepEnergy(const StringState& s, const RigidTable& rigids, const StepContext& ctx, double alpha) {
    const std::size_t n = s.particles();
    const std::size_t m = s.segments();
    const double inv_h2 = ctx.inv_h * ctx.inv_h;
    double e = 0.0;
    auto trial = [&](std::size_t p) -> Vec3 { return fixedRow(s, p) ? s.x[p] : Vec3(s.x[p] + alpha * s.blk_rhs[p]); };
    for (std::size_t p = 0; p < n; ++p) {
        if (fixedRow(s, p)) continue;
        if (s.hold[p].kind == ParticleHold::Kind::Free) {
            e += 0.5 * s.mass[p] * inv_h2 * (trial(p) - s.x_pred[p]).squaredNorm();
        } else {  // glued to a movable body: its displacement this step is K P
            const Mat3 k = mobility(s, rigids, p).K;
            const Vec3 u = k * s.glue_impulse[p] + alpha * s.blk_rhs[p];
            e += 0.5 * inv_h2 * u.dot(k.ldlt().solve(u));
        }
    }
    for (std::size_t b = 0; b < s.body_nodes.size(); ++b) {
        const BodyNode& node = s.body_nodes[b];
        const Vec6 u = node.displacement + alpha * s.node_step[b];
        e += 0.5 * inv_h2 * u.dot(node.mass * u);
    }
    const double rate_gain = s.desc.axial_damping * ctx.inv_h;
    for (std::size_t j = 0; j < m; ++j) {
        if (s.broken[j]) continue;
        const double stretch = (trial(j + 1) - trial(j)).norm() - s.rest_length[j];
        const double effective = std::max(0.0, effectiveStretch(s, j, stretch, rate_gain));
        e += 0.5 / (s.compliance[j] * (1.0 + rate_gain)) * effective * effective;
    }
    for (const SegmentContact& c : s.contacts) {
        const std::size_t j = c.segment;
        if (s.broken[j] || c.stiffness <= 0.0) continue;
        const Vec3 xs = (1.0 - c.s) * trial(j) + c.s * trial(j + 1);
        Vec6 extra = Vec6::Zero();
        if (c.node >= 0) extra = alpha * s.node_step[static_cast<std::size_t>(c.node)];
        const double g = std::min(0.0, rigidGap(s, c, xs, &extra));
        e += 0.5 * c.stiffness * g * g;
        if (c.friction_weight > 0.0) e += 0.5 * c.friction_weight * rigidSlip(s, c, xs, &extra).squaredNorm();
    }
    return e;
}

/// A free particle's inertia row's right-hand side: toward its prediction x'.
inline Vec3 inertiaRhs(const StringState& s, std::size_t p, double inv_h2) { return -(s.mass[p] * inv_h2) * (s.x[p] - s.x_pred[p]); }

/// The inertia row of a free or pinned particle p, as assembleInertia writes it, into d
/// and rhs (a sweep's registers: parallelChainStep's halves assemble it as they go).
inline void inertiaRow(const StringState& s, std::size_t p, double inv_h2, Mat3& d, Vec3& rhs) {
    if (s.hold[p].kind == ParticleHold::Kind::Free) {
        d = (s.mass[p] * inv_h2) * Mat3::Identity();
        rhs = inertiaRhs(s, p, inv_h2);
    } else {
        d = Mat3::Identity();
        rhs.setZero();
    }
}

/// The inertia rows of particles [p0, p1) of the chain's Newton system: free particles
/// toward their prediction x', a glued particle with its body's effective mass, fixed rows
/// for pins, into blk_diag and blk_rhs.
void assembleInertia(StringState& s, RigidTable& rigids, const StepContext& ctx, std::size_t p0, std::size_t p1) {
    const double inv_h2 = ctx.inv_h * ctx.inv_h;
    // Inertia: free particles are pulled back toward their prediction x'; a glued
    // particle carries its body's effective mass K^-1 at the glue point and starts
    // each iteration on the body (which absorbed the earlier corrections).
    for (std::size_t p = p0; p < p1; ++p) {
        const ParticleHold& hold = s.hold[p];
        s.blk_rhs[p].setZero();
        switch (hold.kind) {
            case ParticleHold::Kind::Free:
                inertiaRow(s, p, inv_h2, s.blk_diag[p], s.blk_rhs[p]);
                break;
            case ParticleHold::Kind::Glue:
                s.x[p] = gluePoint(rigids.bodies[hold.body.index], hold.point);
                if (s.glue_movable[p]) {
                    // The body's inertia resists this string's own accumulated pull
                    // (what other strings did to the body is, for this string, part
                    // of the body's prediction): M_eff (x - x') / h^2 = P / h^2.
                    s.blk_diag[p] = mobility(s, rigids, p).K.inverse() * inv_h2;
                    s.blk_rhs[p] = -s.glue_impulse[p] * inv_h2;
                    break;
                }
                [[fallthrough]];
            case ParticleHold::Kind::Pin:
                s.blk_diag[p] = Mat3::Identity();  // fixed: its row is dx = 0
                break;
        }
    }
}

/// springTerm's part after the segment's length, direction and stiffness (`len`, `e`
/// candidate for dir, `k` = 1 / compliance): everything but the Hessian's one division.
/// Returns whether the term needs its Hessian (not where the segment is broken or slack,
/// nor without kHessian), with the stretch its geometric part takes in `geometric`.
template <bool kHessian>
[[gnu::always_inline]] inline bool springForce(StringState& s, const StepContext& ctx, std::size_t j, double* tension_estimate,
                                               double len, const Vec3& e_new, double k, SpringTerm& term, double& geometric) {
    s.active[j] = 0;
    s.spring_force[j] = 0.0;
    if (kHessian) s.blk_off[j].setZero();
    if (s.broken[j]) return false;
    if (len > 1e-15) s.dir[j] = e_new;
    const double stretch = len - s.rest_length[j];
    // Kelvin-Voigt: the segment's force is k (C + tau dC/dt), tau the material's
    // retardation time; it damps the rope's axial (bungee) vibration, which a
    // real fibre's internal friction kills within a few periods.
    const double rate_gain = s.desc.axial_damping * ctx.inv_h;
    const double effective = effectiveStretch(s, j, stretch, rate_gain);
    // Slack segments carry nothing (a rope does not push). Taut ones (within
    // kTautSlack of rest) join with their stiffness but no force, so that one
    // Newton step sees the whole taut chain a correction would stretch; a
    // segment the step compresses leaves again at the next iteration.
    if (slackSegment(s, j, stretch, effective)) return false;
    const double c = std::max(effective, 0.0);
    s.active[j] = 1;
    s.spring_force[j] = k * c;
    term.force = k * c * s.dir[j];
    term.to_a = !fixedRow(s, j);
    term.to_b = !fixedRow(s, j + 1);
    if (!kHessian) {
        if (tension_estimate) tension_estimate[j] = effective;
        return false;
    }
    geometric = c;
    if (tension_estimate) {
        // From a warm start, whose stretch is the last step's final one to within the
        // start's error, the first iteration takes the last step's tension as it is:
        // where the start left the segment a little less stretched, k C makes the step
        // transversely too soft (a 100-segment rope swinging down from the horizontal, 300
        // steps: 995 iterations with k C, 909 without; 1045 not warm-started).
        const double estimate = tension_estimate[j] * s.compliance[j];
        if (tension_estimate[j] > 0.0) geometric = s.strain_warm_start ? estimate : std::min(c, estimate);
        tension_estimate[j] = effective;
    }
    return true;
}

/// springTerm's Hessian, q = geometric / len given: k ((1 + tau/h) e e^T + q (I - e e^T)),
/// entry by entry with the same operations as the matrix expression (so the same bits),
/// the six distinct ones only (e_i e_j = e_j e_i exactly); and blk_off.
[[gnu::always_inline]] inline void springHessian(StringState& s, const StepContext& ctx, std::size_t j, double k, double q,
                                                 SpringTerm& term) {
    const double g = 1.0 + s.desc.axial_damping * ctx.inv_h;
    const Vec3& e = s.dir[j];
    const double e00 = e.x() * e.x(), e11 = e.y() * e.y(), e22 = e.z() * e.z();
    const double e10 = e.y() * e.x(), e20 = e.z() * e.x(), e21 = e.z() * e.y();
    const double h10 = k * (g * e10 + q * (0.0 - e10)), h20 = k * (g * e20 + q * (0.0 - e20));
    const double h21 = k * (g * e21 + q * (0.0 - e21));
    term.hess << k * (g * e00 + q * (1.0 - e00)), h10, h20,  //
        h10, k * (g * e11 + q * (1.0 - e11)), h21,           //
        h20, h21, k * (g * e22 + q * (1.0 - e22));
    if (term.to_a && term.to_b) s.blk_off[j] = -term.hess;
}

/// Segment j's spring of the material's stiffness k = E A / L_rest, if stretched: gradient
/// k C e and Hessian k (e e^T + C/l (I - e e^T)) (the geometric term keeps Newton convergent
/// when a heavy load pulls light particles). Sets active, spring_force, dir and blk_off
/// (zero where the segment couples nothing) of the segment. `tension_estimate` (per
/// segment, may be null): the tension the geometric term of the Hessian takes where it is
/// below the spring's force now (see limitStrain); if the segment is active, its entry is
/// replaced by its effective stretch now, which linearisedTension reads. Without
/// `kHessian` (a chord iteration's gradient), the force only: hess and blk_off are left.
template <bool kHessian = true>
[[gnu::always_inline]] inline SpringTerm springTerm(StringState& s, const StepContext& ctx, std::size_t j,
                                                     double* tension_estimate) {
    SpringTerm term;
    const Vec3 d = s.x[j + 1] - s.x[j];
    const double len = d.norm();
    const double k = 1.0 / s.compliance[j];
    double geometric = 0.0;
    if (springForce<kHessian>(s, ctx, j, tension_estimate, len, Vec3(d / len), k, term, geometric))
        springHessian(s, ctx, j, k, geometric / len, term);
    return term;
}

/// springTerm of segments j and j + 1, their square roots and divisions in the two lanes
/// of one register: a root or a division of two lanes costs what one of one lane does,
/// and a spring's five divisions and root are most of its time (the divider is busy ~18
/// ticks of the TSC a segment). The same operations lane by lane: the same bits.
template <bool kHessian = true>
[[gnu::always_inline]] inline void springTerms(StringState& s, const StepContext& ctx, std::size_t j, double* tension_estimate,
                                               SpringTerm (&term)[2]) {
    const UnitPair d = unitPair(s.x[j + 1] - s.x[j], s.x[j + 2] - s.x[j + 1]);
    const Lanes2 len = d.length;
    const Lanes2 k = 1.0 / Lanes2{s.compliance[j], s.compliance[j + 1]};
    double g0 = 0.0, g1 = 0.0;
    const bool h0 = springForce<kHessian>(s, ctx, j, tension_estimate, len[0], d.unit[0], k[0], term[0], g0);
    const bool h1 = springForce<kHessian>(s, ctx, j + 1, tension_estimate, len[1], d.unit[1], k[1], term[1], g1);
    if (!h0 && !h1) return;
    const Lanes2 q = Lanes2{g0, g1} / len;
    if (h0) springHessian(s, ctx, j, k[0], q[0], term[0]);
    if (h1) springHessian(s, ctx, j + 1, k[1], q[1], term[1]);
}

/// The springs of segments [j0, j1) (springTerm) added to blk_diag and blk_rhs.
void assembleSprings(StringState& s, const StepContext& ctx, std::size_t j0, std::size_t j1, double* tension_estimate) {
    auto add = [&s](std::size_t j, const SpringTerm& term) {
        addSprings(SpringTerm{}, term, s.blk_diag[j], s.blk_rhs[j]);
        addSprings(term, SpringTerm{}, s.blk_diag[j + 1], s.blk_rhs[j + 1]);
    };
    std::size_t j = j0;
    for (; j + 1 < j1; j += 2) {
        SpringTerm term[2];
        springTerms(s, ctx, j, tension_estimate, term);
        add(j, term[0]);
        add(j + 1, term[1]);
    }
    if (j < j1) add(j, springTerm(s, ctx, j, tension_estimate));
}

/// The Newton system of the chain without contacts: the inertia rows (assembleInertia) and
/// the springs of the stretched segments (assembleSprings), into blk_diag, blk_off, blk_rhs.
void assembleChain(StringState& s, RigidTable& rigids, const StepContext& ctx, double* tension_estimate) {
    assembleInertia(s, rigids, ctx, 0, s.particles());
    assembleSprings(s, ctx, 0, s.segments(), tension_estimate);
}

/// A chord iteration's right-hand side: assembleChain's (the gradient of the step's energy
/// now, for a chain of free and pinned particles), without the Hessian, whose blocks stay
/// those solveChain factorised. False where a segment went slack or taut since: the
/// factorised Hessian then lacks its spring or has one it no longer has. The effective
/// stretches of the active segments, which linearisedTension reads, go into s.scratch
/// (the tension stage's) and not into geometric_tension, which the Newton iteration that
/// replaces a chord iteration that fails or is refused reads as it was (acceptChord).
bool assembleChainGradient(StringState& s, const StepContext& ctx) {
    const double inv_h2 = ctx.inv_h * ctx.inv_h;
    for (std::size_t p = 0; p < s.particles(); ++p)
        s.blk_rhs[p] = s.hold[p].kind == ParticleHold::Kind::Free ? inertiaRhs(s, p, inv_h2) : Vec3::Zero();
    bool same = true;
    auto add = [&s](std::size_t j, const SpringTerm& term) {
        if (term.to_a) s.blk_rhs[j] += term.force;
        if (term.to_b) s.blk_rhs[j + 1] -= term.force;
    };
    const std::size_t m = s.segments();
    std::size_t j = 0;
    for (; j + 1 < m; j += 2) {
        const std::uint8_t was[2] = {s.active[j], s.active[j + 1]};
        SpringTerm term[2];
        springTerms<false>(s, ctx, j, s.scratch.data(), term);
        same = same && s.active[j] == was[0] && s.active[j + 1] == was[1];
        add(j, term[0]);
        add(j + 1, term[1]);
    }
    if (j < m) {
        const std::uint8_t was = s.active[j];
        add(j, springTerm<false>(s, ctx, j, s.scratch.data()));
        same = same && s.active[j] == was;
    }
    return same;
}

/// Whether the chord iteration's step in blk_rhs is taken: where it is below
/// kQuadraticRegime times the last iteration's move (`last_move`), the effective
/// stretches of assembleChainGradient go into geometric_tension for linearisedTension.
/// A longer step means the factorised Hessian is too far from the Hessian here (a rope
/// yanked by a huge force: chord steps 18x the Newton step before them), and a Newton
/// iteration from the same state replaces it.
bool acceptChord(StringState& s, double last_move) {
    double worst_squared = 0.0;
    for (std::size_t p = 0; p < s.particles(); ++p)
        if (s.hold[p].kind == ParticleHold::Kind::Free) worst_squared = std::max(worst_squared, s.blk_rhs[p].squaredNorm());
    const double limit = kQuadraticRegime * last_move;
    if (!(worst_squared < limit * limit)) return false;
    for (std::size_t j = 0; j < s.segments(); ++j)
        if (s.active[j]) s.geometric_tension[j] = s.scratch[j];
    return true;
}

/// The tension of each segment after the Newton step held in blk_rhs, to first order:
/// k max(0, C + (1 + tau/h) e . (dx_{j+1} - dx_j)), into geometric_tension (0 for the
/// segments that took no part in the step). C, the effective stretch before the step, is
/// what assembleChain left there.
void linearisedTension(StringState& s, const StepContext& ctx, std::size_t j0, std::size_t j1) {
    const double rate_gain = s.desc.axial_damping * ctx.inv_h;
    // Segment j's linearised effective stretch (0 where it took no part: then its tension
    // is max(0, 0) / compliance = +0, as set); each particle's step found once, carried
    // to the next segment.
    Vec3 da = fixedRow(s, j0) ? Vec3::Zero() : s.blk_rhs[j0];
    auto stretch = [&](std::size_t j) {
        const Vec3 db = fixedRow(s, j + 1) ? Vec3::Zero() : s.blk_rhs[j + 1];
        const double effective = s.active[j] ? s.geometric_tension[j] + (1.0 + rate_gain) * s.dir[j].dot(db - da) : 0.0;
        da = db;
        return effective;
    };
    // The divisions two segments at a time, in lanes.
    std::size_t j = j0;
    for (; j + 1 < j1; j += 2) {
        const double e0 = stretch(j), e1 = stretch(j + 1);
        const Lanes2 t = Lanes2{std::max(0.0, e0), std::max(0.0, e1)} / Lanes2{s.compliance[j], s.compliance[j + 1]};
        s.geometric_tension[j] = t[0];
        s.geometric_tension[j + 1] = t[1];
    }
    if (j < j1) s.geometric_tension[j] = std::max(0.0, stretch(j)) / s.compliance[j];
}

/// solveChain's sweep from the top alone, over particles [0, mid), with the springs of
/// segments [0, mid) assembled as it goes (their sums in assembleChain's order: particle t
/// takes segment t-1's share, then segment t's), and segment mid-1's share of particle mid
/// added at the end; the gains per particle into blk_factor_gain. One sweep alone leaves
/// the core idle while a pivot's divisions run; the assembly fills that time.
/// parallelChainStep runs it on one thread and sweepFromBottom on another: the operations
/// of the serial iteration's lanes, so the same bits. Returns what it carries to the
/// middle particle.
chain::Carry<double> sweepFromTop(StringState& s, const StepContext& ctx, std::size_t mid, double* tension_estimate) {
    chain::Carry<double> carry;
    const double inv_h2 = ctx.inv_h * ctx.inv_h;
    SpringTerm last;  // segment t-1
    for (std::size_t t = 0; t < mid; ++t) {
        const SpringTerm next = springTerm(s, ctx, t, tension_estimate);
        Mat3 d;
        Vec3 rhs;
        inertiaRow(s, t, inv_h2, d, rhs);
        addSprings(last, next, d, rhs);
        last = next;
        double r[3], y[3], gain[9];
        chain::Sym<double> inv;
        chain::load(rhs, r);
        chain::eliminate(carry, chain::lower(d), r, chain::lower(s.blk_off[t]), y, gain, inv);
        chain::store(y, s.blk_rhs[t]);
        std::memcpy(s.blk_factor_gain[t].data(), gain, sizeof gain);
    }
    addSprings(last, SpringTerm{}, s.blk_diag[mid], s.blk_rhs[mid]);
    return carry;
}

/// solveChain's sweep from the far end alone, over particles (mid, n), with the springs
/// of segments [mid, m) assembled as it goes; segment mid's share of particle mid goes to
/// `held` (the middle particle is not this thread's). Returns what it carries to the
/// middle particle.
chain::Carry<double> sweepFromBottom(StringState& s, const StepContext& ctx, std::size_t mid, double* tension_estimate, SpringTerm& held) {
    chain::Carry<double> carry;
    const double inv_h2 = ctx.inv_h * ctx.inv_h;
    SpringTerm last;  // segment i
    for (std::size_t i = s.particles() - 1; i > mid; --i) {
        const SpringTerm next = springTerm(s, ctx, i - 1, tension_estimate);
        Mat3 d;
        Vec3 rhs;
        inertiaRow(s, i, inv_h2, d, rhs);
        addSprings(next, last, d, rhs);
        last = next;
        double r[3], y[3], gain[9];
        chain::Sym<double> inv;
        chain::load(rhs, r);
        chain::eliminate(carry, chain::lower(d), r, chain::lower(s.blk_off[i - 1]), y, gain, inv);
        chain::store(y, s.blk_rhs[i]);
        std::memcpy(s.blk_factor_gain[i].data(), gain, sizeof gain);
    }
    held = last;
    return carry;
}

/// The back substitution of parallelChainStep's halves, outward from the middle particle:
/// x_t = y_t - W_t x_{t+1} above it (t < mid), x_i = y_i - W_i x_{i-1} below it (i > mid),
/// with the gains the sweeps left per particle in blk_factor_gain. The last x is carried
/// in registers, not read back from blk_rhs, where its three stores had to reach the next
/// particle's loads through memory (100 000 segments, two threads: 38 ticks of the TSC a
/// particle read back, 16 carried).
void substituteHalf(StringState& s, std::size_t mid, bool above) {
    double next[3], gain[9], x[3];
    chain::load(s.blk_rhs[mid], next);
    const std::size_t count = above ? mid : s.particles() - 1 - mid;
    for (std::size_t k = 1; k <= count; ++k) {
        const std::size_t p = above ? mid - k : mid + k;
        std::memcpy(gain, s.blk_factor_gain[p].data(), sizeof gain);
        chain::load(s.blk_rhs[p], x);
        chain::substitute(gain, next, x);
        chain::store(x, s.blk_rhs[p]);
        std::copy(x, x + 3, next);
    }
}

/// Moves the free particles in [p0, p1) by their step in blk_rhs (a chain without glued
/// particles); returns the largest squared move.
double applyChainStep(StringState& s, std::size_t p0, std::size_t p1) {
    double worst_squared = 0.0;
    for (std::size_t p = p0; p < p1; ++p) {
        if (fixedRow(s, p)) continue;
        const Vec3& dx = s.blk_rhs[p];
        if (!dx.allFinite()) continue;
        worst_squared = std::max(worst_squared, dx.squaredNorm());
        s.x[p] += dx;
    }
    return worst_squared;
}

/// One Newton iteration of a contact-free chain without glued particles, split over two
/// threads at the middle particle: each half assembles its rows and springs and runs its
/// sweep of solveChain, the middle particle is solved on this thread, and each half then
/// back-substitutes, updates its segments' linearised tension and moves its particles.
/// The sums and products are those of assembleChain and solveChain in the same order
/// (the middle particle's share of segment mid is held back and added in the same place),
/// so the bits are those of the serial iteration. Returns the largest move.
double parallelChainStep(StringState& s, RigidTable& rigids, const StepContext& ctx, ThreadPool& pool) {
    const std::size_t n = s.particles();
    const std::size_t m = s.segments();
    const std::size_t mid = n / 2;
    double* tension_estimate = s.geometric_tension.data();
    SpringTerm held;  // segment mid, whose share of the middle particle waits for it
    chain::Carry<double> top, bottom;
    pool.forEach(2, [&](std::size_t half) {
        if (half == 0) {
            assembleInertia(s, rigids, ctx, mid, mid + 1);  // the others' rows: in the sweeps' registers
            top = sweepFromTop(s, ctx, mid, tension_estimate);
        } else {
            bottom = sweepFromBottom(s, ctx, mid, tension_estimate, held);
        }
    });
    addSprings(SpringTerm{}, held, s.blk_diag[mid], s.blk_rhs[mid]);
    chain::Sym<double> middle_inverse;
    chain::solveMiddle(top, bottom, s.blk_diag[mid], s.blk_rhs[mid], middle_inverse);
    double worst_squared[2] = {0.0, 0.0};
    pool.forEach(2, [&](std::size_t half) {
        if (half == 0) {
            substituteHalf(s, mid, true);
            linearisedTension(s, ctx, 0, mid);
            worst_squared[0] = applyChainStep(s, 0, mid + 1);
        } else {
            substituteHalf(s, mid, false);
            linearisedTension(s, ctx, mid, m);
            worst_squared[1] = applyChainStep(s, mid + 1, n);
        }
    });
    return std::sqrt(std::max(worst_squared[0], worst_squared[1]));
}

/// After a solve: glued particles back on their bodies, the springs' forces in the final
/// state (the tension where bodies press the string) and the row projectors of the
/// particles that rigid bodies press.
void finishChain(StringState& s, const RigidTable& rigids, const StepContext& ctx) {
    const std::size_t m = s.segments();
    const std::size_t n = s.particles();
    // Leave glued particles on their bodies.
    for (std::size_t p = 0; p < n; ++p) {
        const ParticleHold& hold = s.hold[p];
        if (hold.kind == ParticleHold::Kind::Glue) s.x[p] = gluePoint(rigids.bodies[hold.body.index], hold.point);
    }
    // The springs' forces in the final state (the tension where bodies press the string).
    const double rate_gain = s.desc.axial_damping * ctx.inv_h;
    // Two segments at a time, their roots and divisions in lanes (the same bits).
    auto force = [&](std::size_t j, double length) { return std::max(0.0, effectiveStretch(s, j, length - s.rest_length[j], rate_gain)); };
    // A long string's on the pool (forRanges: each segment's force is its own).
    forRanges(ctx.pool, m, kParallelItems, [&](std::size_t j0, std::size_t j1, std::size_t) {
        std::size_t k = j0;
        for (; k + 1 < j1; k += 2) {
            const Lanes2 length = lengthPair(s.x[k + 1] - s.x[k], s.x[k + 2] - s.x[k + 1]);
            const Lanes2 f = Lanes2{force(k, length[0]), force(k + 1, length[1])} / Lanes2{s.compliance[k], s.compliance[k + 1]};
            if (!s.broken[k]) s.spring_force[k] = f[0];
            if (!s.broken[k + 1]) s.spring_force[k + 1] = f[1];
        }
        if (k < j1 && !s.broken[k]) s.spring_force[k] = force(k, (s.x[k + 1] - s.x[k]).norm()) / s.compliance[k];
    });
    // Particles pressed by a body carry an unknown contact force along its normal: the
    // tension solve uses only their equations across the normal (tension.cpp).
    // (All are I already where none was pressed since they were last reset.)
    if (s.rows_pressed)
        for (std::size_t p = 0; p < n; ++p) s.row_projector[p].setIdentity();
    s.rows_pressed = false;
    for (const SegmentContact& c : s.contacts) {
        const std::size_t j = c.segment;
        if (s.broken[j]) continue;
        const Vec3 xs = (1.0 - c.s) * s.x[j] + c.s * s.x[j + 1];
        if (rigidGap(s, c, xs) > kContactSlop * s.radius[j]) continue;  // not touching
        // The contact's force is unknown along the normal and, where friction holds or
        // drags, along the slip.
        Vec3 dirs[2] = {c.plane_normal, Vec3::Zero()};
        if (c.friction_weight > 0.0) {
            const Vec3 slip = rigidSlip(s, c, xs);
            if (slip.norm() > 0.0) dirs[1] = slip.normalized();
        }
        for (const Vec3& along : dirs)
            for (std::size_t q : {j, j + 1}) {
                const Vec3 dir = s.row_projector[q] * along;  // what is left of this direction
                const double len = dir.norm();
                if (len > 1e-6) s.row_projector[q] -= (dir / len) * (dir / len).transpose();
                s.rows_pressed = true;
            }
    }
}

/// warmStart's sums over segments [j0, j1) and particles [p0, p1): the start's inertia
/// (times 2 h^2), and the springs at the prediction (cold) and at the start (warm), their
/// common factor 1 / (2 (1 + tau/h)) taken out; `refused` where a segment is slack at the
/// prediction or not stretched at the start.
struct WarmSums {
    double inertia = 0.0, cold = 0.0, warm = 0.0;
    bool refused = false;
};
WarmSums warmSums(const StringState& s, double rate_gain, std::size_t j0, std::size_t j1, std::size_t p0, std::size_t p1) {
    const Vec3* x = s.x.data();
    const Vec3* shift = s.blk_rhs.data();
    WarmSums sum;
    for (std::size_t p = p0; p < p1; ++p) sum.inertia += s.mass[p] * shift[p].squaredNorm();
    for (std::size_t j = j0; j < j1; ++j) {
        if (s.broken[j]) continue;
        const Vec3 d = x[j + 1] - x[j];
        const Vec3 moved = d + (shift[j + 1] - shift[j]);
        const Lanes2 len = lengthPair(d, moved);
        const double stretch_cold = len[0] - s.rest_length[j];
        const double stretch_warm = len[1] - s.rest_length[j];
        const double effective_cold = effectiveStretch(s, j, stretch_cold, rate_gain);
        const double effective_warm = effectiveStretch(s, j, stretch_warm, rate_gain);
        // Every segment takes part in the solve from the prediction (none slack) and is
        // stretched at the start.
        if (slackSegment(s, j, stretch_cold, effective_cold) || !(stretch_warm > 0.0)) {
            sum.refused = true;
            return sum;
        }
        const double k = 1.0 / s.compliance[j];
        const double c_cold = std::max(0.0, effective_cold), c_warm = std::max(0.0, effective_warm);
        sum.cold += k * c_cold * c_cold;
        sum.warm += k * c_warm * c_warm;
    }
    return sum;
}

/// warmStart's sums are taken in blocks of at least this many segments (at most
/// kWarmBlocks of them), on the pool where a long string has it; the blocks depend on the
/// string's length only, so the sums and the decision are the same on any thread count.
constexpr std::size_t kWarmBlock = kParallelItems;
constexpr std::size_t kWarmBlocks = 64;

/// Moves a chain without contacts or body unknowns from its prediction by the last step's
/// correction (in blk_rhs; zero for held particles), where that is a better start for its
/// Newton iterations (see the file's header); returns whether it did. Not taken:
///  - where the start has no less energy than the prediction (the energy limitStrain
///    minimises: inertia about x' and the springs). A weight let go of would have the
///    correction throw the tip up by the weight's pull; Newton, which takes its full steps
///    in a chain, did not always come back from such a start within its iterations (a
///    released cord flew up instead of hanging still).
///  - where a segment is slack at the prediction or not stretched at the start: the
///    correction is a load's pull, and a chain slack anywhere does not carry its load
///    steadily. From a start that left some segments at or below their rest length,
///    Newton's first step stretched one by 5% (a rope swinging down from the horizontal)
///    and the iterations after spent their time undoing that (12 instead of 4; refusing
///    only starts that left segments slack still gave 6 instead of 4 on 1000 ropes of
///    100 segments swinging down). A slack twisted cord coiling up (the telephone cord)
///    warm-started where it was taut coiled later and less than from its predictions
///    (its final writhe below 2 turns in 3 of 15 runs with perturbed tolerances, against
///    none of 15 without the warm start); taut everywhere or not at all, it coils as
///    before.
bool warmStart(StringState& s, const StepContext& ctx) {
    const std::size_t n = s.particles();
    const std::size_t m = s.segments();
    const double inv_h2 = ctx.inv_h * ctx.inv_h;
    const double rate_gain = s.desc.axial_damping * ctx.inv_h;
    const std::size_t blocks = std::clamp<std::size_t>((m + kWarmBlock - 1) / kWarmBlock, 1, kWarmBlocks);
    WarmSums sums[kWarmBlocks];
    auto block = [&](std::size_t b) {
        const std::size_t j0 = m * b / blocks, j1 = m * (b + 1) / blocks;
        sums[b] = warmSums(s, rate_gain, j0, j1, j0, b + 1 == blocks ? n : j1);
    };
    if (blocks > 1 && ctx.pool && ctx.pool->parallel()) {
        ctx.pool->forEach(blocks, block);
    } else {
        for (std::size_t b = 0; b < blocks; ++b) {
            block(b);
            if (sums[b].refused) return false;
        }
    }
    WarmSums total;
    for (std::size_t b = 0; b < blocks; ++b) {
        if (sums[b].refused) return false;
        total.inertia += sums[b].inertia;
        total.cold += sums[b].cold;
        total.warm += sums[b].warm;
    }
    const double cold = total.cold * (0.5 / (1.0 + rate_gain));
    const double warm = total.warm * (0.5 / (1.0 + rate_gain)) + 0.5 * inv_h2 * total.inertia;
    if (!(warm < cold)) return false;
    forRanges(ctx.pool, n, kParallelItems, [&](std::size_t p0, std::size_t p1, std::size_t) {
        for (std::size_t p = p0; p < p1; ++p) s.x[p] += s.blk_rhs[p];
    });
    return true;
}

}  // namespace

void prepareStrainLimit(StringState& s, RigidTable& rigids, const StepContext& ctx) {
    const std::size_t n = s.particles();
    const std::size_t m = s.segments();
    // The passes over a long string's particles and segments run on the pool (forRanges:
    // per-item writes); only the glued particles' loads on their bodies are applied here,
    // in particle order.
    const bool glued = forRangesAny(ctx.pool, n, kParallelItems, [&](std::size_t p0, std::size_t p1) {
        bool any = false;
        for (std::size_t p = p0; p < p1; ++p) {
            s.glue_impulse[p].setZero();
            const ParticleHold& hold = s.hold[p];
            s.glue_movable[p] = hold.kind == ParticleHold::Kind::Glue && rigids.movable(hold.body);
            any = any || s.glue_movable[p];
        }
        return any;
    });
    if (glued)
        for (std::size_t p = 0; p < n; ++p) {
            if (!s.glue_movable[p]) continue;
            // The glued particle is part of the body now: its weight and force act on it.
            const ParticleHold& hold = s.hold[p];
            RigidState& b = rigids.bodies[hold.body.index];
            const Vec3 load = (s.mass[p] * ctx.gravity + s.force[p]) * (ctx.h * ctx.h);
            applyBodyImpulse(b, s.x[p] - b.position, load);
            s.x[p] = gluePoint(b, hold.point);
        }
    // The last step's correction of the free particles (its end less its prediction),
    // for warmStart, in blk_rhs (limitStrain writes it before it reads it); then the
    // prediction is where the particles start.
    forRanges(ctx.pool, n, kParallelItems, [&](std::size_t p0, std::size_t p1, std::size_t) {
        for (std::size_t p = p0; p < p1; ++p) {
            const Vec3 correction = s.x_prev[p] - s.x_pred[p];
            const bool free = s.hold[p].kind == ParticleHold::Kind::Free;
            s.blk_rhs[p] = free && correction.allFinite() ? correction : Vec3::Zero();
            s.x_pred[p] = s.x[p];
        }
    });
    for (BodyNode& node : s.body_nodes) {
        node.mass = bodyMass(rigids.bodies[node.body.index]);
        node.impulse.setZero();
        node.displacement.setZero();
        node.linearised_at.setZero();
    }
    // The segments' impulses reset and their stretch at the step's start, two roots at a
    // time (one sqrtpd).
    forRanges(ctx.pool, m, kParallelItems, [&](std::size_t j0, std::size_t j1, std::size_t) {
        std::fill(s.impulse.begin() + static_cast<std::ptrdiff_t>(j0), s.impulse.begin() + static_cast<std::ptrdiff_t>(j1), 0.0);
        std::size_t j = j0;
        for (; j + 1 < j1; j += 2) {
            const Lanes2 len = lengthPair(s.x_prev[j + 1] - s.x_prev[j], s.x_prev[j + 2] - s.x_prev[j + 1]);
            s.prev_stretch[j] = len[0] - s.rest_length[j];
            s.prev_stretch[j + 1] = len[1] - s.rest_length[j + 1];
        }
        if (j < j1) s.prev_stretch[j] = (s.x_prev[j + 1] - s.x_prev[j]).norm() - s.rest_length[j];
    });
    s.strain_newton_iterations = 0;
    s.strain_chord_iterations = 0;
    s.strain_warm_start = s.contacts.empty() && s.body_nodes.empty() && !ctx.cold_strain_starts && warmStart(s, ctx);
}

double limitStrain(StringState& s, RigidTable& rigids, const StepContext& ctx) {
    const std::size_t n = s.particles();
    double first_move = -1.0;  // the first iteration's largest move
    const double inv_h2 = ctx.inv_h * ctx.inv_h;
    const double tol = ctx.settings->strain_tolerance;
    const std::size_t nodes = s.body_nodes.size();

    // Body unknowns (contacts with movable bodies): scratch kept in the string (grown to
    // the most nodes seen, never shrunk, so that a running step does not allocate).
    StringState::NodeScratch& scratch = s.node_scratch;
    if (scratch.diag.size() < nodes) {
        scratch.diag.resize(nodes);
        scratch.rhs.resize(nodes);
        scratch.coupling.resize(nodes);
    }
    auto& node_diag = scratch.diag;
    auto& node_rhs = scratch.rhs;
    auto& coupling = scratch.coupling;

    // Contacts with rigid bodies: g >= 0 on linearised planes (linearisePlanes), a stiff
    // one-sided penalty k_c min(0, g)^2 / 2, with x(s) = (1-s) x_j + s x_{j+1}. A movable
    // body takes part with its 6 unknowns and its mass and inertia, so a rope catches a
    // crate with its tension. The penalty only pushes: a contact takes part in an
    // iteration where the current state penetrates it, and a separated contact that the
    // full Newton step would run into joins the Hessian (not the gradient) and the step is
    // solved again, so that the step stops at it instead of passing through it (held as
    // equalities in active-set passes instead, the contacts a pass ignored were found
    // centimetres deep at the next pass, and the passes ran out unconverged).
    linearisePlanes(s, rigids);
    const double stiffest = s.contacts.empty() ? 0.0 : stiffestTerm(s, inv_h2);  // two passes over the string: only for contacts
    for (SegmentContact& c : s.contacts) {
        // Stiff enough to dominate the rope's springs, the particles' and the body's
        // inertia: under a load F it gives way by F / k_c only. Fixed for the step, so
        // that the line search below sees one energy.
        if (c.stiffness > 0.0) continue;
        double kc = stiffest;
        if (c.node >= 0) kc = std::max(kc, inv_h2 / rigids.bodies[c.body.index].inverse_mass);
        c.stiffness = kc * kContactStiffnessFactor;
    }
    auto gapNow = [&](const SegmentContact& c) {
        const std::size_t j = c.segment;
        return rigidGap(s, c, (1.0 - c.s) * s.x[j] + c.s * s.x[j + 1]);
    };
    // The gap after the full step held in blk_rhs and node_step.
    auto gapAfterStep = [&](const SegmentContact& c) {
        const std::size_t j = c.segment;
        auto moved = [&](std::size_t p) { return fixedRow(s, p) ? s.x[p] : Vec3(s.x[p] + s.blk_rhs[p]); };
        const Vec6 step = c.node >= 0 ? s.node_step[static_cast<std::size_t>(c.node)] : Vec6::Zero();
        return rigidGap(s, c, (1.0 - c.s) * moved(j) + c.s * moved(j + 1), &step);
    };

    // A chain without contacts or body unknowns: its Hessian's geometric term takes the
    // linearised tension (starting from the last step's), its system is solved by
    // solveChain, and it stops on a quadratic prediction (see the file's header).
    const bool plain_chain = s.contacts.empty() && nodes == 0;
    if (plain_chain) std::copy(s.spring_force.begin(), s.spring_force.end(), s.geometric_tension.begin());
    // A long one, alone on the pool (not nested in a forEach over strings), is split over
    // two threads (parallelChainStep); glued particles move bodies, so not with those.
    const bool glued = plain_chain && std::any_of(s.hold.begin(), s.hold.end(), [](const ParticleHold& hold) {
        return hold.kind == ParticleHold::Kind::Glue;
    });
    const bool parallel_chain = plain_chain && !glued && n >= kParallelChainParticles && ctx.pool && ctx.pool->parallel();
    // Chord iterations (see the file's header) in a chain of free and pinned particles
    // shorter than kParallelChainParticles: a longer one's iterations are the same on one
    // thread as on two (parallelChainStep), which has none.
    const bool chord_chain = plain_chain && !glued && n < kParallelChainParticles && s.chain_inverse.size() >= 6 * n + 12 && !ctx.newton_strain_only;
    double* const inverses = chord_chain ? s.chain_inverse.data() : nullptr;
    const bool warm_start = s.strain_warm_start;
    // Assembles the Newton system (the chain's, plus the contacts in the Hessian: those
    // marked active) and solves it: the particles' step into blk_rhs, the bodies' into
    // node_step.
    auto solveStep = [&]() {
        assembleChain(s, rigids, ctx, plain_chain ? s.geometric_tension.data() : nullptr);
        for (std::size_t b = 0; b < nodes; ++b) {
            const BodyNode& node = s.body_nodes[b];
            node_diag[b] = node.mass * inv_h2;
            node_rhs[b] = -(node.mass * node.displacement) * inv_h2;
            coupling[b].clear();
        }
        for (const SegmentContact& c : s.contacts) {
            if (!c.active) continue;
            const std::size_t j = c.segment;
            const Vec3& nrm = c.plane_normal;
            const double g = std::min(0.0, gapNow(c));  // the gradient only where it penetrates
            const double kc = c.stiffness;
            const double wa = 1.0 - c.s, wb = c.s;
            const bool fa = !fixedRow(s, j), fb = !fixedRow(s, j + 1);
            addPenaltyRows(s, c, g, fa, fb);
            if (c.node < 0) continue;
            const std::size_t b = static_cast<std::size_t>(c.node);
            const Vec6 au = rigidGapBodyGradient(c);
            node_diag[b] += kc * au * au.transpose();
            node_rhs[b] -= kc * g * au;
            if (fa) coupling[b].emplace_back(j, kc * wa * nrm * au.transpose());
            if (fb) coupling[b].emplace_back(j + 1, kc * wb * nrm * au.transpose());
        }
        // Friction: w/2 |T rel|^2 (T the tangent projector, rel the motion relative to the
        // body): gradient w T rel, Hessian w T on the string's side, w (TJ)^T (TJ) on the
        // body's (J = d rel / d(u, theta)).
        for (const SegmentContact& c : s.contacts) {
            const std::size_t j = c.segment;
            if (!(c.friction_weight > 0.0) || s.broken[j]) continue;
            const bool fa = !fixedRow(s, j), fb = !fixedRow(s, j + 1);
            const FrictionTerm f = addFrictionRows(s, c, fa, fb);
            if (c.node < 0) continue;
            const std::size_t b = static_cast<std::size_t>(c.node);
            const double w = c.friction_weight, wa = 1.0 - c.s, wb = c.s;
            const Vec3& slip = f.slip;
            const Mat36 jb = rigidSlipBodyJacobian(c, f.tangent);
            node_diag[b] += w * jb.transpose() * jb;
            node_rhs[b] -= w * jb.transpose() * slip;
            if (fa) coupling[b].emplace_back(j, (w * wa) * jb);
            if (fb) coupling[b].emplace_back(j + 1, (w * wb) * jb);
        }

        if (plain_chain) {
            solveChain(s, inverses);
            return;
        }
        factorBlockTridiagonal(s);
        solveFactored(s, s.blk_rhs);  // y = A^-1 r
        for (std::size_t b = 0; b < nodes; ++b) s.node_step[b].setZero();
        if (nodes == 0) return;
        // Schur complement on the bodies' unknowns: (D - C^T A^-1 C) du = r_b - C^T y,
        // then dx = y - A^-1 C du. Each body costs six more O(n) solves.
        const std::size_t dim = 6 * nodes;
        Eigen::MatrixXd& schur = scratch.schur;
        Eigen::VectorXd& rs = scratch.rs;
        schur.setZero(static_cast<Eigen::Index>(dim), static_cast<Eigen::Index>(dim));
        rs.resize(static_cast<Eigen::Index>(dim));
        if (s.node_columns.size() < dim) s.node_columns.resize(dim);
        for (std::size_t b = 0; b < nodes; ++b) {
            schur.block<6, 6>(static_cast<Eigen::Index>(6 * b), static_cast<Eigen::Index>(6 * b)) = node_diag[b];
            rs.segment<6>(static_cast<Eigen::Index>(6 * b)) = node_rhs[b];
            for (const auto& [p, blk] : coupling[b]) rs.segment<6>(static_cast<Eigen::Index>(6 * b)) -= blk.transpose() * s.blk_rhs[p];
            for (int col = 0; col < 6; ++col) {
                std::vector<Vec3>& column = s.node_columns[6 * b + static_cast<std::size_t>(col)];
                column.assign(n, Vec3::Zero());
                for (const auto& [p, blk] : coupling[b]) column[p] += blk.col(col);
                solveFactored(s, column);
            }
        }
        for (std::size_t b = 0; b < nodes; ++b)
            for (std::size_t c = 0; c < dim; ++c)
                for (const auto& [p, blk] : coupling[b])
                    schur.block<6, 1>(static_cast<Eigen::Index>(6 * b), static_cast<Eigen::Index>(c)) -=
                        blk.transpose() * s.node_columns[c][p];
        scratch.ldlt.compute(schur);
        Eigen::VectorXd& du = scratch.du;
        du = scratch.ldlt.solve(rs);
        for (std::size_t c = 0; c < dim; ++c) {
            const double f = du[static_cast<Eigen::Index>(c)];
            if (f != 0.0)
                for (std::size_t p = 0; p < n; ++p) s.blk_rhs[p] -= f * s.node_columns[c][p];
        }
        for (std::size_t b = 0; b < nodes; ++b) s.node_step[b] = du.segment<6>(static_cast<Eigen::Index>(6 * b));
    };

    // Impacts are strongly nonlinear (a rope deflected by centimetres in one step): with
    // contacts the solve may take more iterations. Friction's passes: the weights from the
    // last pass's forces and slips (the first pass of a step has none, or a repeated
    // solve's), until they settle.
    const int iterations = ctx.settings->strain_iterations * (s.contacts.empty() ? kChainIterationFactor : kContactIterationFactor);
    bool frictional = false;
    for (const SegmentContact& c : s.contacts) frictional = frictional || c.friction > 0.0;
    for (int pass = 0; pass < (frictional ? kContactPasses : 1); ++pass) {
    bool converged = false;
    double last_move = -1.0;
    bool chord_next = false;  // the next iteration may be a chord iteration
    for (int iter = 0; iter < iterations; ++iter) {
        double worst = 0.0;
        bool stalled = false;
        bool chord = false;  // this iteration is one
        if (parallel_chain) {
            worst = parallelChainStep(s, rigids, ctx, *ctx.pool);
        } else {
            for (SegmentContact& c : s.contacts) c.active = !s.broken[c.segment] && gapNow(c) < 0.0;
            if (chord_next && assembleChainGradient(s, ctx)) {
                chordSolveChain(s, inverses);
                chord = acceptChord(s, last_move);
            }
            if (!chord) solveStep();
            for (int round = 0; round < kPredictRounds; ++round) {
                bool added = false;
                for (SegmentContact& c : s.contacts)
                    if (!c.active && !s.broken[c.segment] && gapAfterStep(c) < 0.0) c.active = added = true;
                if (!added) break;
                solveStep();
            }
            // The springs' curvature changes along a long step (a rope deflected by
            // centimetres) and the penalties switch on along it: backtrack until the (convex)
            // energy decreases. Where no fraction of the step lowers it, the state is the
            // minimum to rounding: stop there, rather than take a step that raises the energy.
            double alpha = 1.0;
            if (!s.contacts.empty()) {
                const double e0 = stepEnergy(s, rigids, ctx, 0.0);
                int halving = 0;
                for (; halving < kLineSearchHalvings && stepEnergy(s, rigids, ctx, alpha) > e0; ++halving) alpha *= 0.5;
                if (halving == kLineSearchHalvings) {
                    alpha = 0.0;
                    stalled = true;
                }
            }
            if (alpha != 1.0)
                for (std::size_t p = 0; p < n; ++p) s.blk_rhs[p] *= alpha;
            for (std::size_t b = 0; b < nodes; ++b) {
                const Vec6 u = alpha * s.node_step[b];
                if (!u.allFinite()) continue;
                BodyNode& node = s.body_nodes[b];
                RigidState& body = rigids.bodies[node.body.index];
                const Vec6 impulse = node.mass * u;
                node.impulse += impulse;
                node.displacement += u;
                body.impulse += impulse.head<3>() * ctx.inv_h;
                displaceBody(body, node.displacement - u - node.linearised_at, node.displacement - node.linearised_at);
                worst = std::max(worst, u.head<3>().norm());
            }
            if (plain_chain) linearisedTension(s, ctx, 0, s.segments());
            // Apply: free particles move, glued ones move their body by the impulse K^-1 dx.
            // The largest move from the largest square (one square root: the same bits).
            double worst_squared = 0.0;
            for (std::size_t p = 0; p < n; ++p) {
                if (fixedRow(s, p)) continue;
                const Vec3& dx = s.blk_rhs[p];
                if (!dx.allFinite()) continue;
                worst_squared = std::max(worst_squared, dx.squaredNorm());
                if (s.hold[p].kind == ParticleHold::Kind::Free) {
                    s.x[p] += dx;
                } else {
                    RigidState& b = rigids.bodies[s.hold[p].body.index];
                    const Vec3 impulse = mobility(s, rigids, p).K.inverse() * dx;
                    s.glue_impulse[p] += impulse;
                    b.impulse += impulse * ctx.inv_h;
                    applyBodyImpulse(b, s.x[p] - b.position, impulse);
                }
            }
            worst = std::max(worst, std::sqrt(worst_squared));
        }
        if (first_move < 0.0) first_move = worst;
        ++s.strain_newton_iterations;
        s.strain_chord_iterations += chord;
        s.strain_warm_start = false;
        // Without contacts the iteration converges quadratically once it is close (each
        // move ~ C times the last one squared): where the moves fall that fast, the move
        // the next iteration would make, predicted with C from the last two, is checked
        // against the tolerance (with a margin of 100) instead of being made. After a
        // chord iteration the next move is predicted linearly, ~2 C m_last times this one
        // (see the file's header), and a move within the tolerance ends the solve only
        // where it fell that fast too.
        const bool quadratic = last_move > 0.0 && worst < kQuadraticRegime * last_move;
        const double margin = kPredictionMargin * worst * worst;
        const bool next_within = plain_chain && quadratic &&
                                 (chord ? 2.0 * margin < tol * s.shortest_rest * last_move
                                        : margin * worst < tol * s.shortest_rest * last_move * last_move);
        // A chord iteration follows the first Newton iteration of a warm start, or a chord
        // iteration whose move fell by kQuadraticRegime or more (see the file's header).
        chord_next = inverses && (iter == 0 ? warm_start : chord && quadratic);
        last_move = worst;
        if (stalled || (worst < tol * s.shortest_rest && (!chord || quadratic)) || next_within) {
            converged = true;
            break;
        }
    }
    if (!frictional) break;
    const double change = weighRigidFriction(s);
    if (converged && change < kFrictionSettled) break;
    }
    for (SegmentContact& c : s.contacts) c.active = !s.broken[c.segment] && gapNow(c) < 0.0;
    finishChain(s, rigids, ctx);
    return std::max(first_move, 0.0);
}

// String-string and self contacts (World::Impl::coupleStrings): the strings that touch
// are solved together. The energy of the cluster is the sum of the strings' own step
// energies (inertia, springs, rigid contacts) plus, per contact between segment j of
// string a at s and segment k of string b at t (b may be a),
//     k_c/2 min(0, g)^2,   g = n . (x_a(s) - x_b(t)) - (r_a + r_b),
//     friction (below),
// with x_a(s) = (1-s) x_j + s x_{j+1}. Its Hessian is block-tridiagonal per string plus
// one rank-1 term k_c u u^T per penetrating contact, u = dg/dx (the four ends, by the
// fractions); the friction adds two more (the tangents). So one Newton step solves
// (A + U K U^T) dx = r by the Woodbury identity with the strings' own factorisations:
//     y = A^-1 r,  Z = A^-1 U,  (K^-1 + U^T Z) z = U^T y,  dx = y - Z z,
// i.e. one O(n) solve per contact direction and a dense system of their number. Both
// sides of a contact move in one solve, with their masses, springs and tensions: the
// impulses are equal and opposite (momentum is exchanged), and a rope resting on a
// clamped rope loads it with its weight instead of dragging it down (a fixed obstacle at
// the other string's predicted position did that). The penalty is one-sided (a contact
// pushes while it penetrates); a contact that the full Newton step would run into joins
// the Hessian before the line search, so that the step stops at it. s, t and n are fixed
// within a pass (a convex problem) and measured again for the next one (the closest
// points; the start-of-step normal where the prediction carried a pair through itself).
// Where the crossing lies at particles of both strings, the four segment pairs there
// are one contact: the pairs whose closest point is the far end of a segment are
// shadowed by the next segment's pair.
//
// Friction is Coulomb's law, lagged as in IPC (Li et al. 2020) and solved as a sequence
// of quadratic problems: with u_t the tangential motion of the two contact points
// relative to each other over the step and F the normal force of the previous pass (or
// the last step), a pass adds w/2 |u_t|^2 with w = mu F / max(|u_t|, eps) taken at its
// start. At the fixed point of the passes that is mu F against sliding, or a stiff
// spring below eps of slip per step (sticking).
//
// Movable bodies are held where the strings' own solves left them (the cluster solve has
// no body unknowns): a rope glued to a crate and lying on another rope keeps the crate's
// motion of its own solve, and what the joint solve changes of a movable body's contact
// forces is not passed to the body. That loses a little momentum where a body presses
// strings that touch each other (a rope wrapped round a free box and crossing itself:
// at most 0.5% of the box's momentum, test FreeBoxThrownAtAFreeRopeNeverGainsEnergy).
// Passing the change on as an impulse afterwards is worse: the penalty is so stiff that
// a micrometre of the joint solve's motion is a large force, which the body, held in the
// solve, never balanced (momentum errors of 400%). Body unknowns in the joint solve would
// remove the loss; left for later.
namespace {

/// Slip of the contact points (relative, per step) below which a string contact sticks,
/// as a fraction of the contact's thickness (the smoothing length eps of friction).
constexpr double kStringSlip = 1e-3;
/// Penalty of a string contact over the stiffest spring (or particle inertia, m / h^2) of
/// its two strings. At rope tensions it gives way by micrometres (F / k), and where a
/// contact cannot be met without stretching a string (a rope pinned back through itself)
/// it gives way as much as the rope stretches, instead of stretching the rope without
/// bound as a contact 100x stiffer than the springs does; such a pair then starts the
/// next step deep and is left to come apart (world.cpp, kStringDeepStart).
constexpr double kStringContactStiffness = 1.0;
/// Axes closer than this fraction of the thickness have no direction of their own.
constexpr double kStringAxisContact = 1e-3;
/// Another pass when a contact's closest points (fractions) or normal moved by more.
constexpr double kStringRelinearise = 1e-3;
/// Times per Newton iteration that contacts the step would hit are added and the step
/// solved again.
constexpr int kStringPredictRounds = 3;
/// When a joint Newton step is solved by one sparse factorisation of the cluster's whole
/// Hessian (sparseClusterStep) instead of the Woodbury identity: past kWoodburyDirections
/// contact directions (normals and friction tangents), or past kWoodburyCachedDirections
/// when directions times the cluster's particles exceed kWoodburyWork. Woodbury costs one
/// chain solve and one stored column of the cluster's length per direction, and a dense
/// system of their number: cheap for the few crossings of ropes lying on each other, but a
/// long rope folded onto itself (the arms of a tear recoiling side by side) makes
/// thousands, and a 5000-segment rope pulled at 10x its rupture load took 28 s in one
/// step (8155 directions: a dense LDL^T of 8155^2 and 1 GB of columns); the sparse
/// factorisation's fill follows where the contacts join the strings (the same step: 5 s,
/// most of it in the Newton iterations of a cluster that does not settle). The tests'
/// clusters stay below both (at most ~190 directions, ~27 000 directions x particles), so
/// their bits are Woodbury's as before.
constexpr std::size_t kWoodburyDirections = 256;
constexpr std::size_t kWoodburyCachedDirections = 64;
constexpr std::size_t kWoodburyWork = 100000;
bool sparseStepPays(std::size_t directions, std::size_t particles) {
    return directions > kWoodburyDirections ||
           (directions > kWoodburyCachedDirections && directions * particles > kWoodburyWork);
}
/// Position accuracy of the joint solve, as a fraction of the thinnest contact.
constexpr double kStringContactTolerance = 1e-5;
/// firstTouch stops within this fraction of the gap of the touch, or after this many
/// advancements (a grazing approach; the direction there is as good).
constexpr double kStringTouchTolerance = 1e-3;
constexpr int kStringTouchIterations = 32;

bool freeParticle(const StringState& s, std::size_t p) { return s.hold[p].kind == ParticleHold::Kind::Free; }

/// How far a segment's real path over the step, from (p0, p1) to (q0, q1), may stray
/// from the straight one (its ends moving linearly): moved by c (its ends' larger travel)
/// while turning by theta, along an arc of that chord it strays from the chord by about
/// c theta / 8 (the sagitta).
double pathStray(const Vec3& p0, const Vec3& p1, const Vec3& q0, const Vec3& q1) {
    const Vec3 u = p1 - p0, v = q1 - q0;
    const double theta = std::atan2(u.cross(v).norm(), u.dot(v));
    const double c = std::sqrt(std::max((q0 - p0).squaredNorm(), (q1 - p1).squaredNorm()));
    return c * theta / 8.0;
}

/// Two segments moving linearly over the step, from (pa0, pa1), (pb0, pb1) at tau = 0 to
/// (a0, a1), (b0, b1) at tau = 1.
struct StraightPaths {
    Vec3 pa0, pa1, pb0, pb1, ta0, ta1, tb0, tb1;
    double r;  ///< the largest relative travel of the ends
    StraightPaths(const Vec3& pa0_, const Vec3& pa1_, const Vec3& pb0_, const Vec3& pb1_, const Vec3& a0,
                  const Vec3& a1, const Vec3& b0, const Vec3& b1)
        : pa0(pa0_), pa1(pa1_), pb0(pb0_), pb1(pb1_), ta0(a0 - pa0_), ta1(a1 - pa1_), tb0(b0 - pb0_), tb1(b1 - pb1_) {
        r = std::sqrt(std::max({(ta0 - tb0).squaredNorm(), (ta0 - tb1).squaredNorm(), (ta1 - tb0).squaredNorm(),
                                (ta1 - tb1).squaredNorm()}));
    }
    /// Where, from `tau` on, the axes first come within `reach` of each other: false when
    /// they never do; else true, with tau there and `normal` the direction from the
    /// second toward the first (the side each is on when they meet). Conservative
    /// advancement: the axes' distance changes over the step by at most r (the closest
    /// points' difference is a convex combination of the ends' differences), so advancing
    /// by (distance - reach) / r of the step never passes the first touch. Stops within
    /// kStringTouchTolerance of `scale` of the touch.
    bool firstTouch(double& tau, double reach, double scale, Vec3& normal) const {
        for (int i = 0; i < kStringTouchIterations; ++i) {
            const SegmentClosest cp =
                closestPointsOfSegments(pa0 + tau * ta0, pa1 + tau * ta1, pb0 + tau * tb0, pb1 + tau * tb1);
            const double ahead = cp.distance - reach;
            if (ahead <= kStringTouchTolerance * scale || i + 1 == kStringTouchIterations) {
                if (!(cp.distance > 0.0)) return false;
                normal = (cp.p - cp.q) / cp.distance;
                return true;
            }
            if (!(r > 0.0)) return false;
            tau += ahead / r;
            if (!(tau <= 1.0)) return false;
        }
        return false;
    }
};

/// The side on which two segments that were apart at the start of the step met during
/// it, as far as the motion from the start tells: true when it does, with `side` the
/// direction from the second toward the first where they met, and `met` whether they
/// did. Their real paths are not known, only that each strays from its straight one by
/// about `stray` (pathStray, both segments' summed), so the straight paths decide only
/// what every path within `stray` of them would: that the pair met at all (the straight
/// paths come within gap - stray: the real ones within gap; never within gap + stray: the
/// real ones never within gap), and on which side of `now` (the direction of the pair at
/// the end) it met, the real meeting lying between the straight paths' touches of
/// gap + stray and gap - stray: decided when those touches, and the touch of the gap
/// itself (`side`), see `now` on the same side.
bool sideMet(const StraightPaths& path, double gap, double stray, const Vec3& now, bool& met, Vec3& side) {
    met = false;
    if (!(stray < gap)) return false;
    double tau = 0.0;
    Vec3 early, late;
    if (!path.firstTouch(tau, gap + stray, gap, early)) return true;  // never within reach
    if (!path.firstTouch(tau, gap, gap, side)) return false;
    if (!path.firstTouch(tau, gap - stray, gap, late)) return false;
    const bool behind = now.dot(side) <= 0.0;
    if ((now.dot(early) <= 0.0) != behind || (now.dot(late) <= 0.0) != behind) return false;
    met = true;
    return true;
}

/// The penalty terms of the string's rigid contacts that penetrate now, without body
/// unknowns (the bodies stay where they are). Their stiffness is the string's own solve's
/// (limitStrain sets it).
void assembleRigidContacts(StringState& s) {
    for (SegmentContact& c : s.contacts) {
        const std::size_t j = c.segment;
        const double g = rigidGap(s, c, (1.0 - c.s) * s.x[j] + c.s * s.x[j + 1]);
        c.active = !s.broken[j] && c.stiffness > 0.0 && g < 0.0;
        if (c.active) addPenaltyRows(s, c, g, freeParticle(s, j), freeParticle(s, j + 1));
    }
    // Their friction, with the weights of the string's own solve (the bodies held).
    for (const SegmentContact& c : s.contacts) {
        const std::size_t j = c.segment;
        if (!(c.friction_weight > 0.0) || s.broken[j]) continue;
        addFrictionRows(s, c, freeParticle(s, j), freeParticle(s, j + 1));
    }
}

/// A factorised chain system for many solves: the block Thomas factorisation of
/// factorBlockTridiagonal with the pivots inverted once (a solve is then mat-vecs only),
/// and a forward sweep that starts at the first nonzero of the right-hand side.
struct ChainSolver {
    std::vector<Mat3> inverse;  // D'_i^-1
    std::vector<char> coupled;  // gain_i != 0
    void factor(StringState& s) {
        factorBlockTridiagonal(s);
        const std::size_t n = s.particles();
        inverse.resize(n);
        coupled.resize(n);
        for (std::size_t i = 0; i < n; ++i) {
            inverse[i] = s.blk_factor[i].solve(Mat3(Mat3::Identity()));
            coupled[i] = s.blk_coupled[i];
        }
    }
    void solve(const StringState& s, std::vector<Vec3>& rhs, std::size_t first = 0) const {
        const std::size_t n = s.particles();
        for (std::size_t i = std::max<std::size_t>(first, 1); i < n; ++i)
            if (coupled[i]) rhs[i] -= s.blk_factor_gain[i] * rhs[i - 1];
        rhs[n - 1] = inverse[n - 1] * rhs[n - 1];
        for (std::size_t i = n - 1; i-- > 0;) rhs[i] = inverse[i] * (rhs[i] - s.blk_off[i] * rhs[i + 1]);
    }
};

}  // namespace

namespace cluster {

/// One entry of a contact direction's gradient u: coefficient of a particle's motion.
struct UEntry {
    std::uint32_t string;
    std::size_t particle;
    Vec3 coef;
};

/// A rank-1 term of the joint Hessian (a contact's normal, or a friction tangent).
struct Direction {
    UEntry u[4];
    int entries = 0;
    double weight = 0.0;             // its Hessian weight (k_c or the friction's)
    std::size_t column[2] = {0, 0};  // offsets of Z in `pool` for its strings
    std::uint32_t string[2] = {0, 0};
    int strings = 0;
};

}  // namespace cluster

/// What solveStringCluster needs besides the strings, kept between calls so that a
/// running step does not allocate (vectors only grow).
struct ClusterScratch::Impl {
    std::vector<double> stiffest;
    std::vector<char> shadowed, was_shadowed;
    std::vector<std::array<std::uint32_t, 4>> keys;
    std::vector<double> friction_weight, previous_weight;
    std::vector<std::size_t> live, candidates;
    std::vector<double> gap_seen, travel_seen;
    std::vector<cluster::Direction> dirs;
    std::vector<Vec3> pool, column;
    std::vector<ChainSolver> solvers;
    std::vector<std::vector<Vec3>> y;
    /// The Woodbury system of `dim` contact directions and its factorisation, one set per
    /// dim up to kCachedDims: Eigen's dynamic matrices keep no spare capacity (a resize to
    /// another size reallocates, and so does LDLT::compute), and the number of directions
    /// changes from step to step, so one shared set allocated ~170 times a step for a rope
    /// draped over another. Each set is allocated when its size first occurs; a running
    /// scene then steps without allocating, with Eigen's LDLT bit for bit as before. When a
    /// size first occurs, the sets up to twice it are made and sized at once (a draped rope's
    /// directions come and go by a few). Larger systems (past 64 directions: ~30 crossings)
    /// share one set, allocating.
    struct Woodbury {
        Eigen::MatrixXd sys;
        Eigen::VectorXd rhs, z;
        Eigen::LDLT<Eigen::MatrixXd> ldlt;
    };
    /// Each string's right-hand side of the Newton system, for sparseClusterStep (the
    /// Woodbury step overwrites blk_rhs); and that step's matrix and factorisation.
    std::vector<std::vector<Vec3>> r;
    std::vector<Eigen::Triplet<double>> triplets;
    Eigen::SparseMatrix<double> hessian;
    Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> sparse;
    Eigen::VectorXd sparse_rhs, sparse_dx;
    static constexpr auto kCachedDims = static_cast<Eigen::Index>(kWoodburyCachedDirections);
    std::vector<std::unique_ptr<Woodbury>> by_dim;  ///< [dim], or [0] for dims past kCachedDims
    Woodbury& woodbury(Eigen::Index dim) {
        if (by_dim.empty()) by_dim.resize(static_cast<std::size_t>(kCachedDims) + 1);
        if (dim > kCachedDims) {
            if (!by_dim[0]) by_dim[0] = std::make_unique<Woodbury>();
            return *by_dim[0];
        }
        if (!by_dim[static_cast<std::size_t>(dim)])
            for (Eigen::Index k = 1; k <= std::min(2 * dim, kCachedDims); ++k) {
                std::unique_ptr<Woodbury>& set = by_dim[static_cast<std::size_t>(k)];
                if (set) continue;
                set = std::make_unique<Woodbury>();
                set->sys.setIdentity(k, k);
                set->rhs.setZero(k);
                set->z.setZero(k);
                set->ldlt.compute(set->sys);
            }
        return *by_dim[static_cast<std::size_t>(dim)];
    }
};

namespace {

/// The joint Newton step of many contact directions: (A + U W U^T) dx = r, A the strings'
/// own block-tridiagonal systems (blk_diag, blk_off as the strings hold them after
/// assembly; fixed rows are identity rows), U W U^T the directions' rank-1 terms, r the
/// right-hand sides kept in sc.r, as one sparse symmetric matrix of the cluster's 3n
/// unknowns, factorised by Eigen's SimplicialLDLT (AMD ordering). The same step as the
/// Woodbury identity's, to rounding. Writes dx into the strings' blk_rhs (zero for
/// particles that are not free); false, with blk_rhs untouched, if the factorisation fails
/// or the step is not finite. It allocates (the pattern is new each time); it only runs
/// for the large clusters of sparseStepPays (past kWoodburyCachedDirections directions,
/// where the Woodbury path allocates too), or where a test asks for it.
bool sparseClusterStep(const std::vector<StringState*>& strings, const std::vector<cluster::Direction>& dirs,
                       ClusterScratch::Impl& sc) {
    std::vector<Eigen::Index> offset(strings.size() + 1, 0);
    for (std::size_t i = 0; i < strings.size(); ++i)
        offset[i + 1] = offset[i] + 3 * static_cast<Eigen::Index>(strings[i]->particles());
    auto add = [&](Eigen::Index row, Eigen::Index col, const Mat3& block) {
        for (Eigen::Index a = 0; a < 3; ++a)
            for (Eigen::Index b = 0; b < 3; ++b)
                if (block(a, b) != 0.0 && row + a >= col + b) sc.triplets.emplace_back(row + a, col + b, block(a, b));
    };
    sc.triplets.clear();
    for (std::size_t i = 0; i < strings.size(); ++i) {
        const StringState& s = *strings[i];
        for (std::size_t p = 0; p < s.particles(); ++p) {
            const Eigen::Index row = offset[i] + 3 * static_cast<Eigen::Index>(p);
            add(row, row, s.blk_diag[p]);
            if (p + 1 < s.particles()) add(row + 3, row, s.blk_off[p].transpose());  // A(p+1, p)
        }
    }
    // A direction's term w u u^T: its entries pairwise (the lower triangle is read).
    for (const cluster::Direction& d : dirs)
        for (int a = 0; a < d.entries; ++a)
            for (int b = 0; b < d.entries; ++b) {
                const Eigen::Index row = offset[d.u[a].string] + 3 * static_cast<Eigen::Index>(d.u[a].particle);
                const Eigen::Index col = offset[d.u[b].string] + 3 * static_cast<Eigen::Index>(d.u[b].particle);
                if (row >= col) add(row, col, d.weight * d.u[a].coef * d.u[b].coef.transpose());
            }
    const Eigen::Index dim = offset.back();
    sc.hessian.resize(dim, dim);
    sc.hessian.setFromTriplets(sc.triplets.begin(), sc.triplets.end());  // sums duplicates
    sc.sparse.compute(sc.hessian);
    if (sc.sparse.info() != Eigen::Success) return false;
    sc.sparse_rhs.resize(dim);
    for (std::size_t i = 0; i < strings.size(); ++i)
        for (std::size_t p = 0; p < strings[i]->particles(); ++p)
            sc.sparse_rhs.segment<3>(offset[i] + 3 * static_cast<Eigen::Index>(p)) = sc.r[i][p];
    sc.sparse_dx = sc.sparse.solve(sc.sparse_rhs);
    if (sc.sparse.info() != Eigen::Success || !sc.sparse_dx.allFinite()) return false;
    for (std::size_t i = 0; i < strings.size(); ++i) {
        StringState& s = *strings[i];
        for (std::size_t p = 0; p < s.particles(); ++p)
            s.blk_rhs[p] = freeParticle(s, p) ? Vec3(sc.sparse_dx.segment<3>(offset[i] + 3 * static_cast<Eigen::Index>(p)))
                                              : Vec3::Zero();
    }
    return true;
}

}  // namespace

ClusterScratch::ClusterScratch() : impl(std::make_unique<Impl>()) {}
ClusterScratch::~ClusterScratch() = default;
ClusterScratch::ClusterScratch(ClusterScratch&&) noexcept = default;
ClusterScratch& ClusterScratch::operator=(ClusterScratch&&) noexcept = default;

void solveStringCluster(const std::vector<StringState*>& strings, std::vector<SegmentContact>& contacts,
                        RigidTable& rigids, const StepContext& ctx, ClusterScratch& work) {
    using cluster::Direction;
    using cluster::UEntry;
    ClusterScratch::Impl& sc = *work.impl;
    const double inv_h2 = ctx.inv_h * ctx.inv_h;
    const std::size_t count = strings.size();
    // The rigid contacts' planes where the bodies are now (other strings' solves may have
    // moved them since this string's own); the bodies stay there in this solve.
    for (StringState* s : strings) linearisePlanes(*s, rigids);
    double shortest = 1e300;
    for (const StringState* s : strings) shortest = std::min(shortest, s->shortest_rest);
    // Converged when no particle moves by more than the strain tolerance of the shortest
    // segment or kStringContactTolerance of the thinnest contact, whichever is larger
    // (the taut-but-slack segments of assembleChain make Newton linear near the end).
    double thinnest = 1e300;
    for (const SegmentContact& c : contacts) thinnest = std::min(thinnest, c.gap);
    const double tol = std::max(ctx.settings->strain_tolerance * shortest, kStringContactTolerance * thinnest);

    // Penalty of a contact: the stiffest spring or particle inertia of either side
    // (kStringContactStiffness).
    std::vector<double>& stiffest = sc.stiffest;
    stiffest.assign(count, 0.0);
    for (std::size_t i = 0; i < count; ++i) {
        const StringState& s = *strings[i];
        stiffest[i] = stiffestTerm(s, inv_h2);
    }
    for (SegmentContact& c : contacts)
        c.stiffness = kStringContactStiffness * std::max(stiffest[c.string], stiffest[c.partner]);

    // Positions along the current Newton step (held in blk_rhs), alpha of the way.
    auto at = [&](const StringState& s, std::size_t p, double alpha) -> Vec3 {
        return freeParticle(s, p) ? Vec3(s.x[p] + alpha * s.blk_rhs[p]) : s.x[p];
    };
    auto sidePoint = [&](const StringState& s, std::size_t j, double f, double alpha) {
        return Vec3((1.0 - f) * at(s, j, alpha) + f * at(s, j + 1, alpha));
    };
    auto startPoint = [](const StringState& s, std::size_t j, double f) {
        return Vec3((1.0 - f) * s.x_prev[j] + f * s.x_prev[j + 1]);
    };
    // A contact whose closest point is the far end of a segment, shared with the next
    // segment that has a contact with the same other segment, is implied by that one (the
    // shared particle lies on both): it is shadowed, so that the four pairs of two
    // strings crossing at particles do not push four times and toggle against each other.
    std::vector<char>& shadowed = sc.shadowed;
    shadowed.assign(contacts.size(), 0);
    std::vector<std::array<std::uint32_t, 4>>& keys = sc.keys;
    keys.resize(contacts.size());
    auto keyOf = [](std::uint32_t sa, std::uint32_t ja, std::uint32_t sb, std::uint32_t jb) {
        std::array<std::uint32_t, 4> k{sa, ja, sb, jb};
        if (std::make_pair(sb, jb) < std::make_pair(sa, ja)) k = {sb, jb, sa, ja};
        return k;
    };
    for (std::size_t i = 0; i < contacts.size(); ++i) {
        const SegmentContact& c = contacts[i];
        keys[i] = keyOf(c.string, c.segment, c.partner, c.partner_segment);
    }
    // Sorted, for the lookups of `exists` (binary searches over the keys themselves: through
    // an index array each step of the search missed the cache twice, and a long rope folded
    // onto itself brings 1e5 contacts, two lookups each per pass).
    std::sort(keys.begin(), keys.end());
    auto exists = [&](std::uint32_t sa, std::int64_t ja, std::uint32_t sb, std::int64_t jb) {
        if (ja < 0 || jb < 0 || ja >= static_cast<std::int64_t>(strings[sa]->segments()) ||
            jb >= static_cast<std::int64_t>(strings[sb]->segments()))
            return false;
        const auto k = keyOf(sa, static_cast<std::uint32_t>(ja), sb, static_cast<std::uint32_t>(jb));
        return std::binary_search(keys.begin(), keys.end(), k) && !strings[sa]->broken[static_cast<std::size_t>(ja)] &&
               !strings[sb]->broken[static_cast<std::size_t>(jb)];
    };
    auto shadow = [&]() {
        for (std::size_t i = 0; i < contacts.size(); ++i) {
            const SegmentContact& c = contacts[i];
            const std::int64_t j = c.segment, k = c.partner_segment;
            // Toward the next segment only, so that two pairs never shadow each other.
            shadowed[i] = (c.s == 1.0 && exists(c.string, j + 1, c.partner, k)) ||
                          (c.partner_s == 1.0 && exists(c.string, j, c.partner, k + 1));
        }
    };
    auto skipped = [&](const SegmentContact& c) {
        return shadowed[static_cast<std::size_t>(&c - contacts.data())] || strings[c.string]->broken[c.segment] ||
               strings[c.partner]->broken[c.partner_segment];
    };
    auto gapAt = [&](const SegmentContact& c, double alpha) {
        const Vec3 pa = sidePoint(*strings[c.string], c.segment, c.s, alpha);
        const Vec3 pb = sidePoint(*strings[c.partner], c.partner_segment, c.partner_s, alpha);
        return c.normal.dot(pa - pb) - c.gap;
    };
    // Relative tangential motion of the contact points over the step.
    auto slipAt = [&](const SegmentContact& c, double alpha) {
        const StringState& a = *strings[c.string];
        const StringState& b = *strings[c.partner];
        Vec3 rel = (sidePoint(a, c.segment, c.s, alpha) - startPoint(a, c.segment, c.s)) -
                   (sidePoint(b, c.partner_segment, c.partner_s, alpha) - startPoint(b, c.partner_segment, c.partner_s));
        return Vec3(rel - c.normal * c.normal.dot(rel));
    };
    // Friction acts where the last pass (or step) found a pressing force.
    auto frictional = [&](const SegmentContact& c) { return c.friction > 0.0 && c.force > 0.0 && !skipped(c); };
    // Friction of a pass: w/2 |u_t|^2 with w = mu F / max(|u_t|, eps) taken at the start
    // of the pass (below), a smooth quadratic, so Newton converges as without it.
    std::vector<double>& friction_weight = sc.friction_weight;
    friction_weight.assign(contacts.size(), 0.0);
    auto frictionEnergy = [&](std::size_t i, double alpha) {
        return 0.5 * friction_weight[i] * slipAt(contacts[i], alpha).squaredNorm();
    };
    auto weighFriction = [&]() {
        for (std::size_t i = 0; i < contacts.size(); ++i) {
            const SegmentContact& c = contacts[i];
            friction_weight[i] = frictional(c) ? c.friction * c.force / std::max(slipAt(c, 0.0).norm(), kStringSlip * c.gap) : 0.0;
        }
    };
    // Closest points and normal at the given positions: the predicted ones in the first
    // pass (the strings' own solves, which ignored each other, may have pulled one
    // through the other), the current ones later (the passes keep them apart). The
    // contact takes the closest-point direction there, which may turn freely while the
    // pair comes into reach (e.g. end against side), unless the positions have carried
    // the pair through itself: then it takes the normal of the side it was on, which the
    // motion from the start of the step tells. A pair that touched at the start is on
    // its start normal's side; one that came into reach during the step, on the side it
    // met the other on, as far as the straight paths from the start tell it for any path
    // within their stray of them (sideMet). Taking the direction now for such a pair (as
    // this code did) pushed it on through itself, against its neighbours' contacts that
    // had not crossed: two arms of a rope meeting head-on at 5 cm a step, their segments
    // nearly parallel, were pushed both ways at once, and the stiff penalties' compromise
    // flung an arm's end at 10 m/s (the ropes gained 0.2-0.8 J; test_string_collision.cpp).
    // Where the straight paths do not tell (strays near the gap: a torn rope whipping
    // round its pin at the speed clamp), only axes that went across each other do: the
    // side of their common perpendicular flipped. (Trusting the straight paths only
    // where each segment strayed from its own by under a tenth of the gap, as this code
    // did at first, split neighbouring pairs between the two rules: of the free rope's
    // arms meeting head-on under the clamped one, the pairs of the segments that turned
    // by 0.24 rad over 4 cm (stray 0.12 of the gap) took the flipped direction while their
    // neighbours, at 0.08, kept their side, and the arms were squeezed through each other
    // at 50 kN.)
    auto linearise = [&](SegmentContact& c, bool predicted) {
        const StringState& a = *strings[c.string];
        const StringState& b = *strings[c.partner];
        const std::vector<Vec3>& xa = predicted ? a.x_pred : a.x;
        const std::vector<Vec3>& xb = predicted ? b.x_pred : b.x;
        const std::size_t j = c.segment, k = c.partner_segment;
        const Vec3 a0 = xa[j], a1 = xa[j + 1], b0 = xb[k], b1 = xb[k + 1];
        const Vec3 pa0 = a.x_prev[j], pa1 = a.x_prev[j + 1], pb0 = b.x_prev[k], pb1 = b.x_prev[k + 1];
        const SegmentClosest cp = closestPointsOfSegments(a0, a1, b0, b1);
        c.s = cp.s;
        c.partner_s = cp.t;
        const Vec3 d = cp.p - cp.q;
        Vec3 side = c.start_normal;
        bool crossed = false;
        if (c.start_distance < c.gap * (1.0 + kContactSlop)) {
            crossed = d.dot(side) <= 0.0;
        } else if (sideMet(StraightPaths(pa0, pa1, pb0, pb1, a0, a1, b0, b1), c.gap,
                           pathStray(pa0, pa1, a0, a1) + pathStray(pb0, pb1, b0, b1), d, crossed, side)) {
            crossed = crossed && d.dot(side) <= 0.0;
        } else if (predicted && cp.distance < c.gap && cp.s > 0.0 && cp.s < 1.0 && cp.t > 0.0 && cp.t < 1.0) {
            const Vec3 m = (a1 - a0).cross(b1 - b0);
            const Vec3 m0 = (pa1 - pa0).cross(pb1 - pb0);
            crossed = m.dot(m0) > 0.0 && m.dot(a0 - b0) * m0.dot(pa0 - pb0) < 0.0;
        }
        if (cp.distance > kStringAxisContact * c.gap && !crossed)
            c.normal = d / cp.distance;
        else if (predicted || crossed)
            c.normal = side;  // else: keep the last pass's normal
    };
    // The (up to four) particle entries of a contact direction e: +e at this side's
    // ends by the fractions, -e at the other side's.
    auto entries = [&](const SegmentContact& c, const Vec3& e, UEntry* out) {
        int k = 0;
        const StringState& a = *strings[c.string];
        const StringState& b = *strings[c.partner];
        if (freeParticle(a, c.segment)) out[k++] = {c.string, c.segment, (1.0 - c.s) * e};
        if (freeParticle(a, c.segment + 1)) out[k++] = {c.string, c.segment + 1, c.s * e};
        if (freeParticle(b, c.partner_segment)) out[k++] = {c.partner, c.partner_segment, -(1.0 - c.partner_s) * e};
        if (freeParticle(b, c.partner_segment + 1)) out[k++] = {c.partner, c.partner_segment + 1, -c.partner_s * e};
        return k;
    };

    for (SegmentContact& c : contacts) {
        linearise(c, true);
    }
    shadow();
    for (SegmentContact& c : contacts) {
        c.active = !skipped(c) && gapAt(c, 0.0) < 0.0;
    }
    weighFriction();
    // Nothing to do where the strings' own solves already keep every pair apart (and no
    // pair pressed at the end of the last step): that state is the joint optimum.
    bool touching = false;
    for (std::size_t i = 0; i < contacts.size(); ++i) touching = touching || contacts[i].active || friction_weight[i] > 0.0;
    if (!touching) return;
    // Scratch: per string the Newton step y and the responses Z of the directions.
    std::vector<Direction>& dirs = sc.dirs;
    std::vector<Vec3>& pool = sc.pool;
    std::vector<Vec3>& scratch = sc.column;
    if (sc.solvers.size() < count) {
        sc.solvers.resize(count);
        sc.y.resize(count);
    }
    std::vector<ChainSolver>& solvers = sc.solvers;
    std::vector<std::vector<Vec3>>& y = sc.y;
    auto zAt = [&](const Direction& d, std::uint32_t string, std::size_t p) -> Vec3 {
        for (int i = 0; i < d.strings; ++i)
            if (d.string[i] == string) return pool[d.column[i] + p];
        return Vec3::Zero();
    };

    // A long rope folded onto itself brings ~1e5-1e6 pairs into its cluster, nearly all
    // of them far apart, and every Newton iteration looked at each several times (the
    // contacts the step runs into, the line search's energies): 14 s of one step. So each
    // contact keeps a lower bound of its gap: the gap last computed, less twice the
    // largest move of any particle since (`travel`: a contact point is a convex
    // combination of two particles, and the normal is a unit vector, so the gap moves by
    // at most the two sides' moves). A contact whose bound clears what a step can close
    // is known to stay apart, and is left out of the loops that would only find that
    // (the same contacts, the same sums, the same bits). `live`: the contacts not skipped
    // in this pass; `candidates`: those of them a step of `reach` could bring to touch,
    // or with friction, in order.
    std::vector<std::size_t>& live = sc.live;
    std::vector<std::size_t>& candidates = sc.candidates;
    std::vector<double>& gap_seen = sc.gap_seen;
    std::vector<double>& travel_seen = sc.travel_seen;
    gap_seen.resize(contacts.size());
    travel_seen.resize(contacts.size());
    double travel = 0.0;
    auto clear = [&](std::size_t ci, double reach) {
        return gap_seen[ci] - (travel - travel_seen[ci]) > reach * (1.0 + 1e-6) + 1e-6 * contacts[ci].gap;
    };
    auto seeGap = [&](std::size_t ci) {
        gap_seen[ci] = gapAt(contacts[ci], 0.0);
        travel_seen[ci] = travel;
        return gap_seen[ci];
    };
    // Twice the largest move of the step held in blk_rhs (infinite if any is not finite,
    // so that nothing is left out).
    auto stepReach = [&]() {
        double largest = 0.0;
        for (const StringState* sp : strings)
            for (std::size_t p = 0; p < sp->particles(); ++p) {
                if (!freeParticle(*sp, p)) continue;
                const double d = sp->blk_rhs[p].squaredNorm();
                largest = std::isfinite(d) ? std::max(largest, d) : std::numeric_limits<double>::infinity();
            }
        return 2.0 * std::sqrt(largest);
    };
    auto findCandidates = [&](double reach) {
        candidates.clear();
        for (std::size_t ci : live)
            if (!clear(ci, reach) || friction_weight[ci] > 0.0) candidates.push_back(ci);
    };
    std::size_t cluster_particles = 0;
    for (const StringState* sp : strings) cluster_particles += sp->particles();
    const int iterations = ctx.settings->strain_iterations * kContactIterationFactor;
    for (int pass = 0; pass < kContactPasses; ++pass) {
        bool converged = false;
        live.clear();
        for (std::size_t ci = 0; ci < contacts.size(); ++ci) {
            if (skipped(contacts[ci])) {
                contacts[ci].active = false;
                continue;
            }
            live.push_back(ci);
            gap_seen[ci] = -std::numeric_limits<double>::infinity();  // not known in this pass
            travel_seen[ci] = 0.0;
        }
        travel = 0.0;
        for (int iter = 0; iter < iterations; ++iter) {
            // Each string's own system (glued particles held: no body unknowns here).
            for (StringState* sp : strings) {
                StringState& s = *sp;
                assembleChain(s, rigids, ctx, nullptr);
                assembleRigidContacts(s);
                for (std::size_t p = 0; p < s.particles(); ++p) {
                    if (freeParticle(s, p)) continue;
                    s.blk_diag[p] = Mat3::Identity();
                    s.blk_rhs[p].setZero();
                    if (p > 0) s.blk_off[p - 1].setZero();
                    if (p < s.segments()) s.blk_off[p].setZero();
                }
                for (auto& step : s.node_step) step.setZero();
            }
            // The contacts' gradients and their directions for the Woodbury step.
            dirs.clear();
            for (std::size_t ci : live) {
                SegmentContact& c = contacts[ci];
                // The penalty k_c/2 min(0, g)^2 is one-sided: it never pulls, so a normal
                // that turned at a corner cannot drag the strings together (contacts held
                // as equalities, as the rigid ones are, did that here).
                const double g = clear(ci, 0.0) ? 1.0 : seeGap(ci);
                c.active = g < 0.0;
                if (c.active) {
                    // Normal: gradient k g u, Hessian k u u^T.
                    UEntry u[4];
                    const int k = entries(c, c.normal, u);
                    for (int i = 0; i < k; ++i) strings[u[i].string]->blk_rhs[u[i].particle] -= c.stiffness * g * u[i].coef;
                    Direction dn;
                    dn.entries = entries(c, c.normal, dn.u);
                    dn.weight = c.stiffness;
                    if (dn.entries > 0) dirs.push_back(dn);
                }
                const double wf = friction_weight[ci];
                if (!(wf > 0.0)) continue;
                // Friction: gradient w u_t on the relative motion, Hessian w (I - n n^T).
                const Vec3 grad = wf * slipAt(c, 0.0);
                // d(rel)/dx has the same entries as the gradient of g with e = I.
                UEntry ug[4];
                const int kg = entries(c, Vec3::Ones(), ug);
                for (int i = 0; i < kg; ++i) {
                    const double f = ug[i].coef.x();  // the fraction (with its sign)
                    strings[ug[i].string]->blk_rhs[ug[i].particle] -= f * grad;
                }
                const Vec3 t1 = c.normal.unitOrthogonal();
                for (const Vec3& t : {t1, Vec3(c.normal.cross(t1))}) {
                    Direction dt;
                    dt.entries = entries(c, t, dt.u);
                    dt.weight = wf;
                    if (dt.entries > 0) dirs.push_back(dt);
                }
            }
            // Factorise every string and solve y = A^-1 r.
            if (sc.r.size() < count) sc.r.resize(count);
            for (std::size_t i = 0; i < count; ++i) {
                StringState& s = *strings[i];
                solvers[i].factor(s);
                sc.r[i] = s.blk_rhs;
                y[i] = s.blk_rhs;
                solvers[i].solve(s, y[i]);
                for (std::size_t p = 0; p < s.particles(); ++p)
                    if (!freeParticle(s, p) || !y[i][p].allFinite()) y[i][p].setZero();
            }
            // Z = A^-1 U, one solve per direction and string it touches (incrementally:
            // directions may be added below).
            pool.clear();
            std::size_t solved = 0;
            auto columns = [&]() {
                for (; solved < dirs.size(); ++solved) {
                    Direction& d = dirs[solved];
                    d.strings = 0;
                    for (int e = 0; e < d.entries; ++e) {
                        bool known = false;
                        for (int i = 0; i < d.strings; ++i) known = known || d.string[i] == d.u[e].string;
                        if (!known) d.string[d.strings++] = d.u[e].string;
                    }
                    for (int i = 0; i < d.strings; ++i) {
                        const StringState& s = *strings[d.string[i]];
                        scratch.assign(s.particles(), Vec3::Zero());
                        std::size_t first = s.particles();
                        for (int e = 0; e < d.entries; ++e)
                            if (d.u[e].string == d.string[i]) {
                                scratch[d.u[e].particle] += d.u[e].coef;
                                first = std::min(first, d.u[e].particle);
                            }
                        solvers[d.string[i]].solve(s, scratch, first);
                        for (std::size_t p = 0; p < s.particles(); ++p)
                            if (!freeParticle(s, p) || !scratch[p].allFinite()) scratch[p].setZero();
                        d.column[i] = pool.size();
                        pool.insert(pool.end(), scratch.begin(), scratch.end());
                    }
                }
            };
            // (K^-1 + U^T Z) z = U^T y, dx = y - Z z (into blk_rhs).
            auto woodbury = [&]() {
                if ((work.always_sparse || sparseStepPays(dirs.size(), cluster_particles)) && sparseClusterStep(strings, dirs, sc))
                    return;
                columns();
                for (std::size_t i = 0; i < count; ++i) strings[i]->blk_rhs = y[i];
                const auto dim = static_cast<Eigen::Index>(dirs.size());
                if (dim == 0) return;
                ClusterScratch::Impl::Woodbury& wb = sc.woodbury(dim);
                Eigen::MatrixXd& sys = wb.sys;
                Eigen::VectorXd& rhs = wb.rhs;
                sys.resize(dim, dim);
                rhs.resize(dim);
                for (Eigen::Index r = 0; r < dim; ++r) {
                    const Direction& dr = dirs[static_cast<std::size_t>(r)];
                    double uy = 0.0;
                    for (int e = 0; e < dr.entries; ++e) uy += dr.u[e].coef.dot(y[dr.u[e].string][dr.u[e].particle]);
                    rhs[r] = uy;
                    for (Eigen::Index col = 0; col < dim; ++col) {
                        const Direction& dc = dirs[static_cast<std::size_t>(col)];
                        double v = 0.0;
                        for (int e = 0; e < dr.entries; ++e) v += dr.u[e].coef.dot(zAt(dc, dr.u[e].string, dr.u[e].particle));
                        sys(r, col) = v;
                    }
                    sys(r, r) += 1.0 / dr.weight;
                }
                // Symmetric to rounding; LDLT reads the lower triangle only.
                wb.ldlt.compute(sys);
                Eigen::VectorXd& z = wb.z;
                z = wb.ldlt.solve(rhs);
                if (!z.allFinite()) return;
                for (Eigen::Index r = 0; r < dim; ++r) {
                    const Direction& d = dirs[static_cast<std::size_t>(r)];
                    for (int i = 0; i < d.strings; ++i) {
                        std::vector<Vec3>& dx = strings[d.string[i]]->blk_rhs;
                        const Vec3* zc = &pool[d.column[i]];
                        for (std::size_t p = 0; p < dx.size(); ++p) dx[p] -= z[r] * zc[p];
                    }
                }
            };
            woodbury();
            findCandidates(stepReach());
            // A separated contact that the full step would drive into penetration joins
            // the Hessian (not the gradient: it does not push yet) and the step is solved
            // again, so that the step stops at it instead of the line search shrinking to
            // nothing against a penalty that switches on (a contact touching exactly).
            for (int round = 0; round < kStringPredictRounds; ++round) {
                bool added = false;
                for (std::size_t ci : candidates) {
                    SegmentContact& c = contacts[ci];
                    if (c.active || !(gapAt(c, 1.0) < 0.0)) continue;
                    c.active = true;
                    Direction dn;
                    dn.entries = entries(c, c.normal, dn.u);
                    dn.weight = c.stiffness;
                    if (dn.entries > 0) {
                        dirs.push_back(dn);
                        added = true;
                    }
                }
                if (!added) break;
                woodbury();
                findCandidates(stepReach());
            }
            // Backtracking line search on the cluster's energy (the contacts left out of
            // `candidates` stay apart along the whole step: no penalty, no friction).
            auto energy = [&](double alpha) {
                double e = 0.0;
                for (const StringState* s : strings) e += stepEnergy(*s, rigids, ctx, alpha);
                for (std::size_t ci : candidates) {
                    const SegmentContact& c = contacts[ci];
                    const double g = std::min(0.0, gapAt(c, alpha));
                    e += 0.5 * c.stiffness * g * g;
                    if (friction_weight[ci] > 0.0) e += frictionEnergy(ci, alpha);
                }
                return e;
            };
            double alpha = 1.0;
            const double e0 = energy(0.0);
            for (int halving = 0; halving < 10 && energy(alpha) > e0; ++halving) alpha *= 0.5;
            double worst = 0.0;
            for (StringState* sp : strings)
                for (std::size_t p = 0; p < sp->particles(); ++p) {
                    if (!freeParticle(*sp, p)) continue;
                    const Vec3 dx = alpha * sp->blk_rhs[p];
                    if (!dx.allFinite()) continue;
                    sp->x[p] += dx;
                    worst = std::max(worst, dx.norm());
                }
            travel += 2.0 * worst;
            if (worst < tol) {
                converged = true;
                break;
            }
        }
        // The pressing forces (the friction bound of the next pass), then the closest
        // points again: another pass while they moved.
        bool changed = false;
        double moved = 0.0;
        for (SegmentContact& c : contacts) c.force = skipped(c) ? 0.0 : c.stiffness * std::max(0.0, -gapAt(c, 0.0));
        for (SegmentContact& c : contacts) {
            const std::size_t i = static_cast<std::size_t>(&c - contacts.data());
            if (strings[c.string]->broken[c.segment] || strings[c.partner]->broken[c.partner_segment]) continue;
            const double s0 = c.s, t0 = c.partner_s;
            const Vec3 n0 = c.normal;
            linearise(c, false);
            if (!shadowed[i]) moved = std::max({moved, std::abs(c.s - s0), std::abs(c.partner_s - t0), (c.normal - n0).norm()});
        }
        std::vector<char>& was_shadowed = sc.was_shadowed;
        was_shadowed = shadowed;
        shadow();
        changed = was_shadowed != shadowed;
        for (SegmentContact& c : contacts) c.active = !skipped(c) && gapAt(c, 0.0) < 0.0;
        // The friction weights follow the new forces and slips: the fixed point of the
        // passes is Coulomb's law (mu F while sliding, a stiff spring below eps).
        std::vector<double>& previous = sc.previous_weight;
        previous = friction_weight;
        weighFriction();
        for (std::size_t i = 0; i < contacts.size(); ++i) {
            const double a = previous[i], b = friction_weight[i];
            if (std::abs(a - b) > kStringRelinearise * std::max(a, b)) changed = true;
        }
        changed = changed || moved > kStringRelinearise;
        if (!changed && converged) break;
    }
    // Springs' forces and rigid row projectors of the final state; the particles a string
    // contact presses lose the contact force's direction from their tension equations.
    for (StringState* sp : strings) finishChain(*sp, rigids, ctx);
    for (const SegmentContact& c : contacts) {
        if (skipped(c) || gapAt(c, 0.0) > kContactSlop * c.gap) continue;
        Vec3 dirs_c[2] = {c.normal, Vec3::Zero()};
        if (frictional(c)) {
            const Vec3 slip = slipAt(c, 0.0);
            if (slip.norm() > 0.0) dirs_c[1] = slip / slip.norm();
        }
        UEntry u[4];
        const int k = entries(c, Vec3::Ones(), u);
        for (int i = 0; i < k; ++i) {
            StringState& s = *strings[u[i].string];
            for (const Vec3& dir : dirs_c) {
                const Vec3 left = s.row_projector[u[i].particle] * dir;  // what is left of it
                const double len = left.norm();
                if (len > 1e-6) s.row_projector[u[i].particle] -= (left / len) * (left / len).transpose();
                s.rows_pressed = true;
            }
        }
    }
}

}  // namespace tearables::detail
