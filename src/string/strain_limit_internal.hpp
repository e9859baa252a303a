// Internal to the strain-limit solve: what its three files share. strain_limit.cpp is the
// Newton driver (energy, assembly, iterations), contact_rows.cpp the rigid contacts' rows,
// cluster_solve.cpp the joint solve of strings that touch each other.
#pragma once

#include "linalg/block_tridiagonal.hpp"
#include "sim/body_motion.hpp"
#include "string/plastic_spring.hpp"
#include "string/string_state.hpp"

#include <Eigen/Core>

#include <algorithm>
#include <cstddef>

namespace tearables::detail {

/// Passes of the contact solves (rigid friction's weights; the joint string solve's
/// closest points and friction), and the iteration budget of a pass with contacts
/// relative to WorldSettings::strain_iterations.
constexpr int kContactPasses = 4;
/// Passes of a string's own solve with friction on rigid bodies: a contact new this step
/// has no friction in the first (no normal force known yet), one the last step had takes
/// that step's force (ContactMemory); each next pass the normal forces of the last, until
/// the friction found obeys Coulomb's law with the normal forces found (weighRigidFriction).
/// A rope laid a full turn round a drum at once settles in 5-8 (the capstan test,
/// tests/string/test_capstan.cpp; 4 held it at 1.05 e^(mu theta)); a rope resting on the
/// ground, in one.
constexpr int kRigidFrictionPasses = 8;
constexpr int kContactIterationFactor = 4;
/// A segment within this fraction of its radius of a body (or of the contact's thickness)
/// counts as touching it.
constexpr double kContactSlop = 0.1;

inline bool freeParticle(const StringState& s, std::size_t p) { return s.hold[p].kind == ParticleHold::Kind::Free; }

// --- rigid-contact rows (contact_rows.cpp) ---------------------------------------------

/// Linearises the string's contact planes where the bodies are now (the start of a solve).
void linearisePlanes(StringState& s, const RigidTable& rigids);
/// The gap of contact c (linearised by linearisePlanes) at string point xs: >= 0 when the
/// string is clear of the plane. `extra`: a further displacement of the body (a trial step).
double rigidGap(const StringState& s, const RigidSegmentContact& c, const Vec3& xs, const Vec6* extra = nullptr);
/// The gradient of rigidGap with respect to the body's displacement (u, theta).
Vec6 rigidGapBodyGradient(const RigidSegmentContact& c);
/// The tangential motion u_t of contact c over the step (relative to the body), with the
/// string's contact point at xs and the body moved by `extra` beyond its displacement.
Vec3 rigidSlip(const StringState& s, const RigidSegmentContact& c, const Vec3& xs, const Vec6* extra = nullptr);
/// IPC's friction mollifier (contact_rows.cpp) at slip y >= 0 with smoothing eps > 0:
/// f0(y), f1(y) / y and f1'(y), f1 = f0'.
struct Mollifier {
    double f0 = 0.0, f1_over_y = 0.0, df1 = 0.0;
};
Mollifier mollify(double y, double eps);
/// Friction's eps of contact c (the slip a step below which it sticks): kRigidSlip of its
/// thickness, m.
double slipSmoothing(const RigidSegmentContact& c);
/// d(u_t)/d(body displacement): T [-I, [arm]x], T the tangent projector.
Mat36 rigidSlipBodyJacobian(const RigidSegmentContact& c, const Mat3& tangent);
/// Rigid contact c's penalty k_c g^2 / 2 on the string's own rows (g: its gap, or 0 where
/// it only joins the Hessian) at the segment's ends that move (`fa`, `fb`).
void addPenaltyRows(StringState& s, const RigidSegmentContact& c, double g, bool fa, bool fb);
/// Rigid contact c's friction D = mu N f0(|u_t|) (contact_rows.cpp; N its lagged
/// friction_normal) at slip u_t: T the tangent projector, and D's gradient and Hessian
/// (positive semidefinite, on the tangent plane) in u_t.
struct FrictionTerm {
    Mat3 tangent;
    Vec3 slip;  ///< u_t
    Vec3 gradient;
    Mat3 hessian;
};
FrictionTerm rigidFrictionTerm(const RigidSegmentContact& c, const Vec3& slip);
/// Whether contact c has friction in the current pass (a normal force, or a lagged weight).
bool hasFriction(const RigidSegmentContact& c);
/// D = mu N f0(|u_t|) of contact c at slip u_t (0 without friction or normal force), or
/// the lagged form's w/2 |u_t|^2 (RigidSegmentContact::lagged), J.
double rigidFrictionEnergy(const RigidSegmentContact& c, const Vec3& slip);
/// The friction force on the string that the last solve balanced, -dD/du_t at slip u_t
/// with its normal force (or weight), N.
Vec3 solvedFrictionForce(const RigidSegmentContact& c, const Vec3& slip);
/// Rigid contact c's friction on the string's own rows, at the segment's ends that move
/// (`fa`, `fb`). Returns its rigidFrictionTerm.
FrictionTerm addFrictionRows(StringState& s, const RigidSegmentContact& c, bool fa, bool fb);
/// How far a contact's friction force `applied` misses Coulomb's law with its bound mu N
/// (`bound`), at `slip` against the smoothing eps: a sliding contact's |f - mu N|, a
/// sticking one's excess over mu N, relative to mu N, or to kNegligibleFriction of
/// `largest_bound` (the largest mu N of the string or cluster) where that is more; 0 where
/// both are 0. The measure that ends friction's passes (weighRigidFriction, the string-pair
/// solve).
double coulombMiss(double applied, double bound, double slip, double eps, double largest_bound);
/// Friction's passes end once no contact's coulombMiss is over this fraction (a string's
/// own solve, the string-pair solve).
constexpr double kFrictionSettled = 1e-2;
/// Friction's normal forces for the next pass: each contact's penalty force now. Returns
/// how far the pass's friction missed Coulomb's law with these forces: the largest miss of
/// a contact (a sliding one's |f - mu N|, a sticking one's excess over mu N) relative to
/// its mu N, or to kNegligibleFriction of the string's largest where that is more.
/// `in_island` (an island's members): friction with a static body is the lagged quadratic
/// w/2 |u_t|^2 with w = mu N / max(|u_t|, eps) from the slip now (StringIslandMember::start).
double weighRigidFriction(StringState& s, bool in_island);
/// The penalty and friction rows of the string's rigid contacts that penetrate now, without
/// body unknowns (the bodies stay where they are), with the string's own solve's stiffness
/// and friction weights.
void assembleRigidContacts(StringState& s);
/// The stiffest spring or particle inertia (m / h^2) of a string, N/m: what its contact
/// penalties are scaled from.
double stiffestTerm(const StringState& s, double inv_h2);

// --- the chain's Newton system (strain_limit.cpp) ----------------------------------------

/// The Newton system of the chain without contacts (inertia rows and stretched springs)
/// into blk_diag, blk_off, blk_rhs. `tension_estimate` (per segment, may be null): the
/// tension of the Hessian's geometric term (see limitStrain).
void assembleChain(StringState& s, RigidTable& rigids, const StepContext& ctx, double* tension_estimate);
/// A chord iteration's right-hand side: assembleChain's gradient into blk_rhs, its Hessian
/// left as the last factorisation took it. False where a segment's branch (slack, elastic,
/// plastic) changed since that assembly.
bool assembleChainGradient(StringState& s, const StepContext& ctx);
/// The energy the Newton iteration minimises at the current state moved by alpha times the
/// step held in blk_rhs (particles) and node_step (bodies).
double stepEnergy(const StringState& s, const RigidTable& rigids, const StepContext& ctx, double alpha);
/// Adds to `e` the springs' energy and the rigid contacts' (penalty and friction) at trial
/// positions trial(p), the touched bodies moved by alpha times their node_step: the part
/// of the step's energy that stepEnergy and an island member (string_island.cpp) share.
template <class Trial>
double addMaterialEnergy(const StringState& s, const StepContext& ctx, double alpha, const Trial& trial, double e) {
    const double rate_gain = s.desc.axial_damping * ctx.inv_h;
    for (std::size_t j = 0; j < s.segments(); ++j) {
        if (s.broken[j]) continue;
        const double stretch = (trial(j + 1) - trial(j)).norm() - s.rest_length[j];
        const double effective = std::max(0.0, stretch + rate_gain * (stretch - s.prev_stretch[j]));
        // psi(c) / (1 + tau/h): its derivative in the length is the force f(c) (c grows by
        // 1 + tau/h per metre); psi = k c^2 / 2 on the elastic branch (plastic_spring.hpp).
        if (s.scratch.plastic_in_solve) {
            e += springEnergyOverStiffness(s, j, effective) / (s.compliance[j] * (1.0 + rate_gain));
            continue;
        }
        e += 0.5 / (s.compliance[j] * (1.0 + rate_gain)) * effective * effective;
    }
    for (const RigidSegmentContact& c : s.contacts) {
        const std::size_t j = c.segment;
        if (s.broken[j] || c.stiffness <= 0.0) continue;
        const Vec3 xs = (1.0 - c.s) * trial(j) + c.s * trial(j + 1);
        Vec6 extra = Vec6::Zero();
        if (c.node >= 0) extra = alpha * s.scratch.node_step[static_cast<std::size_t>(c.node)];
        const double g = std::min(0.0, rigidGap(s, c, xs, &extra));
        e += 0.5 * c.stiffness * g * g;
        if (hasFriction(c)) e += rigidFrictionEnergy(c, rigidSlip(s, c, xs, &extra));
    }
    return e;
}
/// After a solve: glued particles back on their bodies, the springs' forces in the final
/// state and the row projectors of the particles that rigid bodies press.
void finishChain(StringState& s, const RigidTable& rigids, const StepContext& ctx);

/// Each rigid contact's penalty stiffness for this step (where not set yet): stiff enough
/// to dominate the rope's springs, the particles' and the body's inertia, fixed for the
/// step so that a line search sees one energy.
void setContactStiffness(StringState& s, const RigidTable& rigids, double inv_h2);
/// One round of the predicted contacts' active set, for the Newton step in blk_rhs (and
/// the bodies' in node_step): a separated contact the step runs into is held (active,
/// predicted: its gap carried in the model), one held before that the step no longer runs
/// into is let go. Returns whether any changed (the step is then solved again).
/// `held_step`, per particle, moves the rows the solve holds fixed (an island's glued
/// particles, with their bodies); none: they stay.
bool predictContacts(StringState& s, const std::vector<Vec3>* held_step = nullptr);
/// The same for the slack segments: those that the Newton step in blk_rhs (`held_step`
/// for the rows the solve holds) stretches are marked in scratch.predicted_taut, those it
/// no longer stretches unmarked; the chain's assembly then puts their springs in the model
/// with their slack carried (springForce). Returns whether any mark changed.
bool predictSprings(StringState& s, const StepContext& ctx, const std::vector<Vec3>* held_step);
/// The body nodes' rows of the active contacts' penalties and of all contacts' friction:
/// added to `nodes` (diag, rhs, coupling; the caller zeroes or seeds them) and, on the
/// string's side, to blk_diag and blk_rhs.
void assembleContactCoupling(StringState& s, StringScratch::NodeScratch& nodes);
/// After factorChain and y = A^-1 r in blk_rhs: the Schur complement of the chain on its
/// body nodes, D - C^T A^-1 C into nodes.schur, r_b - C^T y into nodes.rs, and the
/// columns A^-1 C into node_columns.
void condenseNodes(StringState& s, StringScratch::NodeScratch& nodes);
/// condenseNodes' right-hand side alone, r_b - C^T y into nodes.rs (y = A^-1 r in blk_rhs,
/// the couplings C in nodes.coupling).
void condenseNodesRhs(const StringState& s, StringScratch::NodeScratch& nodes);
/// The particles' step for the bodies' step du (6 per node): dx = y - A^-1 C du in
/// blk_rhs, du into node_step.
void backSubstituteNodes(StringState& s, const Eigen::VectorXd& du);
/// Segment j's spring (Hessian, force pulling j toward j + 1) where it is stretched or
/// taut; false where it carries nothing (slack or broken).
bool springRow(StringState& s, const StepContext& ctx, std::size_t j, Mat3& hess, Vec3& force);
/// True when particle p does not move in the string's own rows: pinned, glued to an
/// immovable body, or glued to a body of an island (the island moves it with the body).
inline bool fixedRow(const StringState& s, std::size_t p) {
    const ParticleHold& hold = s.hold[p];
    return hold.kind == ParticleHold::Kind::Pin ||
           (hold.kind == ParticleHold::Kind::Glue && (!s.glue_movable[p] || s.island_glue));
}
/// Where particle p goes by the Newton step in blk_rhs: a free particle by its step, a row
/// the solve holds by `held_step` where given (an island's glued particle, with its body),
/// else nowhere. predictContacts and predictSprings test their active sets here.
inline Vec3 steppedPosition(const StringState& s, std::size_t p, const std::vector<Vec3>* held_step) {
    if (!fixedRow(s, p)) return s.x[p] + s.scratch.blk_rhs[p];
    return held_step ? Vec3(s.x[p] + (*held_step)[p]) : s.x[p];
}

/// factorBlockTridiagonal of the string's system (blk_diag, blk_off) into blk_factor,
/// blk_factor_gain and blk_coupled.
inline void factorChain(StringState& s) {
    const std::size_t n = s.particles();
    s.scratch.blk_factor.resize(n);
    s.scratch.blk_coupled.resize(n);
    factorBlockTridiagonal(n, s.scratch.blk_diag.data(), s.scratch.blk_off.data(), s.scratch.blk_factor.data(),
                           s.scratch.blk_factor_gain.data(), s.scratch.blk_coupled.data());
}

}  // namespace tearables::detail
