// Claiming island bodies from Bullet's constraint solver (internal to the plugin).
//
// A substep solves body-body contacts in Bullet's solver, then strings in our action; to
// solve an island (strings, their bodies and the contacts between those bodies) as one
// system, Bullet's solver must leave the island alone. IslandClaimSolver wraps the world's
// constraint solver: bodies flagged as claimed, every contact manifold and typed constraint
// that touches one are withheld; everything else reaches the wrapped solver unchanged. The
// withheld manifolds are kept for the action to read after the solve.
// Bullet's step order and why this works: docs/bullet-island-claim.md.
#pragma once

#include <BulletDynamics/ConstraintSolver/btConstraintSolver.h>
#include <LinearMath/btTransform.h>
#include <LinearMath/btVector3.h>

#include <functional>
#include <vector>

class btCollisionObject;
class btDiscreteDynamicsWorld;
class btPersistentManifold;
class btRigidBody;
class btTypedConstraint;

namespace tearables {

/// Which dynamic bodies a claim withholds from Bullet's solver.
enum class ClaimScope {
    /// The flagged bodies and every dynamic body in their Bullet simulation islands (the
    /// island tags of btSimulationIslandManager). Closed: no withheld contact or joint
    /// reaches a body that Bullet still solves.
    Island,
    /// The flagged bodies only. Contacts and joints between them and unclaimed bodies are
    /// withheld too: the unclaimed side then feels nothing from them unless the caller
    /// solves them.
    Body,
};

/// A withheld body as it was at the solve, before Bullet's integrateTransforms moved it.
struct ClaimedBody {
    btRigidBody* body = nullptr;
    btTransform transform;      ///< world transform of the centre of mass at the step's start
    btVector3 linearVelocity;   ///< m/s: the previous step's, damped; no forces of this step
    btVector3 angularVelocity;  ///< rad/s: likewise
};

/// A constraint solver that withholds claimed bodies, and the contacts and joints touching
/// them, from the solver it wraps. Installing it replaces the world's solver; destroying it
/// puts that solver back. Destroy it before the world, and wrappers of one world in the
/// reverse order of their creation.
class IslandClaimSolver final : public btConstraintSolver {
public:
    /// Wraps the solver `world` has now and installs itself in its place. Throws
    /// std::invalid_argument if `world` has a multibody solver (btMultiBodyDynamicsWorld
    /// solves through its own island callback, which would bypass this wrapper).
    explicit IslandClaimSolver(btDiscreteDynamicsWorld& world, ClaimScope scope = ClaimScope::Island);
    /// Reinstalls the wrapped solver, with the ownership the world had of it.
    ~IslandClaimSolver() override;
    /// The world has been destroyed (without this wrapper: the world never frees it): the
    /// destructor then touches nothing of it, and frees the wrapped solver if the world
    /// owned it (as ~btDiscreteDynamicsWorld would have).
    void worldDestroyed() { worldGone_ = true; }
    IslandClaimSolver(const IslandClaimSolver&) = delete;
    IslandClaimSolver& operator=(const IslandClaimSolver&) = delete;

    /// Flags `body` as claimed from the next step on. Throws std::invalid_argument if `body`
    /// is static or kinematic (those are shared between islands; Bullet solves them as fixed).
    /// Release a body before deleting it; a flagged body outside the world is ignored.
    void claim(btRigidBody& body);
    /// Unflags `body` (no effect if it was not flagged).
    void release(const btRigidBody& body);
    /// Unflags every body.
    void releaseAll();
    /// Whether `body` is flagged (its island may be claimed through another body too).
    bool isFlagged(const btRigidBody& body) const;
    ClaimScope scope() const { return scope_; }
    /// Leaves to Bullet every island (Island scope) or flagged body (Body scope) with a
    /// typed constraint on one of its bodies, for a caller that cannot solve joints. Off
    /// by default.
    void setLeaveJointed(bool leave) { leaveJointed_ = leave; }
    /// With setLeaveJointed: the joints the caller solves itself (`takes` returns true:
    /// they are withheld with their bodies like manifolds) do not leave their islands to
    /// Bullet; nor do disabled joints. Empty: none.
    void setTakenJoints(std::function<bool(const btTypedConstraint&)> takes) { takes_ = std::move(takes); }
    /// The solver that receives the unclaimed work.
    btConstraintSolver& wrapped() const { return *wrapped_; }

    /// What the last solveConstraints withheld, in the order Bullet passed it. The
    /// manifolds stay valid until the next step's collision detection (or until one of
    /// their bodies leaves the world); the constraints as long as the user keeps them.
    const std::vector<ClaimedBody>& claimedBodies() const { return claimedBodies_; }
    const std::vector<btPersistentManifold*>& withheldManifolds() const { return withheldManifolds_; }
    const std::vector<btTypedConstraint*>& withheldConstraints() const { return withheldConstraints_; }

    /// Whether the last solve withheld `object` (false for static and kinematic objects).
    bool withholds(const btCollisionObject& object) const;

    // btConstraintSolver: called by btDiscreteDynamicsWorld::solveConstraints.
    void prepareSolve(int numBodies, int numManifolds) override;
    btScalar solveGroup(btCollisionObject** bodies, int numBodies, btPersistentManifold** manifolds, int numManifolds,
                        btTypedConstraint** constraints, int numConstraints, const btContactSolverInfo& info,
                        btIDebugDraw* debugDrawer, btDispatcher* dispatcher) override;
    void allSolved(const btContactSolverInfo& info, btIDebugDraw* debugDrawer) override;
    void reset() override;
    btConstraintSolverType getSolverType() const override;

private:
    bool withheldManifold(const btPersistentManifold& manifold) const;
    bool withheldConstraint(const btTypedConstraint& constraint) const;

    btDiscreteDynamicsWorld& world_;
    btConstraintSolver* wrapped_;
    bool worldOwnedWrapped_;  // the world allocated its solver itself and frees it when it dies
    ClaimScope scope_;
    bool leaveJointed_ = false;
    std::function<bool(const btTypedConstraint&)> takes_;
    bool worldGone_ = false;

    std::vector<const btRigidBody*> flagged_;  // sorted, for binary search
    std::vector<int> claimedTags_;             // sorted island tags of flagged bodies (Island scope)
    std::vector<int> jointedTags_;             // island tags of bodies with joints (leaveJointed_)
    std::vector<const btRigidBody*> jointed_;  // sorted: dynamic bodies with joints (leaveJointed_)
    bool anyClaimed_ = false;                  // a flagged body is in the world this step

    std::vector<ClaimedBody> claimedBodies_;
    std::vector<btPersistentManifold*> withheldManifolds_;
    std::vector<btTypedConstraint*> withheldConstraints_;

    // The unclaimed part of one solveGroup call, reused between calls.
    std::vector<btCollisionObject*> passBodies_;
    std::vector<btPersistentManifold*> passManifolds_;
    std::vector<btTypedConstraint*> passConstraints_;
};

}  // namespace tearables
