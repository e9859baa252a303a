// The contract between a material that moves rigid bodies and the island solve
// (src/island/): everything coupled through a movable body is solved as one system.
//
// The island minimises one energy over its members' unknowns and its bodies' six each
// (displacement u, rotation vector theta, from where the solve started):
//     E = sum_bodies u^T M u / (2 h^2)  +  sum_members E_member(x_member, u)
// by Newton with substructuring: each member eliminates its own unknowns onto the bodies
// it touches (its Schur complement), the island solves the small dense body system, and
// each member takes its own step back (back substitution); a line search on E.
#pragma once

#include "sim/body_motion.hpp"
#include "sim/rigid_table.hpp"
#include "sim/step_context.hpp"

#include <Eigen/Core>

#include <vector>

namespace tearables::detail {

/// One member of an island (a string): its unknowns, eliminated onto its bodies. The
/// body arguments are island vectors, six entries per body; `slot[k]` is the island's
/// index of the member's k-th body (bodies()).
class IslandMember {
public:
    virtual ~IslandMember() = default;
    /// The movable bodies the member couples to.
    virtual const std::vector<RigidId>& bodies() const = 0;
    /// Whether the member touches a body (contacts): the island then starts cold.
    virtual bool touchesBodies() const = 0;
    /// The warm start: each point the member holds on a body, its last step's correction c
    /// and its arm r from the body's centre, as the least-squares terms of the body's
    /// move (u, theta) that carries the point by c: J^T J into `normal` (per body) and
    /// J^T c into `rhs` (6 per body), J = [I, -[r]x].
    virtual void addWarmHints(const std::vector<int>& slot, std::vector<Mat6>& normal, Eigen::VectorXd& rhs) const = 0;
    /// The warm start's step: the bodies' `du`, the member's own its last step's
    /// correction. The island takes it where it lowers the energy.
    virtual void warmStep(const std::vector<int>& slot, const Eigen::VectorXd& du) = 0;
    /// A step of the bodies alone, `du`, the member's own unknowns held: an island solved
    /// again starts from where the first solve left its bodies (IslandSolve::restart).
    virtual void holdStep(const std::vector<int>& slot, const Eigen::VectorXd& du) { backSubstitute(slot, du); }
    /// Start of a pass: contacts linearised where the bodies are now.
    virtual void beginPass() = 0;
    /// The Newton system at the current state, condensed onto the member's bodies (its
    /// Schur complement and reduced right-hand side, minus the gradient). `fresh`: the
    /// first system of an iteration (contacts that touch now join it; later ones of the
    /// same iteration keep the set addPredictedContacts chose). Members condense in parallel.
    virtual void condense(bool fresh) = 0;
    /// A chord iteration's condensed system: the gradient at the current state against the
    /// Hessian of the last condense(), which the island keeps factorised. False where the
    /// member cannot (it touches bodies, or its model changed branch): the island then
    /// condenses every member afresh.
    virtual bool condenseChord() { return false; }
    /// Undoes a condenseChord that succeeded where another member's failed (the island
    /// condenses afresh instead): the member counts the iteration once.
    virtual void cancelChord() {}
    /// Adds the condensed right-hand side alone (after condenseChord) to the island's `rhs`.
    virtual void addRhsTo(const std::vector<int>& /*slot*/, Eigen::VectorXd& /*rhs*/) const {}
    /// Adds the condensed system to the island's `system` and `rhs`.
    virtual void addTo(const std::vector<int>& slot, Eigen::MatrixXd& system, Eigen::VectorXd& rhs) const = 0;
    /// Adds to `softening` (per island body, its rotation block) the negative part of the
    /// turning stiffness of the points the member holds on its bodies, which condense()
    /// left out of its system: the island adds it where the body's own inertia keeps the
    /// system positive definite (IslandSolver::addSoftening).
    virtual void addTurningSoftening(const std::vector<int>& /*slot*/, std::vector<Mat3>& /*softening*/) const {}
    /// The member's own step for the bodies' step `du`.
    virtual void backSubstitute(const std::vector<int>& slot, const Eigen::VectorXd& du) = 0;
    /// Holds the clear contacts the full step would run into and lets go of those held so
    /// that it no longer does; true where the set changed (the system is then condensed
    /// again).
    virtual bool addPredictedContacts() = 0;
    /// E_member at alpha times the step (its own, and its bodies' from backSubstitute).
    virtual double energy(double alpha) const = 0;
    /// Takes alpha times the step; the island has moved the bodies already, to
    /// `displacement` from where the solve started. Returns the largest move over the
    /// member's tolerance (below 1: converged).
    virtual double apply(double alpha, const std::vector<int>& slot, const Eigen::VectorXd& displacement) = 0;
    /// Whether the member has friction whose lagged weights need passes.
    virtual bool frictional() const = 0;
    /// Friction's weights from this pass; returns their largest relative change.
    virtual double reweigh() = 0;
    /// End of the solve.
    virtual void finish(int iterations) = 0;
    /// Whether the member is contacts between bodies rather than a string (reports count strings).
    virtual bool isBodyContacts() const { return false; }
    /// The strings the member solves (reports count them).
    virtual std::size_t stringCount() const { return isBodyContacts() ? 0 : 1; }
};

/// Groups members into islands (members sharing a body) and solves each.
class IslandSolve {
public:
    virtual ~IslandSolve() = default;
    virtual void solve(const std::vector<IslandMember*>& members, RigidTable& rigids, const StepContext& ctx) = 0;
    /// Whether the step has members of the solve's own (contacts between bodies): it is
    /// then called even where no string holds or touches a movable body.
    virtual bool hasOwnMembers() const = 0;
    /// Before the step's islands are solved again (the bodies back where the first solve
    /// found them): its own members' inputs as the step gave them, and the next solve
    /// starts each body where the first solve left it (IslandMember::holdStep).
    virtual void restart() = 0;
    /// Keeps the last solve's outcome (what it wrote to its own members' contacts and
    /// joints, its reports, its bodies' displacements), and puts it back: a solve again
    /// that does not converge is undone.
    virtual void keepOutcome() = 0;
    virtual void restoreOutcome() = 0;
    /// Whether every island of the last solve converged.
    virtual bool converged() const = 0;
};

}  // namespace tearables::detail
