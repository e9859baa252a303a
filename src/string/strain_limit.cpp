// Strain limiting and rigid attachments: one Newton solve per chain (the strain-limit
// stage of StringSystem::step).
//
// Strings Sec. 5.2 limits every segment to L <= L_max by sweeping corrections from the
// clamped ends; we take the exact mass-weighted projection instead, which covers the
// paper's three cases (one end, both ends, several points clamped) at once:
//
//   x = argmin  sum_p m_p/(2h^2) |x_p - x'_p|^2  +  sum_j k_j/2 max(0, |x_{j+1}-x_j| - L_j)^2
//
// backward Euler on segments of stiffness k_j = E A / L_j (the compliance form, which meets
// L_max = L (1 + sigma/E) of Sec. 5.4 within the solve). Newton with each stretched
// segment's geometric stiffness gives a symmetric block-tridiagonal system, O(n)
// (linalg/block_tridiagonal). Without contacts the geometric term takes the first-order
// tension k (C + e . (dx_{j+1} - dx_j)), or k C where smaller (k C of a stiff spring
// overstates it by a transverse move's second-order stretch), and chord iterations reuse
// the factorisation (rate ~2 m_c / m_N). Pinned particles are fixed rows; a glued particle
// carries its body's effective mass K^-1, K = 1/M - [r]x I^-1 [r]x. Rigid contacts:
// contact_rows.cpp; strings touching each other: cluster_solve.cpp.
#include "base/lanes.hpp"
#include "base/thread_pool.hpp"
#include "string/plastic_spring.hpp"
#include "string/strain_limit_internal.hpp"

#include <Eigen/Cholesky>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

namespace tearables::detail {

namespace {
/// A segment shorter than its rest length by less than this fraction counts as taut.
constexpr double kTautSlack = 1e-4;
/// The active mark of a slack segment put in the model by prediction (springForce): none
/// of springBranch's, so that a chord iteration sees the change when it becomes taut.
constexpr std::uint8_t kPredictedTaut = 4;
/// Contact penalty over the stiffest spring, particle and body inertia it competes with.
constexpr double kContactStiffnessFactor = 100.0;
/// The iteration budget of a contact-free chain relative to WorldSettings::strain_iterations
/// (the setting is the cloth's budget too): room for the transients of a sagging rope whose
/// segments go slack and taut, where a step that stops unconverged feeds an oscillation.
constexpr int kChainIterationFactor = 2;
/// A contact-free chain stops when its moves fall by this factor or more per iteration and
/// the next move, predicted quadratically and times kPredictionMargin, is within tolerance.
constexpr double kQuadraticRegime = 0.1;
constexpr double kPredictionMargin = 100.0;
/// A contact-free chain of at least this many particles and no glued ones is split over
/// two threads where the world has them (limitStrain, parallelChainStep): each half's
/// assembly, sweep and back substitution on one.
constexpr std::size_t kParallelChainParticles = kParallelItems;
/// Halvings of a Newton step before the line search gives up (the energy is at its
/// minimum to rounding along the step).
constexpr int kLineSearchHalvings = 30;
/// Times per Newton iteration that contacts the step would run into are added and the
/// step solved again.
constexpr int kPredictRounds = 4;
/// The relative rounding of a string's step energy (a sum over its particles and
/// segments) that a line search of a string yielding in the solve does not count as a rise.
constexpr double kEnergyRounding = 1e-12;

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


/// Segment j's stretch C with the material's rate term (Kelvin-Voigt, see springTerm):
/// C + (tau/h) (C - C_prev), the stretch its force and energy take.
inline double effectiveStretch(const StringState& s, std::size_t j, double stretch, double rate_gain) {
    return stretch + rate_gain * (stretch - s.prev_stretch[j]);
}

/// Whether segment j, at stretch C and effective stretch `effective`, is slack: shorter
/// than kTautSlack of its rest length and not stretching. A slack segment carries nothing
/// and takes no part in the solve (springTerm).
inline bool slackSegment(const StringState& s, std::size_t j, double stretch, double effective) {
    const double band = s.scratch.exact_slack ? 0.0 : kTautSlack;
    return stretch <= -band * s.rest_length[j] && effective <= 0.0;
}

/// solveFactored of the string's factorised system (factorChain) for `rhs` (n) in place;
/// rhs is zero above row `first`.
void solveFactored(const StringState& s, std::vector<Vec3>& rhs, std::size_t first = 0) {
    solveFactored(s.particles(), s.scratch.blk_off.data(), s.scratch.blk_factor.data(), s.scratch.blk_factor_gain.data(),
                  s.scratch.blk_coupled.data(), rhs.data(), first);
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

}  // namespace

/// The energy the Newton iteration minimises, at the current state moved by alpha times
/// the step held in blk_rhs (particles) and node_step (bodies): inertia of particles,
/// glued bodies and touched bodies, the material's springs and the contact penalties.
double stepEnergy(const StringState& s, const RigidTable& rigids, const StepContext& ctx, double alpha) {
    const std::size_t n = s.particles();
    const double inv_h2 = ctx.inv_h * ctx.inv_h;
    double e = 0.0;
    auto trial = [&](std::size_t p) -> Vec3 { return fixedRow(s, p) ? s.x[p] : Vec3(s.x[p] + alpha * s.scratch.blk_rhs[p]); };
    for (std::size_t p = 0; p < n; ++p) {
        if (fixedRow(s, p)) continue;
        if (s.hold[p].kind == ParticleHold::Kind::Free) {
            e += 0.5 * s.inertia_gain * s.mass[p] * inv_h2 * (trial(p) - s.x_pred[p]).squaredNorm();
        } else {  // glued to a movable body: its displacement this step is K P
            const Mat3 k = mobility(s, rigids, p).K;
            const Vec3 u = k * s.glue_impulse[p] + alpha * s.scratch.blk_rhs[p];
            e += 0.5 * inv_h2 * u.dot(k.ldlt().solve(u));
        }
    }
    for (std::size_t b = 0; b < s.body_nodes.size(); ++b) {
        const BodyNode& node = s.body_nodes[b];
        const Vec6 u = node.displacement + alpha * s.scratch.node_step[b];
        e += 0.5 * inv_h2 * u.dot(node.mass * u);
    }
    return addMaterialEnergy(s, ctx, alpha, trial, e);
}

namespace {

/// A free particle's inertia row's right-hand side: toward its prediction x'.
inline Vec3 inertiaRhs(const StringState& s, std::size_t p, double inv_h2) {
    return -(s.inertia_gain * s.mass[p] * inv_h2) * (s.x[p] - s.x_pred[p]);
}

/// The inertia row of a free or pinned particle p, as assembleInertia writes it, into d
/// and rhs (a sweep's registers: parallelChainStep's halves assemble it as they go).
inline void inertiaRow(const StringState& s, std::size_t p, double inv_h2, Mat3& d, Vec3& rhs) {
    if (s.hold[p].kind == ParticleHold::Kind::Free) {
        d = (s.inertia_gain * s.mass[p] * inv_h2) * Mat3::Identity();
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
    // A glued particle carries its body's effective mass K^-1 at the glue point and starts
    // each iteration on the body (which absorbed the earlier corrections).
    for (std::size_t p = p0; p < p1; ++p) {
        const ParticleHold& hold = s.hold[p];
        s.scratch.blk_rhs[p].setZero();
        switch (hold.kind) {
            case ParticleHold::Kind::Free:
                inertiaRow(s, p, inv_h2, s.scratch.blk_diag[p], s.scratch.blk_rhs[p]);
                break;
            case ParticleHold::Kind::Glue:
                s.x[p] = gluePoint(rigids.bodies[hold.body.index], hold.point);
                if (s.glue_movable[p] && !s.island_glue) {
                    // The body's inertia resists this string's own accumulated pull
                    // (what other strings did to the body is, for this string, part
                    // of the body's prediction): M_eff (x - x') / h^2 = P / h^2.
                    s.scratch.blk_diag[p] = mobility(s, rigids, p).K.inverse() * inv_h2;
                    s.scratch.blk_rhs[p] = -s.glue_impulse[p] * inv_h2;
                    break;
                }
                [[fallthrough]];
            case ParticleHold::Kind::Pin:
                s.scratch.blk_diag[p] = Mat3::Identity();  // fixed: its row is dx = 0
                break;
        }
    }
}

/// springTerm's part after the segment's length, direction and stiffness (`len`, `e`
/// candidate for dir, `k` = 1 / compliance): everything but the Hessian's one division.
/// Returns whether the term needs its Hessian (not where the segment is broken or slack,
/// nor without kHessian), with the stretch its geometric part takes in `geometric` and the
/// axial tangent over k in `axial` (1 on the elastic branch).
template <bool kHessian>
[[gnu::always_inline]] inline bool springForce(StringState& s, const StepContext& ctx, std::size_t j, double* tension_estimate,
                                               double len, const Vec3& e_new, double k, SpringTerm& term, double& geometric,
                                               double& axial) {
    s.scratch.active[j] = 0;
    s.spring_force[j] = 0.0;
    if (kHessian) s.scratch.blk_off[j].setZero();
    if (s.broken[j]) return false;
    if (len > 1e-15) s.scratch.dir[j] = e_new;
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
    if (slackSegment(s, j, stretch, effective)) {
        // A slack segment that the step is predicted to stretch (predictSprings): its
        // spring with the slack carried, k/2 (C + e . (dx_b - dx_a))^2 in the model (a
        // force k C < 0 and the axial stiffness alone), so that the step stops where the
        // segment becomes taut instead of running on past it with no stiffness in the
        // model, which the energy then refuses (the line search's halvings).
        if (s.scratch.predicted_taut.empty() || !s.scratch.predicted_taut[j]) return false;
        s.scratch.active[j] = kPredictedTaut;
        term.force = k * effective * s.scratch.dir[j];
        term.to_a = !fixedRow(s, j);
        term.to_b = !fixedRow(s, j + 1);
        axial = 1.0;
        geometric = 0.0;
        return kHessian;
    }
    // Past yield (yield_in_solve) the force follows the plastic branch (plastic_spring.hpp):
    // c here is the equivalent elastic stretch f / k, `slope` the tangent over k. The
    // branch is the segment's active mark, so a chord iteration whose segment changed
    // branch is refused as one whose segment went slack.
    const SpringBranch branch = springBranch(s, j, std::max(effective, 0.0));
    const double c = branch.stretch;
    s.scratch.active[j] = branch.branch;
    s.spring_force[j] = k * c;
    term.force = k * c * s.scratch.dir[j];
    term.to_a = !fixedRow(s, j);
    term.to_b = !fixedRow(s, j + 1);
    if (!kHessian) {
        if (tension_estimate) tension_estimate[j] = effective;
        return false;
    }
    axial = branch.slope;
    geometric = c;
    if (tension_estimate) {
        // From a warm start, whose stretch is the last step's final one to within the
        // start's error, the first iteration takes the last step's tension as it is:
        // where the start left the segment a little less stretched, k C would make the
        // step transversely too soft.
        const double estimate = tension_estimate[j] * s.compliance[j];
        if (tension_estimate[j] > 0.0) geometric = s.scratch.strain_warm_start ? estimate : std::min(c, estimate);
        tension_estimate[j] = effective;
    }
    return true;
}

/// springTerm's Hessian, q = geometric / len given: k (a (1 + tau/h) e e^T + q (I - e e^T)),
/// a the axial tangent over k (plastic_spring.hpp; 1 on the elastic branch),
/// entry by entry with the same operations as the matrix expression (so the same bits),
/// the six distinct ones only (e_i e_j = e_j e_i exactly); and blk_off.
[[gnu::always_inline]] inline void springHessian(StringState& s, const StepContext& ctx, std::size_t j, double k, double q,
                                                 double axial, SpringTerm& term) {
    const double g = axial * (1.0 + s.desc.axial_damping * ctx.inv_h);  // times 1 exactly where elastic
    const Vec3& e = s.scratch.dir[j];
    const double e00 = e.x() * e.x(), e11 = e.y() * e.y(), e22 = e.z() * e.z();
    const double e10 = e.y() * e.x(), e20 = e.z() * e.x(), e21 = e.z() * e.y();
    const double h10 = k * (g * e10 + q * (0.0 - e10)), h20 = k * (g * e20 + q * (0.0 - e20));
    const double h21 = k * (g * e21 + q * (0.0 - e21));
    term.hess << k * (g * e00 + q * (1.0 - e00)), h10, h20,  //
        h10, k * (g * e11 + q * (1.0 - e11)), h21,           //
        h20, h21, k * (g * e22 + q * (1.0 - e22));
    if (term.to_a && term.to_b) s.scratch.blk_off[j] = -term.hess;
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
    double geometric = 0.0, axial = 1.0;
    if (springForce<kHessian>(s, ctx, j, tension_estimate, len, Vec3(d / len), k, term, geometric, axial))
        springHessian(s, ctx, j, k, geometric / len, axial, term);
    return term;
}

/// springTerm of segments j and j + 1 with their roots and divisions in the two lanes of
/// one register (most of a spring's time); the same operations lane by lane: the same bits.
template <bool kHessian = true>
[[gnu::always_inline]] inline void springTerms(StringState& s, const StepContext& ctx, std::size_t j, double* tension_estimate,
                                               SpringTerm (&term)[2]) {
    const UnitPair d = unitPair(s.x[j + 1] - s.x[j], s.x[j + 2] - s.x[j + 1]);
    const Lanes2 len = d.length;
    const Lanes2 k = 1.0 / Lanes2{s.compliance[j], s.compliance[j + 1]};
    double g0 = 0.0, g1 = 0.0, a0 = 1.0, a1 = 1.0;
    const bool h0 = springForce<kHessian>(s, ctx, j, tension_estimate, len[0], d.unit[0], k[0], term[0], g0, a0);
    const bool h1 = springForce<kHessian>(s, ctx, j + 1, tension_estimate, len[1], d.unit[1], k[1], term[1], g1, a1);
    if (!h0 && !h1) return;
    const Lanes2 q = Lanes2{g0, g1} / len;
    if (h0) springHessian(s, ctx, j, k[0], q[0], a0, term[0]);
    if (h1) springHessian(s, ctx, j + 1, k[1], q[1], a1, term[1]);
}

/// The springs of segments [j0, j1) (springTerm) added to blk_diag and blk_rhs.
void assembleSprings(StringState& s, const StepContext& ctx, std::size_t j0, std::size_t j1, double* tension_estimate) {
    auto add = [&s](std::size_t j, const SpringTerm& term) {
        addSprings(SpringTerm{}, term, s.scratch.blk_diag[j], s.scratch.blk_rhs[j]);
        addSprings(term, SpringTerm{}, s.scratch.blk_diag[j + 1], s.scratch.blk_rhs[j + 1]);
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

}  // namespace

/// The Newton system of the chain without contacts: the inertia rows (assembleInertia) and
/// the springs of the stretched segments (assembleSprings), into blk_diag, blk_off, blk_rhs.
void assembleChain(StringState& s, RigidTable& rigids, const StepContext& ctx, double* tension_estimate) {
    assembleInertia(s, rigids, ctx, 0, s.particles());
    assembleSprings(s, ctx, 0, s.segments(), tension_estimate);
}

/// A chord iteration's right-hand side: assembleChain's gradient, without the Hessian,
/// whose blocks stay those solveChain (or an island member) factorised. False where a segment went slack or taut
/// since. The effective stretches go into s.scratch.segment_work, not geometric_tension,
/// which a Newton iteration replacing a refused chord iteration reads as it was (acceptChord).
bool assembleChainGradient(StringState& s, const StepContext& ctx) {
    const double inv_h2 = ctx.inv_h * ctx.inv_h;
    for (std::size_t p = 0; p < s.particles(); ++p)
        s.scratch.blk_rhs[p] = s.hold[p].kind == ParticleHold::Kind::Free ? inertiaRhs(s, p, inv_h2) : Vec3::Zero();
    bool same = true;
    auto add = [&s](std::size_t j, const SpringTerm& term) {
        if (term.to_a) s.scratch.blk_rhs[j] += term.force;
        if (term.to_b) s.scratch.blk_rhs[j + 1] -= term.force;
    };
    const std::size_t m = s.segments();
    std::size_t j = 0;
    for (; j + 1 < m; j += 2) {
        const std::uint8_t was[2] = {s.scratch.active[j], s.scratch.active[j + 1]};
        SpringTerm term[2];
        springTerms<false>(s, ctx, j, s.scratch.segment_work.data(), term);
        same = same && s.scratch.active[j] == was[0] && s.scratch.active[j + 1] == was[1];
        add(j, term[0]);
        add(j + 1, term[1]);
    }
    if (j < m) {
        const std::uint8_t was = s.scratch.active[j];
        add(j, springTerm<false>(s, ctx, j, s.scratch.segment_work.data()));
        same = same && s.scratch.active[j] == was;
    }
    return same;
}

namespace {

/// Whether the chord iteration's step in blk_rhs is taken: where it is below
/// kQuadraticRegime times the last iteration's move (`last_move`), the effective
/// stretches of assembleChainGradient go into geometric_tension for linearisedTension.
/// A longer step means the factorised Hessian is too far from the Hessian here, and a
/// Newton iteration from the same state replaces it.
bool acceptChord(StringState& s, double last_move) {
    double worst_squared = 0.0;
    for (std::size_t p = 0; p < s.particles(); ++p)
        if (s.hold[p].kind == ParticleHold::Kind::Free)
            worst_squared = std::max(worst_squared, s.scratch.blk_rhs[p].squaredNorm());
    const double limit = kQuadraticRegime * last_move;
    if (!(worst_squared < limit * limit)) return false;
    for (std::size_t j = 0; j < s.segments(); ++j)
        if (s.scratch.active[j]) s.scratch.geometric_tension[j] = s.scratch.segment_work[j];
    return true;
}

/// The tension of each segment after the Newton step held in blk_rhs, to first order:
/// k f(max(0, C + (1 + tau/h) e . (dx_{j+1} - dx_j))), f the spring's branch
/// (plastic_spring.hpp; the identity where elastic), into geometric_tension (0 for the
/// segments that took no part in the step). C, the effective stretch before the step, is
/// what assembleChain left there.
void linearisedTension(StringState& s, const StepContext& ctx, std::size_t j0, std::size_t j1) {
    const double rate_gain = s.desc.axial_damping * ctx.inv_h;
    // Segment j's linearised effective stretch (0 where it took no part: then its tension
    // is max(0, 0) / compliance = +0, as set); each particle's step found once, carried
    // to the next segment.
    Vec3 da = fixedRow(s, j0) ? Vec3::Zero() : s.scratch.blk_rhs[j0];
    auto stretch = [&](std::size_t j) {
        const Vec3 db = fixedRow(s, j + 1) ? Vec3::Zero() : s.scratch.blk_rhs[j + 1];
        const double effective =
            s.scratch.active[j] ? s.scratch.geometric_tension[j] + (1.0 + rate_gain) * s.scratch.dir[j].dot(db - da) : 0.0;
        da = db;
        return effective;
    };
    // Past yield (yield_in_solve) the force of the spring's branch there.
    auto force = [&](std::size_t j, double effective) { return springBranch(s, j, std::max(0.0, effective)).stretch; };
    // The divisions two segments at a time, in lanes.
    std::size_t j = j0;
    for (; j + 1 < j1; j += 2) {
        const double e0 = stretch(j), e1 = stretch(j + 1);
        const Lanes2 t = Lanes2{force(j, e0), force(j + 1, e1)} / Lanes2{s.compliance[j], s.compliance[j + 1]};
        s.scratch.geometric_tension[j] = t[0];
        s.scratch.geometric_tension[j + 1] = t[1];
    }
    if (j < j1) s.scratch.geometric_tension[j] = force(j, stretch(j)) / s.compliance[j];
}

/// solveChain's sweep from the top alone, over particles [0, mid), assembling the springs
/// of segments [0, mid) as it goes (in assembleChain's order) and adding segment mid-1's
/// share of particle mid at the end; gains into blk_factor_gain. The assembly fills the
/// time a pivot's divisions leave the core idle. With sweepFromBottom on another thread
/// (parallelChainStep): the serial iteration's operations, so the same bits. Returns what
/// it carries to the middle particle.
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
        chain::eliminate(carry, chain::lower(d), r, chain::lower(s.scratch.blk_off[t]), y, gain, inv);
        chain::store(y, s.scratch.blk_rhs[t]);
        std::memcpy(s.scratch.blk_factor_gain[t].data(), gain, sizeof gain);
    }
    addSprings(last, SpringTerm{}, s.scratch.blk_diag[mid], s.scratch.blk_rhs[mid]);
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
        chain::eliminate(carry, chain::lower(d), r, chain::lower(s.scratch.blk_off[i - 1]), y, gain, inv);
        chain::store(y, s.scratch.blk_rhs[i]);
        std::memcpy(s.scratch.blk_factor_gain[i].data(), gain, sizeof gain);
    }
    held = last;
    return carry;
}

/// Moves the free particles in [p0, p1) by their step in blk_rhs (a chain without glued
/// particles); returns the largest squared move.
double applyChainStep(StringState& s, std::size_t p0, std::size_t p1) {
    double worst_squared = 0.0;
    for (std::size_t p = p0; p < p1; ++p) {
        if (fixedRow(s, p)) continue;
        const Vec3& dx = s.scratch.blk_rhs[p];
        if (!dx.allFinite()) continue;
        worst_squared = std::max(worst_squared, dx.squaredNorm());
        s.x[p] += dx;
    }
    return worst_squared;
}

/// One Newton iteration of a contact-free chain without glued particles, split over two
/// threads at the middle particle: each half assembles, sweeps, back-substitutes, updates
/// its linearised tension and moves its particles; the middle particle is solved here. The
/// sums are assembleChain's and solveChain's in the same order (segment mid's share of the
/// middle particle held back and added in place): the bits of the serial iteration.
double parallelChainStep(StringState& s, RigidTable& rigids, const StepContext& ctx, ThreadPool& pool) {
    const std::size_t n = s.particles();
    const std::size_t m = s.segments();
    const std::size_t mid = n / 2;
    double* tension_estimate = s.scratch.geometric_tension.data();
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
    addSprings(SpringTerm{}, held, s.scratch.blk_diag[mid], s.scratch.blk_rhs[mid]);
    chain::Sym<double> middle_inverse;
    chain::solveMiddle(top, bottom, s.scratch.blk_diag[mid], s.scratch.blk_rhs[mid], middle_inverse);
    double worst_squared[2] = {0.0, 0.0};
    pool.forEach(2, [&](std::size_t half) {
        if (half == 0) {
            substituteHalf(n, mid, true, s.scratch.blk_rhs.data(), s.scratch.blk_factor_gain.data());
            linearisedTension(s, ctx, 0, mid);
            worst_squared[0] = applyChainStep(s, 0, mid + 1);
        } else {
            substituteHalf(n, mid, false, s.scratch.blk_rhs.data(), s.scratch.blk_factor_gain.data());
            linearisedTension(s, ctx, mid, m);
            worst_squared[1] = applyChainStep(s, mid + 1, n);
        }
    });
    return std::sqrt(std::max(worst_squared[0], worst_squared[1]));
}

}  // namespace

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
    auto force = [&](std::size_t j, double length) {
        return springBranch(s, j, std::max(0.0, effectiveStretch(s, j, length - s.rest_length[j], rate_gain))).stretch;
    };
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
    if (s.scratch.rows_pressed)
        for (std::size_t p = 0; p < n; ++p) s.scratch.row_projector[p].setIdentity();
    s.scratch.rows_pressed = false;
    // The normal forces friction starts from next step (ContactMemory): the last
    // weighing's (weighRigidFriction), of every contact with friction, zero included.
    s.contact_memory.clear();
    for (const RigidSegmentContact& c : s.contacts)
        if (c.friction > 0.0 && !s.broken[c.segment])
            s.contact_memory.push_back({c.segment, c.s, c.body, c.local_normal, c.friction_normal});
    std::sort(s.contact_memory.begin(), s.contact_memory.end(), ContactMemory::before);  // in place: no allocation
    for (const RigidSegmentContact& c : s.contacts) {
        const std::size_t j = c.segment;
        if (s.broken[j]) continue;
        const Vec3 xs = (1.0 - c.s) * s.x[j] + c.s * s.x[j + 1];
        if (rigidGap(s, c, xs) > kContactSlop * s.radius[j]) continue;  // not touching
        // The contact's force is unknown along the normal and, where friction holds or
        // drags, along the slip.
        Vec3 dirs[2] = {c.plane_normal, Vec3::Zero()};
        if (c.lagged ? c.friction_weight > 0.0 : c.friction > 0.0 && c.solved_normal > 0.0) {
            const Vec3 slip = rigidSlip(s, c, xs);
            if (slip.norm() > 0.0) dirs[1] = slip.normalized();
        }
        for (const Vec3& along : dirs)
            for (std::size_t q : {j, j + 1}) {
                const Vec3 dir = s.scratch.row_projector[q] * along;  // what is left of this direction
                const double len = dir.norm();
                if (len > 1e-6) s.scratch.row_projector[q] -= (dir / len) * (dir / len).transpose();
                s.scratch.rows_pressed = true;
            }
    }
}

namespace {

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
    const Vec3* shift = s.scratch.blk_rhs.data();
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
        if (s.scratch.plastic_in_solve) {  // twice the energy over k on the spring's branches
            sum.cold += k * (2.0 * springEnergyOverStiffness(s, j, c_cold));
            sum.warm += k * (2.0 * springEnergyOverStiffness(s, j, c_warm));
            continue;
        }
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
/// Newton iterations: a rope holding a load is pulled back by about as much every step.
/// Returns whether it did. The energy is convex, so the solution is the same. Not taken:
///  - where the start has no less energy than the prediction (the energy limitStrain
///    minimises: inertia about x' and the springs): a weight let go of would have the
///    correction throw the tip up by the weight's pull;
///  - where a segment is slack at the prediction or not stretched at the start: the
///    correction is a load's pull, and a chain slack anywhere does not carry its load
///    steadily (Newton's first step from such a start overstretches a segment).
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
    const double warm = total.warm * (0.5 / (1.0 + rate_gain)) + 0.5 * s.inertia_gain * inv_h2 * total.inertia;
    if (!(warm < cold)) return false;
    forRanges(ctx.pool, n, kParallelItems, [&](std::size_t p0, std::size_t p1, std::size_t) {
        for (std::size_t p = p0; p < p1; ++p) s.x[p] += s.scratch.blk_rhs[p];
    });
    return true;
}

}  // namespace

void prepareStrainLimit(StringState& s, RigidTable& rigids, const StepContext& ctx) {
    const std::size_t n = s.particles();
    const std::size_t m = s.segments();
    // A long string's passes run on the pool (per-item writes); only the glued particles'
    // loads on their bodies are applied here, in particle order.
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
    if (glued || !s.contacts.empty() || !s.body_nodes.empty()) predictBackwardEuler(s, ctx);
    if (glued)
        for (std::size_t p = 0; p < n; ++p) {
            if (!s.glue_movable[p]) continue;
            // The glued particle is part of the body now: its weight and force act on it,
            // and the reaction of shape matching's goals (shape_matching.cpp).
            const ParticleHold& hold = s.hold[p];
            RigidState& b = rigids.bodies[hold.body.index];
            const Vec3 load = (s.mass[p] * ctx.gravity + s.force[p]) * (ctx.h * ctx.h) + s.scratch.csm_goal[p];
            applyBodyImpulse(b, s.x[p] - b.position, load);
            s.x[p] = gluePoint(b, hold.point);
        }
    // The last step's correction of the free particles (its end less its prediction),
    // for warmStart, in blk_rhs (limitStrain writes it before it reads it); then the
    // prediction is where the particles start.
    forRanges(ctx.pool, n, kParallelItems, [&](std::size_t p0, std::size_t p1, std::size_t) {
        for (std::size_t p = p0; p < p1; ++p) {
            const Vec3 correction = s.x_prev[p] - s.x_pred[p];
            // A particle glued to a body of an island keeps its correction too: its body's
            // (IslandSolver's warm start).
            const bool free = s.hold[p].kind == ParticleHold::Kind::Free || (s.glue_movable[p] && ctx.islands);
            s.scratch.blk_rhs[p] = free && correction.allFinite() ? correction : Vec3::Zero();
            s.x_pred[p] = s.x[p];
        }
    });
    for (BodyNode& node : s.body_nodes) {
        node.mass = bodyMass(rigids.bodies[node.body.index]);
        node.impulse.setZero();
        node.displacement.setZero();
        node.linearised_at.setZero();
    }
    // The segments' stretch at the step's start, two roots at a time (one sqrtpd).
    forRanges(ctx.pool, m, kParallelItems, [&](std::size_t j0, std::size_t j1, std::size_t) {
        std::size_t j = j0;
        for (; j + 1 < j1; j += 2) {
            const Lanes2 len = lengthPair(s.x_prev[j + 1] - s.x_prev[j], s.x_prev[j + 2] - s.x_prev[j + 1]);
            s.prev_stretch[j] = len[0] - s.rest_length[j];
            s.prev_stretch[j + 1] = len[1] - s.rest_length[j + 1];
        }
        if (j < j1) s.prev_stretch[j] = (s.x_prev[j + 1] - s.x_prev[j]).norm() - s.rest_length[j];
    });
    s.diagnostics.strain_newton_iterations = 0;
    s.diagnostics.strain_chord_iterations = 0;
    // A string of an island (glued to a movable body) is warm-started with its island, its
    // bodies and the other strings at once (IslandSolver): its correction stays in blk_rhs.
    s.scratch.strain_converged = true;  // until a solve of this string stops at its iteration cap
    s.scratch.plastic_in_solve = false;  // until StrainSolve takes the string (yield_in_solve)
    s.scratch.strain_warm_start = s.contacts.empty() && s.body_nodes.empty() && !(glued && ctx.islands) &&
                                  !ctx.cold_strain_starts && warmStart(s, ctx);
}

void setContactStiffness(StringState& s, const RigidTable& rigids, double inv_h2) {
    const double stiffest = s.contacts.empty() ? 0.0 : stiffestTerm(s, inv_h2);  // two passes over the string: only for contacts
    for (RigidSegmentContact& c : s.contacts) {
        // Under a load F the contact gives way by F / k_c only.
        if (c.stiffness > 0.0) continue;
        double kc = stiffest;
        if (c.node >= 0) kc = std::max(kc, inv_h2 / rigids.bodies[c.body.index].inverse_mass);
        c.stiffness = kc * kContactStiffnessFactor;
    }
}

void assembleContactCoupling(StringState& s, StringScratch::NodeScratch& nodes) {
    auto& node_diag = nodes.diag;
    auto& node_rhs = nodes.rhs;
    auto& coupling = nodes.coupling;
    for (const RigidSegmentContact& c : s.contacts) {
        if (!c.active) continue;
        const std::size_t j = c.segment;
        const Vec3& nrm = c.plane_normal;
        // The gradient only where it penetrates, or where the contact is held because the
        // step runs into it: there the model is k_c (g + a . dx)^2 / 2 with g > 0 now, whose
        // minimum is the penetration the load needs. Held with g taken as 0 (a stiff spring
        // where the string is now, no pull toward the plane), the step toward the contact
        // shrinks by k_c over the other stiffnesses (kContactStiffnessFactor, 100) and the
        // solve creeps onto the contact at ~1% an iteration.
        const double gap = rigidGap(s, c, (1.0 - c.s) * s.x[j] + c.s * s.x[j + 1]);
        const double g = c.predicted ? gap : std::min(0.0, gap);
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
    // Friction: D(u_t) (rigidFrictionTerm: gradient g, Hessian H in u_t = T rel, T the
    // tangent projector, rel the motion relative to the body): on the string's side
    // addFrictionRows, on the body's J^T g and J^T H J with J = d u_t / d(u, theta).
    for (const RigidSegmentContact& c : s.contacts) {
        const std::size_t j = c.segment;
        if (!hasFriction(c) || s.broken[j]) continue;
        const bool fa = !fixedRow(s, j), fb = !fixedRow(s, j + 1);
        const FrictionTerm f = addFrictionRows(s, c, fa, fb);
        if (c.node < 0) continue;
        const std::size_t b = static_cast<std::size_t>(c.node);
        const double wa = 1.0 - c.s, wb = c.s;
        const Mat36 jb = rigidSlipBodyJacobian(c, f.tangent);
        if (c.lagged) {  // w (TJ)^T (TJ), w (TJ)^T T rel (T J = jb: T T = T)
            const double w = c.friction_weight;
            node_diag[b] += w * jb.transpose() * jb;
            node_rhs[b] -= w * jb.transpose() * f.slip;
            if (fa) coupling[b].emplace_back(j, (w * wa) * jb);
            if (fb) coupling[b].emplace_back(j + 1, (w * wb) * jb);
            continue;
        }
        const Mat36 hj = f.hessian * jb;
        node_diag[b] += jb.transpose() * hj;
        node_rhs[b] -= jb.transpose() * f.gradient;
        if (fa) coupling[b].emplace_back(j, wa * hj);
        if (fb) coupling[b].emplace_back(j + 1, wb * hj);
    }
}

void condenseNodesRhs(const StringState& s, StringScratch::NodeScratch& nodes_scratch) {
    const std::size_t nodes = s.body_nodes.size();
    Eigen::VectorXd& rs = nodes_scratch.rs;
    rs.resize(static_cast<Eigen::Index>(6 * nodes));
    for (std::size_t b = 0; b < nodes; ++b) {
        rs.segment<6>(static_cast<Eigen::Index>(6 * b)) = nodes_scratch.rhs[b];
        for (const auto& [p, blk] : nodes_scratch.coupling[b])
            rs.segment<6>(static_cast<Eigen::Index>(6 * b)) -= blk.transpose() * s.scratch.blk_rhs[p];
    }
}

void condenseNodes(StringState& s, StringScratch::NodeScratch& nodes_scratch) {
    const std::size_t n = s.particles();
    const std::size_t nodes = s.body_nodes.size();
    const auto& node_diag = nodes_scratch.diag;
    const auto& coupling = nodes_scratch.coupling;
    // Schur complement on the bodies' unknowns: (D - C^T A^-1 C) du = r_b - C^T y,
    // then dx = y - A^-1 C du. Each body costs six more O(n) solves.
    const std::size_t dim = 6 * nodes;
    Eigen::MatrixXd& schur = nodes_scratch.schur;
    schur.setZero(static_cast<Eigen::Index>(dim), static_cast<Eigen::Index>(dim));
    condenseNodesRhs(s, nodes_scratch);
    if (s.scratch.node_columns.size() < dim) s.scratch.node_columns.resize(dim);
    std::vector<Vec3*>& columns = s.scratch.column_pointers;
    std::vector<std::size_t>& firsts = s.scratch.column_firsts;
    columns.clear();
    firsts.clear();
    for (std::size_t b = 0; b < nodes; ++b) {
        schur.block<6, 6>(static_cast<Eigen::Index>(6 * b), static_cast<Eigen::Index>(6 * b)) = node_diag[b];
        for (int col = 0; col < 6; ++col) {
            std::vector<Vec3>& column = s.scratch.node_columns[6 * b + static_cast<std::size_t>(col)];
            column.assign(n, Vec3::Zero());
            std::size_t first = n;
            for (const auto& [p, blk] : coupling[b]) {
                column[p] += blk.col(col);
                first = std::min<std::size_t>(first, p);
            }
            columns.push_back(column.data());
            firsts.push_back(first < n ? first : 0);
        }
    }
    solveFactoredColumns(n, s.scratch.blk_off.data(), s.scratch.blk_factor.data(), s.scratch.blk_factor_gain.data(),
                         s.scratch.blk_coupled.data(), columns.data(), firsts.data(), columns.size());
    for (std::size_t b = 0; b < nodes; ++b)
        for (std::size_t c = 0; c < dim; ++c)
            for (const auto& [p, blk] : coupling[b])
                schur.block<6, 1>(static_cast<Eigen::Index>(6 * b), static_cast<Eigen::Index>(c)) -=
                    blk.transpose() * s.scratch.node_columns[c][p];
}

void backSubstituteNodes(StringState& s, const Eigen::VectorXd& du) {
    const std::size_t n = s.particles();
    const std::size_t nodes = s.body_nodes.size();
    for (std::size_t c = 0; c < 6 * nodes; ++c) {
        const double f = du[static_cast<Eigen::Index>(c)];
        if (f != 0.0)
            for (std::size_t p = 0; p < n; ++p) s.scratch.blk_rhs[p] -= f * s.scratch.node_columns[c][p];
    }
    for (std::size_t b = 0; b < nodes; ++b) s.scratch.node_step[b] = du.segment<6>(static_cast<Eigen::Index>(6 * b));
}

bool predictSprings(StringState& s, const StepContext& ctx, const std::vector<Vec3>* held_step) {
    const std::size_t m = s.segments();
    if (s.scratch.predicted_taut.size() != m) s.scratch.predicted_taut.assign(m, 0);
    auto moved = [&](std::size_t p) { return steppedPosition(s, p, held_step); };
    const double rate_gain = s.desc.axial_damping * ctx.inv_h;
    bool changed = false;
    for (std::size_t j = 0; j < m; ++j) {
        if (s.broken[j]) continue;
        const double stretch = (s.x[j + 1] - s.x[j]).norm() - s.rest_length[j];
        if (!slackSegment(s, j, stretch, effectiveStretch(s, j, stretch, rate_gain))) continue;
        const double after = (moved(j + 1) - moved(j)).norm() - s.rest_length[j];
        const std::uint8_t stretched = effectiveStretch(s, j, after, rate_gain) > 0.0;
        if (stretched != s.scratch.predicted_taut[j]) {
            s.scratch.predicted_taut[j] = stretched;
            changed = true;
        }
    }
    return changed;
}

bool springRow(StringState& s, const StepContext& ctx, std::size_t j, Mat3& hess, Vec3& force) {
    const SpringTerm term = springTerm(s, ctx, j, nullptr);
    hess = term.hess;
    force = term.force;
    return s.scratch.active[j] != 0;
}

namespace {

/// limitStrain's Newton iterations on one string (see the file's header): passes of
/// iterations (several where rigid friction's lagged weights must settle), each iteration a
/// Newton or chord step (solveStep: assemble, then solveChain or the factorised system with
/// the touched bodies' Schur complement), the contacts the step would run into added
/// (addPredictedContacts), a line search on the energy and the move (applyStep).
class StrainSolve {
public:
    StrainSolve(StringState& string, RigidTable& rigid_table, const StepContext& context)
        : s(string), rigids(rigid_table), ctx(context), n(string.particles()), inv_h2(context.inv_h * context.inv_h),
          tol(context.settings->strain_tolerance), nodes(string.body_nodes.size()), scratch(string.scratch.node_scratch) {
        // Body unknowns (contacts with movable bodies): scratch kept in the string (grown to
        // the most nodes seen, never shrunk, so that a running step does not allocate).
        if (scratch.diag.size() < nodes) {
            scratch.diag.resize(nodes);
            scratch.rhs.resize(nodes);
            scratch.coupling.resize(nodes);
        }
        // Contacts with rigid bodies: g >= 0 on linearised planes (linearisePlanes), a stiff
        // one-sided penalty k_c min(0, g)^2 / 2, x(s) = (1-s) x_j + s x_{j+1}. A movable body
        // takes part with its 6 unknowns, so a rope catches a crate with its tension. A
        // separated contact the full Newton step would run into joins the Hessian (not the
        // gradient) and the step is solved again, so that it stops at the contact.
        linearisePlanes(s, rigids);
        setContactStiffness(s, rigids, inv_h2);
        // A chain without contacts or body unknowns: its Hessian's geometric term takes the
        // linearised tension (starting from the last step's), its system is solved by
        // solveChain, and it stops on a quadratic prediction of its next move (run).
        plain_chain = s.contacts.empty() && nodes == 0;
        if (plain_chain) std::copy(s.spring_force.begin(), s.spring_force.end(), s.scratch.geometric_tension.begin());
        // A long one, alone on the pool (not nested in a forEach over strings), is split over
        // two threads (parallelChainStep); glued particles move bodies, so not with those.
        const bool glued = plain_chain && std::any_of(s.hold.begin(), s.hold.end(), [](const ParticleHold& hold) {
            return hold.kind == ParticleHold::Kind::Glue;
        });
        // Not where the string yields in the solve: its steps take the line search (lineSearch).
        s.scratch.plastic_in_solve = s.desc.yield_in_solve;
        parallel_chain = plain_chain && !glued && n >= kParallelChainParticles && ctx.pool && ctx.pool->parallel() &&
                         !s.scratch.plastic_in_solve;
        // Chord iterations (the last Newton factorisation reused, products only): only after
        // the first Newton iteration from a warm start, whose geometric term took the last
        // step's converged tension (a cold first-order estimate is too far off for a linear
        // rate), and only below kParallelChainParticles (parallelChainStep has none).
        const bool chord_chain =
            plain_chain && !glued && n < kParallelChainParticles && s.scratch.chain_inverse.size() >= 6 * n + 12 &&
            !ctx.newton_strain_only;
        inverses = chord_chain ? s.scratch.chain_inverse.data() : nullptr;
        warm_start = s.scratch.strain_warm_start;
    }

    /// Runs the solve; returns the largest move of its first iteration.
    double run() {
        double first_move = -1.0;  // the first iteration's largest move
        // Impacts are strongly nonlinear: with contacts the solve may take more iterations.
        // Friction's passes reweigh from the last pass's forces and slips until they settle.
        const int iterations = ctx.settings->strain_iterations * (s.contacts.empty() ? kChainIterationFactor : kContactIterationFactor);
        bool frictional = false;
        for (const RigidSegmentContact& c : s.contacts) frictional = frictional || c.friction > 0.0;
        if (!s.contacts.empty()) warmStartOnBodies();
        for (int pass = 0; pass < (frictional ? kRigidFrictionPasses : 1); ++pass) {
            bool converged = false;
            double last_move = -1.0;
            bool chord_next = false;  // the next iteration may be a chord iteration
            for (int iter = 0; iter < iterations; ++iter) {
                double worst = 0.0;
                bool stalled = false;
                bool chord = false;  // this iteration is one
                bool cut = false;    // its step was shortened by the line search
                if (parallel_chain)
                    worst = parallelChainStep(s, rigids, ctx, *ctx.pool);
                else
                    worst = iterate(chord_next, last_move, chord, stalled, cut);
                if (first_move < 0.0) first_move = worst;
                ++s.diagnostics.strain_newton_iterations;
                s.diagnostics.strain_chord_iterations += chord;
                s.scratch.strain_warm_start = false;
                // Without contacts the iteration converges quadratically near the solution
                // (move ~ C times the last one squared): where the moves fall that fast, the
                // next move, predicted with C from the last two, is checked against the
                // tolerance (margin 100) instead of being made. After a chord iteration the
                // next move is ~2 C m_last times this one (linear), and ends the solve only
                // where the move fell that fast too.
                const bool quadratic = last_move > 0.0 && worst < kQuadraticRegime * last_move;
                const double margin = kPredictionMargin * worst * worst;
                // Where the string yields in the solve, not where a segment is now on another
                // branch than the one its last Newton system took (a kink of the force:
                // slack, elastic, plastic; plastic_spring.hpp): the next move is not the
                // quadratic one then.
                const bool next_within = plain_chain && quadratic && (!s.scratch.plastic_in_solve || sameBranches()) &&
                                         (chord ? 2.0 * margin < tol * s.shortest_rest * last_move
                                                : margin * worst < tol * s.shortest_rest * last_move * last_move);
                // A chord iteration follows the first Newton iteration of a warm start, or a
                // chord iteration whose move fell by kQuadraticRegime or more.
                chord_next = inverses && (iter == 0 ? warm_start : chord && quadratic);
                last_move = worst;
                // A step the line search shortened is no sign of convergence.
                if (!cut && (stalled || (worst < tol * s.shortest_rest && (!chord || quadratic)) || next_within)) {
                    converged = true;
                    break;
                }
            }
            s.scratch.strain_converged = converged;
            if (!frictional) break;
            const double change = weighRigidFriction(s, false);
            if (converged && change < kFrictionSettled) break;
        }
        for (RigidSegmentContact& c : s.contacts) {
            c.active = !s.broken[c.segment] && gapNow(c) < 0.0;
            c.predicted = false;
        }
        finishChain(s, rigids, ctx);
        return std::max(first_move, 0.0);
    }

private:
    /// Whether every segment is on the branch of its spring (slack 0, else springBranch's)
    /// that the last assembly found (the active marks).
    bool sameBranches() const {
        const double rate_gain = s.desc.axial_damping * ctx.inv_h;
        for (std::size_t j = 0; j < s.segments(); ++j) {
            if (s.broken[j]) continue;
            const double stretch = (s.x[j + 1] - s.x[j]).norm() - s.rest_length[j];
            const double effective = effectiveStretch(s, j, stretch, rate_gain);
            const std::uint8_t branch =
                slackSegment(s, j, stretch, effective) ? 0 : springBranch(s, j, std::max(effective, 0.0)).branch;
            if (branch != s.scratch.active[j]) return false;
        }
        return true;
    }
    /// A string lying on bodies that do not move with it (no body unknowns) starts where
    /// the last step's correction takes its prediction (prepareStrainLimit left it in
    /// blk_rhs), as a contact-free chain does (warmStart), where that lowers the step's
    /// energy, contacts and friction included: a rope at rest on the ground starts at rest,
    /// with its contacts pressed as they were. Only where no particle moves by more than
    /// its segments' radius: a body the host did not report as a contact is farther than
    /// that from the swept segment, so the start jumps no contact the solve has not got.
    void warmStartOnBodies() {
        if (nodes > 0 || ctx.cold_strain_starts || std::any_of(s.glue_movable.begin(), s.glue_movable.end(), [](std::uint8_t g) { return g != 0; }))
            return;
        for (std::size_t p = 0; p < n; ++p) {
            const double reach = std::min(s.radius[std::min(p, s.segments() - 1)], s.radius[p > 0 ? p - 1 : 0]);
            if (!(s.scratch.blk_rhs[p].squaredNorm() <= reach * reach)) return;
        }
        linearisePlanes(s, rigids);
        if (!(stepEnergy(s, rigids, ctx, 1.0) < stepEnergy(s, rigids, ctx, 0.0))) return;
        for (std::size_t p = 0; p < n; ++p)
            if (!fixedRow(s, p)) s.x[p] += s.scratch.blk_rhs[p];
    }
    double gapNow(const RigidSegmentContact& c) const {
        const std::size_t j = c.segment;
        return rigidGap(s, c, (1.0 - c.s) * s.x[j] + c.s * s.x[j + 1]);
    }
    /// The gap after the full step held in blk_rhs and node_step.
    /// One iteration other than parallelChainStep's: a chord step where `chord_next`
    /// allows it and acceptChord takes it (`chord`), else a Newton step; then the contacts
    /// it would run into, the line search (`stalled` where it found no lower energy) and
    /// the move. Returns the largest move.
    double iterate(bool chord_next, double last_move, bool& chord, bool& stalled, bool& cut) {
        for (RigidSegmentContact& c : s.contacts) {
            c.active = !s.broken[c.segment] && gapNow(c) < 0.0;
            c.predicted = false;
        }
        if (chord_next && assembleChainGradient(s, ctx)) {
            chordSolveChain(n, s.scratch.blk_off.data(), s.scratch.blk_rhs.data(), s.scratch.blk_factor_gain.data(),
                            s.scratch.chain_coupled.data(), inverses);
            chord = acceptChord(s, last_move);
        }
        if (!chord) solveStep();
        addPredictedContacts();
        return applyStep(lineSearch(stalled, cut));
    }

    /// Assembles the Newton system (the chain's, plus the contacts in the Hessian: those
    /// marked active) and solves it: the particles' step into blk_rhs, the bodies' into
    /// node_step.
    void solveStep() {
        assemble();
        solve();
    }

    /// The chain's rows (assembleChain), the active contacts' penalty rows and all
    /// contacts' friction rows, with their bodies' blocks and couplings (node scratch).
    void assemble() {
        auto& node_diag = scratch.diag;
        auto& node_rhs = scratch.rhs;
        auto& coupling = scratch.coupling;
        assembleChain(s, rigids, ctx, plain_chain ? s.scratch.geometric_tension.data() : nullptr);
        for (std::size_t b = 0; b < nodes; ++b) {
            const BodyNode& node = s.body_nodes[b];
            node_diag[b] = node.mass * inv_h2;
            node_rhs[b] = -(node.mass * node.displacement) * inv_h2;
            coupling[b].clear();
        }
        assembleContactCoupling(s, scratch);
    }

    /// solveChain for a plain chain; else the factorised chain, with the Schur complement
    /// on the touched bodies' unknowns.
    void solve() {
        if (plain_chain) {
            solveChain(n, s.scratch.blk_diag.data(), s.scratch.blk_off.data(), s.scratch.blk_rhs.data(),
                       s.scratch.blk_factor_gain.data(), s.scratch.chain_coupled.data(), inverses);
            return;
        }
        factorChain(s);
        solveFactored(s, s.scratch.blk_rhs);  // y = A^-1 r
        for (std::size_t b = 0; b < nodes; ++b) s.scratch.node_step[b].setZero();
        if (nodes == 0) return;
        condenseNodes(s, scratch);
        scratch.ldlt.compute(scratch.schur);
        scratch.du = scratch.ldlt.solve(scratch.rs);
        backSubstituteNodes(s, scratch.du);
    }

    /// A separated contact that the full Newton step would run into is held, with its gap
    /// in the model (k_c (g + a . dx)^2 / 2, g > 0 now: the step stops on the plane), and
    /// the step is solved again; one held so that, held, the step no longer runs into it
    /// is let go (the active set of a semismooth Newton step, as an island's member does,
    /// string_island.cpp). Held with its gap taken as 0 instead, the contact is a stiff
    /// spring where the string is now: the step toward the body shrinks by k_c over the
    /// other stiffnesses (kContactStiffnessFactor) and a rope pulled onto a drum hovers
    /// off it for the whole solve, pressing nothing (no normal force, so no friction).
    void addPredictedContacts() {
        for (int round = 0; round < kPredictRounds && predictContacts(s); ++round) solveStep();
    }

    /// The springs' curvature changes along a long step (a rope deflected by
    /// centimetres) and the penalties switch on along it: backtrack until the (convex)
    /// energy decreases. Where no fraction of the step lowers it, the state is the
    /// minimum to rounding: stop there, rather than take a step that raises the energy.
    /// A string that yields in the solve takes it too, contacts or not: its springs soften
    /// past yield (plastic_spring.hpp), and a Newton step from a segment on the soft branch
    /// overshoots onto the stiff one and back, a cycle that only the energy's descent
    /// breaks. `cut` says that the step was shortened (a short move is then no sign of
    /// convergence).
    double lineSearch(bool& stalled, bool& cut) {
        double alpha = 1.0;
        if (!s.contacts.empty()) {
            const double e0 = stepEnergy(s, rigids, ctx, 0.0);
            int halving = 0;
            for (; halving < kLineSearchHalvings && stepEnergy(s, rigids, ctx, alpha) > e0; ++halving) alpha *= 0.5;
            if (halving == kLineSearchHalvings) {
                alpha = 0.0;
                stalled = true;
            }
        } else if (s.scratch.plastic_in_solve) {
            // The same search; without contacts the energy where the last one stopped is the
            // energy here (nothing else moves the chain), so each step evaluates it once.
            // Near the solution a step changes the energy by less than its sum's rounding
            // (kEnergyRounding of it): such a step is taken, not halved 30 times.
            const double e0 = std::isnan(energy_now) ? stepEnergy(s, rigids, ctx, 0.0) : energy_now;
            const double within = e0 + kEnergyRounding * std::abs(e0);
            double e = stepEnergy(s, rigids, ctx, alpha);
            int halving = 0;
            while (e > within) {
                if (++halving == kLineSearchHalvings) break;
                alpha *= 0.5;
                e = stepEnergy(s, rigids, ctx, alpha);
            }
            if (halving == kLineSearchHalvings) {
                alpha = 0.0;
                stalled = true;
                e = e0;
            }
            energy_now = e;
        }
        cut = s.scratch.plastic_in_solve && !stalled && alpha < 1.0;
        return alpha;
    }

    /// Moves along alpha times the step: bodies by their displacement, free particles, and
    /// glued ones' bodies by the impulse K^-1 dx. Returns the largest move.
    double applyStep(double alpha) {
        double worst = 0.0;
        if (alpha != 1.0)
            for (std::size_t p = 0; p < n; ++p) s.scratch.blk_rhs[p] *= alpha;
        for (std::size_t b = 0; b < nodes; ++b) {
            const Vec6 u = alpha * s.scratch.node_step[b];
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
        // Free particles move; glued ones move their body by the impulse K^-1 dx.
        double worst_squared = 0.0;
        for (std::size_t p = 0; p < n; ++p) {
            if (fixedRow(s, p)) continue;
            const Vec3& dx = s.scratch.blk_rhs[p];
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
        return std::max(worst, std::sqrt(worst_squared));
    }

    StringState& s;
    RigidTable& rigids;
    const StepContext& ctx;
    const std::size_t n;
    const double inv_h2;
    const double tol;
    const std::size_t nodes;
    StringScratch::NodeScratch& scratch;
    /// A chain without contacts or body unknowns, on two threads, and its chord iterations'
    /// store of pivot inverses (null: none).
    bool plain_chain = false;
    bool parallel_chain = false;
    /// A contact-free string that yields in the solve: the step energy at the current state
    /// (lineSearch), NaN until a search has found it.
    double energy_now = std::numeric_limits<double>::quiet_NaN();
    double* inverses = nullptr;
    bool warm_start = false;
};

}  // namespace

double limitStrain(StringState& s, RigidTable& rigids, const StepContext& ctx) { return StrainSolve(s, rigids, ctx).run(); }

}  // namespace tearables::detail
