// IslandClaimSolver: filters what btDiscreteDynamicsWorld::solveConstraints hands to the
// world's solver. The facts it relies on, with their places in Bullet 3.24, are in
// docs/bullet-island-claim.md.
#include "island_claim.hpp"

#include <btBulletDynamicsCommon.h>

#include <algorithm>
#include <stdexcept>

namespace tearables {

namespace {

// btDiscreteDynamicsWorld::m_ownsConstraintSolver is protected. A pointer to it formed in a
// derived class reads and writes it on any world; no object of this class is ever made.
struct SolverOwnership : btDiscreteDynamicsWorld {
    static bool btDiscreteDynamicsWorld::*flag() { return &SolverOwnership::m_ownsConstraintSolver; }
};

template <class T>
bool contains(const std::vector<T>& sorted, const T& value) {
    return std::binary_search(sorted.begin(), sorted.end(), value);
}

template <class T>
T* dataOrNull(std::vector<T>& v) {
    return v.empty() ? nullptr : v.data();
}

}  // namespace

IslandClaimSolver::IslandClaimSolver(btDiscreteDynamicsWorld& world, ClaimScope scope)
    : world_(world),
      wrapped_(world.getConstraintSolver()),
      worldOwnedWrapped_(world.*SolverOwnership::flag()),
      scope_(scope) {
    if (wrapped_ == nullptr) throw std::invalid_argument("world: has no constraint solver to wrap");
    if (wrapped_->getSolverType() == BT_MULTIBODY_SOLVER)
        throw std::invalid_argument(
            "world: has a multibody constraint solver; btMultiBodyDynamicsWorld::solveConstraints calls it "
            "directly, so a wrapper would be bypassed");
    // btDiscreteDynamicsWorld::setConstraintSolver frees the old solver if the world owns it
    // (a world built with a null solver): take the ownership over for as long as we wrap it.
    world.*SolverOwnership::flag() = false;
    world.setConstraintSolver(this);
}

IslandClaimSolver::~IslandClaimSolver() {
    if (!worldGone_ && world_.getConstraintSolver() == this) {
        world_.setConstraintSolver(wrapped_);
        world_.*SolverOwnership::flag() = worldOwnedWrapped_;
    } else if (worldOwnedWrapped_) {
        // Someone installed another solver over us: nobody else will free the world's own
        // solver; free it as ~btDiscreteDynamicsWorld would have.
        wrapped_->~btConstraintSolver();
        btAlignedFree(wrapped_);
    }
}

void IslandClaimSolver::claim(btRigidBody& body) {
    if (body.isStaticOrKinematicObject())
        throw std::invalid_argument("body: static and kinematic bodies cannot be claimed (Bullet shares them "
                                    "between islands as fixed bodies)");
    const auto at = std::lower_bound(flagged_.begin(), flagged_.end(), &body);
    if (at == flagged_.end() || *at != &body) flagged_.insert(at, &body);
}

void IslandClaimSolver::release(const btRigidBody& body) {
    const auto at = std::lower_bound(flagged_.begin(), flagged_.end(), &body);
    if (at != flagged_.end() && *at == &body) flagged_.erase(at);
}

void IslandClaimSolver::releaseAll() { flagged_.clear(); }

bool IslandClaimSolver::isFlagged(const btRigidBody& body) const { return contains(flagged_, &body); }

bool IslandClaimSolver::withholds(const btCollisionObject& object) const {
    if (!anyClaimed_ || object.isStaticOrKinematicObject()) return false;
    if (scope_ == ClaimScope::Island) return contains(claimedTags_, object.getIslandTag());
    const btRigidBody* body = btRigidBody::upcast(&object);
    return body != nullptr && contains(flagged_, body) && !contains(jointed_, body);
}

bool IslandClaimSolver::withheldManifold(const btPersistentManifold& manifold) const {
    return withholds(*manifold.getBody0()) || withholds(*manifold.getBody1());
}

bool IslandClaimSolver::withheldConstraint(const btTypedConstraint& constraint) const {
    return withholds(constraint.getRigidBodyA()) || withholds(constraint.getRigidBodyB());
}

// Called once per solveConstraints, after calculateSimulationIslands has stored the island
// tags and before buildAndProcessIslands: the place to decide what this step claims. Only
// the world's own objects are looked at, so a flagged body that left the world is never read.
void IslandClaimSolver::prepareSolve(int numBodies, int numManifolds) {
    claimedBodies_.clear();
    withheldManifolds_.clear();
    withheldConstraints_.clear();
    claimedTags_.clear();
    anyClaimed_ = false;
    if (!flagged_.empty()) {
        const btCollisionObjectArray& objects = world_.getCollisionObjectArray();
        // The world's joints (a body's constraint refs are kept only for joints that
        // disable collision between their bodies, so the world's list is read).
        jointed_.clear();
        jointedTags_.clear();
        if (leaveJointed_) {
            for (int i = 0; i < world_.getNumConstraints(); ++i) {
                const btTypedConstraint* joint = world_.getConstraint(i);
                if (!joint->isEnabled() || (takes_ && takes_(*joint))) continue;
                for (const btRigidBody* body : {&joint->getRigidBodyA(), &joint->getRigidBodyB()}) {
                    if (body->isStaticOrKinematicObject()) continue;
                    jointed_.push_back(body);
                    jointedTags_.push_back(body->getIslandTag());
                }
            }
            std::sort(jointed_.begin(), jointed_.end());
        }
        for (int i = 0; i < objects.size(); ++i) {
            const btCollisionObject* object = objects[i];
            const btRigidBody* body = btRigidBody::upcast(object);
            if (body == nullptr || body->isStaticOrKinematicObject()) continue;
            const bool jointed = contains(jointed_, body);
            if (!contains(flagged_, body) || (jointed && scope_ == ClaimScope::Body)) continue;
            if (scope_ == ClaimScope::Island) claimedTags_.push_back(body->getIslandTag());
            anyClaimed_ = true;
        }
        std::sort(claimedTags_.begin(), claimedTags_.end());
        claimedTags_.erase(std::unique(claimedTags_.begin(), claimedTags_.end()), claimedTags_.end());
        if (scope_ == ClaimScope::Island && !jointedTags_.empty()) {
            std::sort(jointedTags_.begin(), jointedTags_.end());
            claimedTags_.erase(std::remove_if(claimedTags_.begin(), claimedTags_.end(),
                                              [&](int tag) { return contains(jointedTags_, tag); }),
                               claimedTags_.end());
            anyClaimed_ = !claimedTags_.empty();
        }
    }
    wrapped_->prepareSolve(numBodies, numManifolds);
}

// One call per island, or per batch of whole islands (InplaceSolverIslandCallback with
// m_minimumSolverBatchSize > 1), or once for everything (islandId -1, when the island
// manager does not split islands; static bodies are then in `bodies` too). Filtering each
// body, manifold and constraint on its own is right in all three cases.
btScalar IslandClaimSolver::solveGroup(btCollisionObject** bodies, int numBodies, btPersistentManifold** manifolds,
                                       int numManifolds, btTypedConstraint** constraints, int numConstraints,
                                       const btContactSolverInfo& info, btIDebugDraw* debugDrawer,
                                       btDispatcher* dispatcher) {
    if (!anyClaimed_)
        return wrapped_->solveGroup(bodies, numBodies, manifolds, numManifolds, constraints, numConstraints, info,
                                    debugDrawer, dispatcher);
    passBodies_.clear();
    passManifolds_.clear();
    passConstraints_.clear();
    for (int i = 0; i < numBodies; ++i) {
        btCollisionObject* object = bodies[i];
        if (!withholds(*object)) {
            passBodies_.push_back(object);
        } else if (btRigidBody* body = btRigidBody::upcast(object)) {
            claimedBodies_.push_back(
                ClaimedBody{body, body->getWorldTransform(), body->getLinearVelocity(), body->getAngularVelocity()});
        }
    }
    for (int i = 0; i < numManifolds; ++i)
        (withheldManifold(*manifolds[i]) ? withheldManifolds_ : passManifolds_).push_back(manifolds[i]);
    for (int i = 0; i < numConstraints; ++i)
        (withheldConstraint(*constraints[i]) ? withheldConstraints_ : passConstraints_).push_back(constraints[i]);

    if (passBodies_.empty() && passManifolds_.empty() && passConstraints_.empty()) return 0;
    return wrapped_->solveGroup(dataOrNull(passBodies_), static_cast<int>(passBodies_.size()),
                                dataOrNull(passManifolds_), static_cast<int>(passManifolds_.size()),
                                dataOrNull(passConstraints_), static_cast<int>(passConstraints_.size()), info,
                                debugDrawer, dispatcher);
}

void IslandClaimSolver::allSolved(const btContactSolverInfo& info, btIDebugDraw* debugDrawer) {
    wrapped_->allSolved(info, debugDrawer);
}

void IslandClaimSolver::reset() { wrapped_->reset(); }

btConstraintSolverType IslandClaimSolver::getSolverType() const { return wrapped_->getSolverType(); }

}  // namespace tearables
