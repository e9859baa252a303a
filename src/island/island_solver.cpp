// Islands (sim/island.hpp): members that share a movable body are solved together.
//
// Grouping: union-find over the bodies, each member joining the bodies it touches. Each
// island is then one Newton solve of E = sum_b u_b^T M_b u_b / (2 h^2) + sum E_member:
// per iteration every member condenses its Newton system onto its bodies (Schur
// complement), the island solves the dense body system (6 per body) by LDL^T, every
// member substitutes back, a backtracking line search on E, and the bodies move by the
// accepted step (their velocities follow from the displacement, World::applyBodyVelocities).
// Members with lagged friction take passes that reweigh it between converged solves, as
// a string alone does.
#include "island/island_solver.hpp"

#include "base/thread_pool.hpp"
#include "base/union_find.hpp"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <numeric>

namespace tearables::detail {

namespace {

/// The iteration budget of a pass relative to WorldSettings::strain_iterations (as for a
/// string with contacts alone), the passes friction may take, when they are settled, and
/// the halvings of the line search before it gives up (the energy at its minimum to
/// rounding along the step).
constexpr int kIterationFactor = 4;
constexpr int kFrictionPasses = 4;
constexpr double kFrictionSettled = 1e-2;
constexpr int kLineSearchHalvings = 30;
/// Non-monotone line search (Grippo, Lampariello & Lucidi, "A nonmonotone line search
/// technique for Newton's method", SIAM J. Numer. Anal. 23 (1986) 707-716): a step is
/// accepted when the energy is no higher than the highest of the last kEnergyMemory
/// accepted energies of the pass, not only the last. Taut segments are stiff
/// (k = E A / L, ~1e7 N/m for a 4 mm segment of rope) and curved: a Newton step that
/// moves a taut segment sideways by d stretches it by d^2 / (2 L), a term the quadratic
/// model lacks, so the energy along the full step can rise where the step is right (the
/// Maratos effect) and a monotone search halves it again and again, stalling a rope that
/// lies on the ground or slides on a body. The reference values never increase (each is
/// the maximum of a window whose newest entry is below the previous maximum), so the pass
/// still ends no higher than it began and the iteration still converges (ibid., Thm 1).
constexpr std::size_t kEnergyMemory = 10;
/// The share of a body's rotational inertia that the turning stiffness's negative part may
/// not take away (addSoftening).
constexpr double kInertiaKept = 0.5;
/// The warm start's weight on a body's turn, relative to its held points' arms squared
/// (and a floor, m^2, for points at its centre): small enough to leave the turn the points
/// fix, large enough to make the one they leave free zero.
constexpr double kWarmTurnWeight = 1e-6;
constexpr double kWarmTurnFloor = 1e-12;
/// A chord iteration follows an iteration whose move fell by this factor or more (the
/// strings' own solve's kQuadraticRegime).
constexpr double kQuadraticRegime = 0.1;
/// Times per iteration that the contacts the step runs into are revised (addPredictedContacts)
/// and the system solved again.
constexpr int kPredictRounds = 3;
/// The slowest rate that the estimate of the distance still to go takes (a rate near 1
/// would ask for moves far below rounding).
constexpr double kSlowestRate = 0.99;

}  // namespace

void IslandSolver::setBodyContacts(const std::vector<BodyContact>& contacts, const RigidTable& rigids) {
    body_contacts_.assign(contacts.begin(), contacts.end());
    prepareBodyContacts(body_contacts_, rigids);
    last_forces_.resize(body_contacts_.size());
    for (std::size_t k = 0; k < body_contacts_.size(); ++k) last_forces_[k] = body_contacts_[k].force;
}

/// A contact's force is the last step's on the way in (its friction's first weight) and
/// the solve's on the way out.
void IslandSolver::restart() {
    for (std::size_t k = 0; k < body_contacts_.size(); ++k) body_contacts_[k].force = last_forces_[k];
    resume_ = true;
}

void IslandSolver::keepOutcome() {
    kept_.contacts = body_contacts_;
    kept_.joints = body_joints_;
    kept_.reports = reports_;
    kept_.displacement = last_displacement_;
}

void IslandSolver::restoreOutcome() {
    body_contacts_ = kept_.contacts;
    body_joints_ = kept_.joints;
    reports_ = kept_.reports;
    last_displacement_ = kept_.displacement;
}

bool IslandSolver::converged() const {
    return std::all_of(reports_.begin(), reports_.end(), [](const IslandSummary& r) { return r.residual < 1.0; });
}

void IslandSolver::setBodyJoints(const std::vector<BodyJoint>& joints, const RigidTable& rigids) {
    body_joints_.assign(joints.begin(), joints.end());
    prepareBodyJoints(body_joints_, rigids);
}

void IslandSolver::solve(const std::vector<IslandMember*>& members, RigidTable& rigids, const StepContext& ctx) {
    reports_.clear();
    all_members_ = members;
    std::size_t pairs = 0;
    for (std::size_t first = 0; first < body_contacts_.size();) {
        std::size_t end = first + 1;
        while (end < body_contacts_.size() && body_contacts_[end].a == body_contacts_[first].a &&
               body_contacts_[end].b == body_contacts_[first].b)
            ++end;
        if (body_members_.size() == pairs) body_members_.emplace_back();
        body_members_[pairs++].start(body_contacts_, first, end - first, rigids, ctx);
        first = end;
    }
    if (joint_members_.size() < body_joints_.size()) joint_members_.resize(body_joints_.size());
    for (std::size_t k = 0; k < body_joints_.size(); ++k) joint_members_[k].start(body_joints_[k], rigids, ctx);
    for (std::size_t k = 0; k < pairs; ++k) all_members_.push_back(&body_members_[k]);  // after any growth
    for (std::size_t k = 0; k < body_joints_.size(); ++k) all_members_.push_back(&joint_members_[k]);
    group(all_members_, rigids);
    inv_h2_ = ctx.inv_h * ctx.inv_h;
    pool_ = ctx.pool;
    for (std::size_t i = 0; i < used_; ++i) reports_.push_back(solveIsland(islands_[i], rigids, ctx));
    resume_ = false;
}

void IslandSolver::group(const std::vector<IslandMember*>& members, const RigidTable& rigids) {
    const std::size_t table = rigids.bodies.size();
    parent_.resize(table);
    std::iota(parent_.begin(), parent_.end(), 0u);
    for (const IslandMember* m : members) {
        const std::vector<RigidId>& bodies = m->bodies();
        for (std::size_t k = 1; k < bodies.size(); ++k) {
            const std::uint32_t a = unionRoot(parent_, bodies[0].index);
            const std::uint32_t b = unionRoot(parent_, bodies[k].index);
            if (a != b) parent_[std::max(a, b)] = std::min(a, b);
        }
    }
    used_ = 0;
    island_of_.assign(table, -1);
    slot_of_.assign(table, -1);
    for (IslandMember* m : members) {
        const std::vector<RigidId>& bodies = m->bodies();
        if (bodies.empty()) continue;
        const std::uint32_t root = unionRoot(parent_, bodies[0].index);
        if (island_of_[root] < 0) {
            island_of_[root] = static_cast<int>(used_);
            if (islands_.size() == used_) islands_.emplace_back();
            Island& fresh = islands_[used_++];
            fresh.members.clear();
            fresh.bodies.clear();
            fresh.used_slots = 0;
        }
        Island& island = islands_[static_cast<std::size_t>(island_of_[root])];
        if (island.slots.size() == island.used_slots) island.slots.emplace_back();
        std::vector<int>& slots = island.slots[island.used_slots++];
        slots.clear();
        for (RigidId b : bodies) {
            if (slot_of_[b.index] < 0) {
                slot_of_[b.index] = static_cast<int>(island.bodies.size());
                island.bodies.push_back(b);
            }
            slots.push_back(slot_of_[b.index]);
        }
        island.members.push_back(m);
    }
}

template <class Fn>
void IslandSolver::forMembers(const Island& island, Fn&& fn) {
    if (member_value_.size() < island.members.size()) member_value_.resize(island.members.size());
    if (pool_) {
        pool_->forEach(island.members.size(), fn);
    } else {
        for (std::size_t k = 0; k < island.members.size(); ++k) fn(k);
    }
}

void IslandSolver::inertiaRhs(const Island& island) {
    rhs_.setZero(static_cast<Eigen::Index>(6 * island.bodies.size()));
    for (std::size_t b = 0; b < island.bodies.size(); ++b) {
        const Eigen::Index r = static_cast<Eigen::Index>(6 * b);
        rhs_.segment<6>(r) -= mass_[b] * displacement_.segment<6>(r) * inv_h2_;
    }
}

void IslandSolver::solveSystem(Island& island, bool fresh) {
    const Eigen::Index dim = static_cast<Eigen::Index>(6 * island.bodies.size());
    system_.setZero(dim, dim);
    for (std::size_t b = 0; b < island.bodies.size(); ++b) {
        const Eigen::Index r = static_cast<Eigen::Index>(6 * b);
        system_.block<6, 6>(r, r) += mass_[b] * inv_h2_;
    }
    inertiaRhs(island);
    forMembers(island, [&](std::size_t k) { island.members[k]->condense(fresh); });
    for (std::size_t k = 0; k < island.members.size(); ++k) island.members[k]->addTo(island.slots[k], system_, rhs_);
    addSoftening(island);
    ldlt_.compute(system_);
    du_ = ldlt_.solve(rhs_);
    forMembers(island, [&](std::size_t k) { island.members[k]->backSubstitute(island.slots[k], du_); });
}

/// The turning stiffness's negative part (IslandMember::addTurningSoftening) joins each
/// body's rotation block scaled by the largest t <= 1 with M + t S >= kInertiaKept M, M the
/// block's inertia over h^2: t = (1 - kInertiaKept) / mu where mu, the largest generalised
/// eigenvalue of (-S, M), is above 1 - kInertiaKept. Every other term of the system
/// (inertia, springs taut or in the band, penalties, friction, the positive parts, and their
/// Schur complements) is positive semidefinite, so the system stays positive definite.
void IslandSolver::addSoftening(const Island& island) {
    softening_.assign(island.bodies.size(), Mat3::Zero());
    for (std::size_t k = 0; k < island.members.size(); ++k) island.members[k]->addTurningSoftening(island.slots[k], softening_);
    for (std::size_t b = 0; b < island.bodies.size(); ++b) {
        const Mat3& s = softening_[b];
        if (s.isZero(0.0)) continue;
        const Mat3 inertia = mass_[b].bottomRightCorner<3, 3>() * inv_h2_;
        if (!inertia.allFinite() || !s.allFinite()) continue;
        const Eigen::GeneralizedSelfAdjointEigenSolver<Mat3> eig(-s, inertia);
        if (eig.info() != Eigen::Success) continue;
        const double mu = eig.eigenvalues().maxCoeff();
        const double t = mu > 1.0 - kInertiaKept ? (1.0 - kInertiaKept) / mu : 1.0;
        const Eigen::Index r = static_cast<Eigen::Index>(6 * b + 3);
        system_.block<3, 3>(r, r) += t * s;
    }
}

/// A chord iteration (see IslandMember::condenseChord): every member's gradient against
/// the Hessian the island factorised last, the same LDL^T. False, and nothing changed,
/// where a member cannot take it.
bool IslandSolver::solveChord(Island& island) {
    forMembers(island, [&](std::size_t k) { member_value_[k] = island.members[k]->condenseChord() ? 1.0 : 0.0; });
    const bool all = std::all_of(member_value_.begin(), member_value_.begin() + static_cast<std::ptrdiff_t>(island.members.size()),
                                 [](double taken) { return taken > 0.0; });
    if (!all) {
        for (std::size_t k = 0; k < island.members.size(); ++k)
            if (member_value_[k] > 0.0) island.members[k]->cancelChord();
        return false;
    }
    inertiaRhs(island);
    for (std::size_t k = 0; k < island.members.size(); ++k) island.members[k]->addRhsTo(island.slots[k], rhs_);
    du_ = ldlt_.solve(rhs_);
    forMembers(island, [&](std::size_t k) { island.members[k]->backSubstitute(island.slots[k], du_); });
    return true;
}

double IslandSolver::energy(const Island& island, double alpha) {
    double e = 0.0;
    for (std::size_t b = 0; b < island.bodies.size(); ++b) {
        const Eigen::Index r = static_cast<Eigen::Index>(6 * b);
        const Vec6 u = displacement_.segment<6>(r) + alpha * du_.segment<6>(r);
        e += 0.5 * inv_h2_ * u.dot(mass_[b] * u);
    }
    // Each member's energy on its own thread; summed in member order (the same bits on
    // any number of threads).
    forMembers(island, [&](std::size_t k) { member_value_[k] = island.members[k]->energy(alpha); });
    for (std::size_t k = 0; k < island.members.size(); ++k) e += member_value_[k];
    return e;
}

void IslandSolver::moveBodies(Island& island, RigidTable& rigids, const StepContext& ctx, double alpha) {
    for (std::size_t b = 0; b < island.bodies.size(); ++b) {
        const Eigen::Index r = static_cast<Eigen::Index>(6 * b);
        const Vec6 before = displacement_.segment<6>(r);
        const Vec6 step = alpha * du_.segment<6>(r);
        if (!step.allFinite()) continue;
        RigidState& body = rigids.bodies[island.bodies[b].index];
        // Turned from where the pass linearised the contacts (rotations do not add).
        const Vec6 from = before - pass_start_.segment<6>(r);
        displaceBody(body, from, from + step);
        displacement_.segment<6>(r) = before + step;
        body.impulse += (mass_[b] * step).head<3>() * ctx.inv_h;
    }
}

/// A structure held the same way step after step (a board hanging on ropes) is corrected
/// by about as much each step: the island starts from the last step's corrections, each
/// body moved (translated and turned) as best carries its held points by theirs, where that
/// lowers its energy (convex: the same minimum). Not where a string touches a body: a
/// contact the start would jump.
bool IslandSolver::warmStart(Island& island, RigidTable& rigids, const StepContext& ctx) {
    const std::size_t bodies = island.bodies.size();
    du_.setZero(static_cast<Eigen::Index>(6 * bodies));
    pass_start_ = displacement_;
    if (resume_) {
        // Solved again: each body where the last solve left it, the members' own unknowns
        // where they are (the first solve's), whatever the energy says (a start, not a step).
        for (std::size_t b = 0; b < bodies; ++b) {
            const std::size_t index = island.bodies[b].index;
            if (index < last_displacement_.size()) du_.segment<6>(static_cast<Eigen::Index>(6 * b)) = last_displacement_[index];
        }
        for (std::size_t k = 0; k < island.members.size(); ++k) {
            island.members[k]->beginPass();
            island.members[k]->holdStep(island.slots[k], du_);
        }
        moveBodies(island, rigids, ctx, 1.0);
        forMembers(island, [&](std::size_t k) { island.members[k]->apply(1.0, island.slots[k], displacement_); });
        return true;
    }
    if (ctx.cold_strain_starts) return false;
    for (const IslandMember* m : island.members)
        if (m->touchesBodies()) return false;
    hint_normal_.assign(bodies, Mat6::Zero());
    hint_rhs_.setZero(static_cast<Eigen::Index>(6 * bodies));
    for (std::size_t k = 0; k < island.members.size(); ++k) island.members[k]->addWarmHints(island.slots[k], hint_normal_, hint_rhs_);
    for (std::size_t b = 0; b < bodies; ++b) {
        Mat6 normal = hint_normal_[b];
        if (!(normal(0, 0) > 0.0)) continue;
        // A turn the held points do not fix (about the line through two of them, any turn
        // for one) is taken as none: a small weight on the turn's size.
        normal.bottomRightCorner<3, 3>().diagonal().array() += kWarmTurnWeight * normal.bottomRightCorner<3, 3>().trace() / 3.0 + kWarmTurnFloor;
        const Vec6 step = normal.ldlt().solve(hint_rhs_.segment<6>(static_cast<Eigen::Index>(6 * b)));
        if (step.allFinite()) du_.segment<6>(static_cast<Eigen::Index>(6 * b)) = step;
    }
    for (std::size_t k = 0; k < island.members.size(); ++k) {
        island.members[k]->beginPass();
        island.members[k]->warmStep(island.slots[k], du_);
    }
    if (!(energy(island, 1.0) < energy(island, 0.0))) return false;
    moveBodies(island, rigids, ctx, 1.0);
    forMembers(island, [&](std::size_t k) { island.members[k]->apply(1.0, island.slots[k], displacement_); });
    return true;
}

IslandSummary IslandSolver::solveIsland(Island& island, RigidTable& rigids, const StepContext& ctx) {
    IslandSummary report;
    for (const IslandMember* m : island.members) report.strings += m->stringCount();
    report.bodies = island.bodies.size();
    mass_.resize(island.bodies.size());
    for (std::size_t b = 0; b < island.bodies.size(); ++b) mass_[b] = bodyMass(rigids.bodies[island.bodies[b].index]);
    displacement_.setZero(static_cast<Eigen::Index>(6 * island.bodies.size()));
    bool frictional = false;
    for (IslandMember* m : island.members) frictional = frictional || m->frictional();
    const bool warm = warmStart(island, rigids, ctx);
    const int iterations = ctx.settings->strain_iterations * kIterationFactor;
    for (int pass = 0; pass < (frictional ? kFrictionPasses : 1); ++pass) {
        for (IslandMember* m : island.members) m->beginPass();
        pass_start_ = displacement_;
        accepted_energy_.clear();
        bool converged = false;
        // Chord iterations (the last Hessian kept, its factorisations and the island's
        // LDL^T reused) where the island holds no contact, after an iteration whose move
        // fell by kQuadraticRegime or more. A chord step from a Hessian factorised a move
        // d away misses Newton's by ~C d |step| where Newton's own miss is C |step|^2 (C
        // the Hessian's rate of change): as good where d is the last step, which the
        // quadratic regime makes short; not after a long first step (a taut segment's
        // axial stiffness, turned by d / L, swamps its transverse stiffness T / L).
        // From a warm start the first step is short (the change of the structure's
        // correction since the last step): a chord iteration may follow it, as in a
        // string's own solve.
        bool chord_next = false;
        double last_move = 0.0;
        // The energy where the last accepted step ends: the next iteration's start (the
        // energy is fixed within a pass: friction's weights change between passes only).
        bool carried_energy = false;
        double last_energy = 0.0;
        for (int iter = 0; iter < iterations; ++iter) {
            const bool chord = chord_next && solveChord(island);
            if (!chord) {
                solveSystem(island, true);
                for (int round = 0; round < kPredictRounds; ++round) {
                    bool changed = false;
                    for (IslandMember* m : island.members) changed = m->addPredictedContacts() || changed;
                    if (!changed) break;
                    solveSystem(island, false);
                }
            }
            // Backtrack until the (convex) energy is below the reference of the
            // non-monotone search; where no fraction of the step gets there, the state is
            // the minimum to rounding.
            const double e0 = carried_energy ? last_energy : energy(island, 0.0);
            if (accepted_energy_.size() == kEnergyMemory) accepted_energy_.erase(accepted_energy_.begin());
            accepted_energy_.push_back(e0);
            const double reference = *std::max_element(accepted_energy_.begin(), accepted_energy_.end());
            double alpha = 1.0;
            int halving = 0;
            for (; halving < kLineSearchHalvings && !((last_energy = energy(island, alpha)) <= reference); ++halving) alpha *= 0.5;
            const bool stalled = halving == kLineSearchHalvings;
            if (stalled) {
                alpha = 0.0;
                last_energy = e0;
            }
            carried_energy = true;
            moveBodies(island, rigids, ctx, alpha);
            forMembers(island, [&](std::size_t k) { member_value_[k] = island.members[k]->apply(alpha, island.slots[k], displacement_); });
            double worst = 0.0;
            for (std::size_t k = 0; k < island.members.size(); ++k) worst = std::max(worst, member_value_[k]);
            ++report.iterations;
            report.residual = worst;
            // A chord step is the Newton step only to the change of the Hessian since it
            // was factorised: a short one ends the solve only where it fell as fast as a
            // Newton step would (and one the line search refused is retried as Newton's).
            const bool fell = last_move > 0.0 && worst < kQuadraticRegime * last_move;
            // A Newton step ends the solve where the distance still to go is within
            // tolerance: its move where the moves fall quadratically, but at a linear rate r
            // (friction's majoriser near the verge of slipping: r ~ 0.9) the moves still to
            // come sum to about move r / (1 - r), and a move within tolerance is far from
            // the fixed point (a rope sliding over a movable drum stopped a third of the way).
            const double rate = last_move > 0.0 ? std::min(worst / last_move, kSlowestRate) : 0.0;
            const double to_go = std::max(worst, worst * rate / (1.0 - rate));
            if (chord ? (!stalled && worst < 1.0 && fell) : (stalled || to_go < 1.0)) {
                converged = true;
                break;
            }
            chord_next = !stalled && (fell || (warm && pass == 0 && iter == 0));
            last_move = worst;
        }
        if (!frictional) break;
        double change = 0.0;
        for (IslandMember* m : island.members) change = std::max(change, m->reweigh());
        if (converged && change < kFrictionSettled) break;
    }
    for (IslandMember* m : island.members) m->finish(report.iterations);
    if (last_displacement_.size() < rigids.bodies.size()) last_displacement_.resize(rigids.bodies.size(), Vec6::Zero());
    for (std::size_t b = 0; b < island.bodies.size(); ++b)
        last_displacement_[island.bodies[b].index] = displacement_.segment<6>(static_cast<Eigen::Index>(6 * b));
    return report;
}

}  // namespace tearables::detail
