// IslandClaimSolver (plugin/island_claim.hpp): claimed bodies, their contacts and joints
// are withheld from Bullet's solver and delivered to us; everything else is solved by the
// wrapped solver exactly as without the wrapper.
#include "island_claim.hpp"

#include "bullet_fixture.hpp"

#include <BulletCollision/CollisionDispatch/btSimulationIslandManager.h>
#include <btBulletDynamicsCommon.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <stdexcept>
#include <vector>

namespace {

using tearables::ClaimScope;
using tearables::IslandClaimSolver;
using tearables::testing::Physics;

constexpr double kStep = 0.01;  // s, Physics::step's default

/// A static ground slab whose top face is y = 0.
btRigidBody& addGround(Physics& p) { return p.box(btVector3(20, 0.5f, 20), 0.0, btVector3(0, -0.5f, 0)); }

/// Stands in for the island solver: gives each claimed body the free motion Bullet's solver
/// would have (semi-implicit Euler on getTotalForce, which holds gravity) from the pose and
/// velocity it had at the solve, and overwrites what integrateTransforms did.
struct FreeMotion : btActionInterface {
    const IslandClaimSolver& claims;
    explicit FreeMotion(const IslandClaimSolver& c) : claims(c) {}
    void updateAction(btCollisionWorld*, btScalar h) override {
        for (const tearables::ClaimedBody& c : claims.claimedBodies()) {
            const btVector3 v = c.linearVelocity + c.body->getTotalForce() * c.body->getInvMass() * h;
            btTransform x = c.transform;
            x.setOrigin(x.getOrigin() + v * h);
            c.body->setCenterOfMassTransform(x);
            c.body->setLinearVelocity(v);
        }
    }
    void debugDraw(btIDebugDraw*) override {}
};

/// A user's own solver: Bullet's, counting what it is given.
struct CountingSolver : btSequentialImpulseConstraintSolver {
    int calls = 0;
    std::vector<const btCollisionObject*> bodies;
    std::vector<const btTypedConstraint*> constraints;
    btScalar solveGroup(btCollisionObject** b, int nb, btPersistentManifold** m, int nm, btTypedConstraint** c, int nc,
                        const btContactSolverInfo& info, btIDebugDraw* draw, btDispatcher* dispatcher) override {
        ++calls;
        bodies.insert(bodies.end(), b, b + nb);
        constraints.insert(constraints.end(), c, c + nc);
        return btSequentialImpulseConstraintSolver::solveGroup(b, nb, m, nm, c, nc, info, draw, dispatcher);
    }
    bool saw(const btCollisionObject& o) const { return std::count(bodies.begin(), bodies.end(), &o) > 0; }
    bool saw(const btTypedConstraint& c) const { return std::count(constraints.begin(), constraints.end(), &c) > 0; }
};

bool claimed(const IslandClaimSolver& s, const btRigidBody& b) {
    const auto& c = s.claimedBodies();
    return std::any_of(c.begin(), c.end(), [&](const tearables::ClaimedBody& x) { return x.body == &b; });
}

TEST(IslandClaim, UnclaimedBoxRestsOnTheGround) {
    Physics p;
    addGround(p);
    btRigidBody& box = p.box(btVector3(0.5f, 0.5f, 0.5f), 1.0, btVector3(0, 0.5f, 0));
    IslandClaimSolver claims(*p.world);  // installed, nothing claimed
    p.step(120);
    EXPECT_GT(box.getWorldTransform().getOrigin().y() - 0.5f, -0.01f);  // penetration < 1 cm
    EXPECT_TRUE(claims.claimedBodies().empty());
    EXPECT_TRUE(claims.withheldManifolds().empty());
}

TEST(IslandClaim, ClaimedBoxIsNotHeldAndItsContactIsDelivered) {
    Physics p;
    btRigidBody& ground = addGround(p);
    btRigidBody& box = p.box(btVector3(0.5f, 0.5f, 0.5f), 1.0, btVector3(0, 0.5f, 0));
    IslandClaimSolver claims(*p.world);
    FreeMotion motion(claims);
    p.world->addAction(&motion);
    claims.claim(box);

    p.step(1);
    ASSERT_EQ(claims.claimedBodies().size(), 1u);
    EXPECT_EQ(claims.claimedBodies()[0].body, &box);
    ASSERT_EQ(claims.withheldManifolds().size(), 1u);
    const btPersistentManifold& m = *claims.withheldManifolds()[0];
    const bool boxFirst = m.getBody0() == &box;
    EXPECT_EQ(boxFirst ? m.getBody1() : m.getBody0(), &ground);
    ASSERT_GE(m.getNumContacts(), 3);  // a face on a face: Bullet keeps up to 4 points
    const btTransform& x0 = claims.claimedBodies()[0].transform;  // the pose collision saw
    for (int i = 0; i < m.getNumContacts(); ++i) {
        const btManifoldPoint& pt = m.getContactPoint(i);
        // m_normalWorldOnB points from body1 to body0: up if the box is body0.
        EXPECT_NEAR(pt.m_normalWorldOnB.y(), boxFirst ? 1.0f : -1.0f, 1e-4f);
        EXPECT_NEAR(pt.getDistance(), 0.0f, 0.01f);  // touching
        EXPECT_GT(pt.m_combinedFriction, 0.0f);
        // The box's local point is on its bottom face, and maps to the world point.
        const btVector3& local = boxFirst ? pt.m_localPointA : pt.m_localPointB;
        EXPECT_NEAR(local.y(), -0.5f, 0.01f);
        EXPECT_LT((x0 * local - (boxFirst ? pt.getPositionWorldOnA() : pt.getPositionWorldOnB())).length(), 1e-4f);
    }

    p.step(119);
    EXPECT_LT(box.getWorldTransform().getOrigin().y(), -1.0f);  // fell into the ground
    p.world->removeAction(&motion);
}

TEST(IslandClaim, ClaimedBodyKeepsItsVelocityWithoutForces) {
    // Gravity and applied forces enter velocities inside the solver (initSolverBody,
    // writeBackBodies): a claimed body that nobody solves coasts at its old velocity.
    Physics p;
    btRigidBody& box = p.box(btVector3(0.5f, 0.5f, 0.5f), 2.0, btVector3(0, 3, 0));
    box.setLinearVelocity(btVector3(1, 0, 0));
    IslandClaimSolver claims(*p.world);
    claims.claim(box);
    p.step(10);
    EXPECT_EQ(box.getLinearVelocity(), btVector3(1, 0, 0));
    EXPECT_NEAR(box.getWorldTransform().getOrigin().x(), 10 * kStep, 1e-5);
    EXPECT_EQ(box.getWorldTransform().getOrigin().y(), 3.0f);
}

/// Two stacks of three boxes, 10 m apart, 2-3 cm apart vertically so that they settle; the
/// gaps are under the broadphase's AABB padding, so each stack is one Bullet island.
std::vector<btRigidBody*> addStacks(Physics& p) {
    addGround(p);
    std::vector<btRigidBody*> boxes;
    for (float x : {-5.0f, 5.0f})
        for (int k = 0; k < 3; ++k)
            boxes.push_back(&p.box(btVector3(0.5f, 0.5f, 0.5f), 1.0 + k,
                                   btVector3(x + 0.1f * static_cast<float>(k), 0.52f + 1.03f * static_cast<float>(k), 0)));
    return boxes;
}

bool sameBits(const btRigidBody& a, const btRigidBody& b) {
    auto same = [](const btVector3& u, const btVector3& v) { return u.x() == v.x() && u.y() == v.y() && u.z() == v.z(); };
    const btMatrix3x3& ra = a.getWorldTransform().getBasis();
    const btMatrix3x3& rb = b.getWorldTransform().getBasis();
    return same(a.getWorldTransform().getOrigin(), b.getWorldTransform().getOrigin()) && same(ra[0], rb[0]) &&
           same(ra[1], rb[1]) && same(ra[2], rb[2]) && same(a.getLinearVelocity(), b.getLinearVelocity()) &&
           same(a.getAngularVelocity(), b.getAngularVelocity());
}

/// How Bullet hands islands to the solver (docs/bullet-island-claim.md): batched (the
/// default, m_minimumSolverBatchSize 128), one island per call, or everything in one call.
enum class Handing { Batched, PerIsland, Unsplit };

void setHanding(btDiscreteDynamicsWorld& world, Handing h) {
    if (h == Handing::PerIsland) world.getSolverInfo().m_minimumSolverBatchSize = 1;
    if (h == Handing::Unsplit) world.getSimulationIslandManager()->setSplitIslands(false);
}

class IslandClaimStacks : public ::testing::TestWithParam<Handing> {};

TEST_P(IslandClaimStacks, ClaimingOneStackLeavesTheOtherBitForBit) {
    Physics plain, wrapped;
    const std::vector<btRigidBody*> a = addStacks(plain);
    const std::vector<btRigidBody*> b = addStacks(wrapped);
    setHanding(*plain.world, GetParam());
    setHanding(*wrapped.world, GetParam());
    IslandClaimSolver claims(*wrapped.world);  // Island scope: the whole left stack
    claims.claim(*b[0]);
    for (int s = 0; s < 150; ++s) {
        plain.step(1);
        wrapped.step(1);
        for (int k = 0; k < 3; ++k) EXPECT_TRUE(claimed(claims, *b[k])) << "left box " << k << ", step " << s;
        for (int k = 3; k < 6; ++k) {
            EXPECT_FALSE(claimed(claims, *b[k])) << "right box " << k << ", step " << s;
            ASSERT_TRUE(sameBits(*a[k], *b[k])) << "right box " << k << " differs at step " << s;
        }
    }
    // The right stack did something worth comparing: it fell and settled on the ground.
    EXPECT_NEAR(a[3]->getWorldTransform().getOrigin().y(), 0.5f, 0.01f);
    // The left stack was Bullet's in the plain run only (no one solves it in the other).
    EXPECT_NEAR(a[0]->getWorldTransform().getOrigin().y(), 0.5f, 0.01f);
    EXPECT_EQ(b[0]->getWorldTransform().getOrigin().y(), 0.52f);
}

INSTANTIATE_TEST_SUITE_P(IslandClaim, IslandClaimStacks,
                         ::testing::Values(Handing::Batched, Handing::PerIsland, Handing::Unsplit));

TEST(IslandClaim, UsersSolverGetsTheRestAndIsRestored) {
    Physics p;
    addGround(p);
    btRigidBody& mine = p.box(btVector3(0.5f, 0.5f, 0.5f), 1.0, btVector3(-5, 0.5f, 0));
    btRigidBody& theirs = p.box(btVector3(0.5f, 0.5f, 0.5f), 1.0, btVector3(5, 0.5f, 0));
    CountingSolver user;
    p.world->setConstraintSolver(&user);
    {
        IslandClaimSolver claims(*p.world);
        EXPECT_EQ(p.world->getConstraintSolver(), &claims);
        EXPECT_EQ(&claims.wrapped(), &user);
        EXPECT_EQ(claims.getSolverType(), BT_SEQUENTIAL_IMPULSE_SOLVER);
        claims.claim(mine);
        p.step(20);
        EXPECT_GT(user.calls, 0);
        EXPECT_TRUE(user.saw(theirs));
        EXPECT_FALSE(user.saw(mine));
        EXPECT_NEAR(theirs.getWorldTransform().getOrigin().y(), 0.5f, 0.01f);  // still held
    }
    EXPECT_EQ(p.world->getConstraintSolver(), &user);
    const int before = user.calls;
    p.step(5);
    EXPECT_GT(user.calls, before);
    EXPECT_TRUE(user.saw(mine));  // Bullet's again
}

TEST(IslandClaim, WorldOwnedSolverSurvivesTheWrapper) {
    // A world built with a null solver owns and frees its own; setConstraintSolver would
    // free it on the spot if the wrapper did not take the ownership over.
    btDefaultCollisionConfiguration config;
    btCollisionDispatcher dispatcher(&config);
    btDbvtBroadphase broadphase;
    auto world = std::make_unique<btDiscreteDynamicsWorld>(&dispatcher, &broadphase, nullptr, &config);
    btConstraintSolver* own = world->getConstraintSolver();
    btBoxShape groundShape(btVector3(20, 0.5f, 20)), boxShape(btVector3(0.5f, 0.5f, 0.5f));
    btRigidBody ground(0, nullptr, &groundShape);
    ground.setWorldTransform(btTransform(btQuaternion::getIdentity(), btVector3(0, -0.5f, 0)));
    btVector3 inertia;
    boxShape.calculateLocalInertia(1, inertia);
    btRigidBody box(1, nullptr, &boxShape, inertia);
    box.setWorldTransform(btTransform(btQuaternion::getIdentity(), btVector3(0, 0.5f, 0)));
    world->addRigidBody(&ground);
    world->addRigidBody(&box);
    {
        IslandClaimSolver claims(*world);
        EXPECT_EQ(&claims.wrapped(), own);
        for (int i = 0; i < 60; ++i) world->stepSimulation(0.01f, 1, 0.01f);
    }
    EXPECT_EQ(world->getConstraintSolver(), own);
    for (int i = 0; i < 60; ++i) world->stepSimulation(0.01f, 1, 0.01f);
    EXPECT_NEAR(box.getWorldTransform().getOrigin().y(), 0.5f, 0.01f);
    world->removeRigidBody(&box);
    world->removeRigidBody(&ground);
    world.reset();  // frees its own solver (under AddressSanitizer: exactly once)
}

TEST(IslandClaim, ClaimRefusesStaticBodies) {
    Physics p;
    btRigidBody& ground = addGround(p);
    IslandClaimSolver claims(*p.world);
    EXPECT_THROW(claims.claim(ground), std::invalid_argument);
    EXPECT_FALSE(claims.isFlagged(ground));
}

/// Four free bodies in a row, 3 m apart, no ground; a ball joint between the first two and
/// one between the last two.
struct Joints {
    Physics p;
    CountingSolver user;
    std::vector<btRigidBody*> body;
    std::unique_ptr<btPoint2PointConstraint> ab, cd;
    Joints() {
        for (int k = 0; k < 4; ++k) body.push_back(&p.sphere(0.3, 1.0, btVector3(3.0f * static_cast<float>(k), 5, 0)));
        ab = std::make_unique<btPoint2PointConstraint>(*body[0], *body[1], btVector3(0.5f, 0, 0), btVector3(-0.5f, 0, 0));
        cd = std::make_unique<btPoint2PointConstraint>(*body[2], *body[3], btVector3(0.5f, 0, 0), btVector3(-0.5f, 0, 0));
        p.world->addConstraint(ab.get());
        p.world->addConstraint(cd.get());
        p.world->setConstraintSolver(&user);
    }
    ~Joints() {
        p.world->removeConstraint(ab.get());
        p.world->removeConstraint(cd.get());
    }
};

TEST(IslandClaim, JointToAClaimedBodyIsWithheld) {
    Joints j;
    IslandClaimSolver claims(*j.p.world, ClaimScope::Body);
    claims.claim(*j.body[0]);
    j.p.step(1);
    ASSERT_EQ(claims.withheldConstraints().size(), 1u);
    EXPECT_EQ(claims.withheldConstraints()[0], j.ab.get());
    EXPECT_FALSE(j.user.saw(*j.ab));
    EXPECT_TRUE(j.user.saw(*j.cd));
    // Body scope: the joint's other body stays Bullet's (and no longer feels the joint).
    EXPECT_TRUE(claimed(claims, *j.body[0]));
    EXPECT_FALSE(claimed(claims, *j.body[1]));
    EXPECT_TRUE(j.user.saw(*j.body[1]));
    EXPECT_TRUE(claims.withholds(*j.body[0]));
    EXPECT_FALSE(claims.withholds(*j.body[1]));
}

TEST(IslandClaim, IslandScopeClaimsTheJointsOtherBody) {
    Joints j;
    IslandClaimSolver claims(*j.p.world, ClaimScope::Island);
    claims.claim(*j.body[0]);
    j.p.step(1);
    ASSERT_EQ(claims.withheldConstraints().size(), 1u);
    EXPECT_EQ(claims.withheldConstraints()[0], j.ab.get());
    // calculateSimulationIslands unites a joint's two bodies: both are claimed.
    EXPECT_TRUE(claimed(claims, *j.body[0]));
    EXPECT_TRUE(claimed(claims, *j.body[1]));
    EXPECT_FALSE(claimed(claims, *j.body[2]));
    EXPECT_FALSE(claimed(claims, *j.body[3]));
    EXPECT_FALSE(j.user.saw(*j.body[1]));
    EXPECT_TRUE(j.user.saw(*j.cd));
}

}  // namespace

// A caller that cannot solve joints leaves jointed islands to Bullet: claiming a body of a
// jointed pair withholds nothing, and the user's solver still sees the joint and both
// bodies; a free body flagged at the same time is claimed as usual.
TEST(IslandClaim, LeaveJointedLeavesAJointsIslandToBullet) {
    for (const ClaimScope scope : {ClaimScope::Island, ClaimScope::Body}) {
        Joints j;
        btRigidBody& free = j.p.sphere(0.3, 1.0, btVector3(20, 5, 0));
        IslandClaimSolver claims(*j.p.world, scope);
        claims.setLeaveJointed(true);
        claims.claim(*j.body[0]);
        claims.claim(free);
        j.p.step(1);
        EXPECT_TRUE(claims.withheldConstraints().empty());
        EXPECT_TRUE(j.user.saw(*j.ab));
        EXPECT_FALSE(claimed(claims, *j.body[0]));
        EXPECT_FALSE(claimed(claims, *j.body[1]));
        EXPECT_TRUE(j.user.saw(*j.body[0]));
        EXPECT_TRUE(claimed(claims, free));
    }
}
