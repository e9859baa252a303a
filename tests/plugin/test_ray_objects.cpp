// Ropes in Bullet's own ray tests (BulletWorld::setRopesRayTestable, plugin/bullet_rays.cpp):
// world.rayTest meets a rope where its capsules are (the core's tearables::rayTest is the
// geometric reference), names the rope and segment through ropeHit, leaves a cut's gap
// open, reports the closest of a crate and a rope, and the rope's object never makes a
// Bullet contact. Removing a rope or turning the option off takes the objects out.
#include "tearables/bullet_core.hpp"
#include "tearables/queries.hpp"

#include "bullet_fixture.hpp"

#include <btBulletDynamicsCommon.h>
#include <gtest/gtest.h>

#include <cmath>
#include <optional>

namespace {

using tearables::BulletWorld;
using tearables::RopeHit;
using tearables::StringDesc;
using tearables::StringId;
using tearables::Vec3;
using tearables::testing::Physics;

constexpr double kRadius = 0.01;  // m: the ropes' radius here
constexpr int kSegments = 20;     // 5 cm each over the 1 m rope

/// A 1 m rope hanging straight down from (0, 2, 0), pinned at the top, 1 cm thick.
StringId hangingRope(BulletWorld& ropes, double x = 0.0) {
    StringDesc d = tearables::testing::plainRope({x, 2, 0}, {x, 1, 0}, kSegments);
    d.radius = kRadius;
    const StringId id = ropes.addString(d);
    ropes.attach(id, 0, btVector3(static_cast<btScalar>(x), 2, 0));
    return id;
}

/// Bullet's closest-hit callback, keeping what ClosestRayResultCallback drops: the compound
/// child that was hit (LocalShapeInfo::m_triangleIndex, btCollisionWorld::rayTestSingleInternal).
struct ClosestWithChild : btCollisionWorld::ClosestRayResultCallback {
    ClosestWithChild(const btVector3& from, const btVector3& to) : ClosestRayResultCallback(from, to) {}
    int child = -1;
    btScalar addSingleResult(btCollisionWorld::LocalRayResult& r, bool normal_in_world) override {
        child = r.m_localShapeInfo ? r.m_localShapeInfo->m_triangleIndex : -1;
        return ClosestRayResultCallback::addSingleResult(r, normal_in_world);
    }
};

struct Shot {
    const btCollisionObject* object = nullptr;
    int child = -1;
    btVector3 point{0, 0, 0};
};

/// Bullet's world.rayTest from `from` to `to`: the closest object hit, if any.
std::optional<Shot> shoot(btDiscreteDynamicsWorld& world, const Vec3& from, const Vec3& to) {
    ClosestWithChild cb(tearables::toBullet(from), tearables::toBullet(to));
    world.rayTest(cb.m_rayFromWorld, cb.m_rayToWorld, cb);
    if (!cb.hasHit()) return std::nullopt;
    return Shot{cb.m_collisionObject, cb.child, cb.m_hitPointWorld};
}

/// A horizontal ray along x at height y (and depth z) across the rope at x = 0.
std::pair<Vec3, Vec3> across(double y, double z = 0.0) { return {Vec3(-1, y, z), Vec3(1, y, z)}; }

bool sameHit(const std::optional<RopeHit>& hit, StringId id, int segment) {
    return hit && hit->string == id && hit->segment == segment;
}

// A ray across the hanging rope hits its object where the core's exact ray-capsule test
// hits it, and the hit names the rope and the segment, from the child index and from the
// point alike. The rope's segments answer rays exactly (plugin/bullet_rays.cpp), so the
// points agree to the rounding of single-precision coordinates near 1 m (~1e-7 m): 1e-5 m
// (a thousandth of the radius) is asked for, where Bullet's iterative cast against a
// btCapsuleShape is off by up to half a radius.
constexpr double kPointTolerance = 1e-5;  // m

TEST(RopeRays, ARayAcrossAHangingRopeHitsItAtTheRightPoint) {
    Physics p;
    BulletWorld ropes(*p.world);
    const StringId rope = hangingRope(ropes);
    int mine = 0;
    ropes.setUserPointer(rope, &mine);
    p.step(10);
    ASSERT_TRUE(ropes.lastError().empty()) << ropes.lastError();
    const btCollisionObject* object = ropes.rayObject(rope);
    ASSERT_NE(object, nullptr);
    EXPECT_EQ(object->getUserPointer(), &mine);  // the user's pointer for the rope
    EXPECT_EQ(object->getUserIndex(), static_cast<int>(rope.index));
    EXPECT_EQ(object->getUserIndex2(), static_cast<int>(rope.generation));

    for (const double y : {1.93, 1.52, 1.31, 1.07}) {
        // Off the axis by 0.4 r in z, so that the ray meets the round side obliquely.
        const auto [from, to] = across(y, 0.4 * kRadius);
        const auto expected = tearables::rayTest(ropes.core(), from, to);
        ASSERT_TRUE(expected) << y;
        const auto shot = shoot(*p.world, from, to);
        ASSERT_TRUE(shot) << y;
        EXPECT_EQ(shot->object, object) << y;
        EXPECT_LT((tearables::toCore(shot->point) - expected->point).norm(), kPointTolerance) << y;
        EXPECT_TRUE(sameHit(ropes.ropeHit(shot->object, shot->child), rope, expected->segment)) << y;
        EXPECT_TRUE(sameHit(ropes.ropeHit(shot->object, shot->point), rope, expected->segment)) << y;
    }
}

// Stepped as games step Bullet (a 1/60 s frame of four 1/240 s steps), a swinging rope's
// object is where the rope is at the end of each frame: a ray through a particle meets it
// where the core's exact test does, to the same 1e-5 m.
TEST(RopeRays, TheObjectFollowsTheRopeAtTheEndOfEachFrame) {
    Physics p;
    BulletWorld ropes(*p.world);
    StringDesc d = tearables::testing::plainRope({0, 2, 0}, {1, 2, 0}, kSegments);  // released level: it swings
    d.radius = kRadius;
    const StringId rope = ropes.addString(d);
    ropes.attach(rope, 0, btVector3(0, 2, 0));
    for (int frame = 0; frame < 20; ++frame) {
        p.world->stepSimulation(1.0f / 60.0f, 10, 1.0f / 240.0f);
        ASSERT_TRUE(ropes.lastError().empty()) << ropes.lastError();
        const Vec3 at = (*ropes.core().view(rope).positions)[kSegments / 2];
        const Vec3 from = at - Vec3(0, 0, 1), to = at + Vec3(0, 0, 1);
        const auto expected = tearables::rayTest(ropes.core(), from, to);
        ASSERT_TRUE(expected) << frame;
        const auto shot = shoot(*p.world, from, to);
        ASSERT_TRUE(shot) << frame;
        EXPECT_LT((tearables::toCore(shot->point) - expected->point).norm(), kPointTolerance) << frame;
    }
}

// A ray that passes 1.5 radii from the rope's axis misses it (and so does the core's).
TEST(RopeRays, ARayBesideTheRopeMisses) {
    Physics p;
    BulletWorld ropes(*p.world);
    const StringId rope = hangingRope(ropes);
    p.step(10);
    for (const double y : {1.93, 1.52, 1.07}) {
        const auto [from, to] = across(y, 1.5 * kRadius);
        EXPECT_FALSE(tearables::rayTest(ropes.core(), from, to)) << y;
        EXPECT_FALSE(shoot(*p.world, from, to)) << y;
        const auto [from2, to2] = across(y, 0.5 * kRadius);  // the same height, through it
        EXPECT_TRUE(shoot(*p.world, from2, to2)) << y;
    }
    EXPECT_NE(ropes.rayObject(rope), nullptr);
}

/// The middle of segment j of `rope` now.
Vec3 middle(const BulletWorld& ropes, StringId rope, int j) {
    const auto& x = *ropes.core().view(rope).positions;
    return 0.5 * (x[j] + x[j + 1]);
}

/// A ray along x through `at` hits `rope` at `segment`.
void expectHit(btDiscreteDynamicsWorld& world, const BulletWorld& ropes, StringId rope, const Vec3& at, int segment) {
    const auto shot = shoot(world, at - Vec3(1, 0, 0), at + Vec3(1, 0, 0));
    ASSERT_TRUE(shot) << segment;
    EXPECT_TRUE(sameHit(ropes.ropeHit(shot->object, shot->child), rope, segment)) << segment;
}

// A cut opens a gap at once: a ray through the cut segment's middle (2.5 cm from its ends,
// past the neighbours' 1 cm caps) misses, rays through each piece hit it; after steps in
// which the lower piece falls away, the same holds at its new place.
TEST(RopeRays, ACutLeavesAGapAndEachPieceIsHit) {
    Physics p;
    BulletWorld ropes(*p.world);
    const StringId rope = hangingRope(ropes);
    p.step(10);
    ASSERT_TRUE(ropes.cut(rope, 10));
    const Vec3 gap = middle(ropes, rope, 10);
    EXPECT_FALSE(shoot(*p.world, gap - Vec3(1, 0, 0), gap + Vec3(1, 0, 0)));
    expectHit(*p.world, ropes, rope, middle(ropes, rope, 5), 5);    // the upper piece
    expectHit(*p.world, ropes, rope, middle(ropes, rope, 15), 15);  // the lower piece
    p.step(20);  // 0.2 s: the lower piece has fallen ~0.2 m
    ASSERT_TRUE(ropes.lastError().empty()) << ropes.lastError();
    ASSERT_LT(middle(ropes, rope, 15).y(), 1.25 - 0.1);
    expectHit(*p.world, ropes, rope, middle(ropes, rope, 5), 5);
    expectHit(*p.world, ropes, rope, middle(ropes, rope, 15), 15);
    expectHit(*p.world, ropes, rope, middle(ropes, rope, 11), 11);
    expectHit(*p.world, ropes, rope, middle(ropes, rope, 9), 9);
    // Where the lower piece's top was, there is nothing now.
    EXPECT_FALSE(shoot(*p.world, gap - Vec3(1, 0, 0), gap + Vec3(1, 0, 0)));
}

// A tear inside a step (a crate heavier than the rope's rupture load): once the event is
// reported, the torn segment is a gap to rays and both pieces are hit.
TEST(RopeRays, ATearLeavesAGapAndEachPieceIsHit) {
    Physics p;
    BulletWorld ropes(*p.world);
    StringDesc d = StringDesc::straight({0, 2, 0}, {0, 1, 0}, 10);
    d.material.variation = 0.0;
    d.radius = 0.002;  // nylon's rupture load over pi r^2: ~1 kN
    const StringId rope = ropes.addString(d);
    ropes.attach(rope, 0, btVector3(0, 2, 0));
    btRigidBody& crate = p.box(btVector3(0.1f, 0.1f, 0.1f), 150.0, btVector3(0, 0.9f, 0));  // 1471 N
    ropes.attach(rope, -1, crate, btVector3(0, 0.1f, 0));
    int torn = -1;
    for (int i = 0; i < 120 && torn < 0; ++i) {
        p.step(1, 1.0 / 240.0);
        for (const auto& e : ropes.events())
            if (e.type == tearables::EventType::Tear) torn = e.segment;
    }
    ASSERT_GE(torn, 0);
    p.step(2, 1.0 / 240.0);  // the ends part
    const auto& x = *ropes.core().view(rope).positions;
    ASSERT_GT((x[torn + 1] - x[torn]).norm(), 4.0 * d.radius);  // the gap is wider than the two caps
    const Vec3 gap = middle(ropes, rope, torn);
    EXPECT_FALSE(shoot(*p.world, gap - Vec3(1, 0, 0), gap + Vec3(1, 0, 0)));
    // Each piece through a segment away from the tear (in a piece of the hanging rope).
    const int above = torn > 0 ? torn - 1 : -1, below = torn + 1 < 10 ? torn + 1 : -1;
    if (above >= 0) expectHit(*p.world, ropes, rope, middle(ropes, rope, above), above);
    if (below >= 0) {
        // The lower piece hangs on the crate; a ray along z avoids the crate's box.
        const Vec3 at = middle(ropes, rope, below);
        const auto shot = shoot(*p.world, at - Vec3(0, 0, 1), at + Vec3(0, 0, 1));
        ASSERT_TRUE(shot);
        EXPECT_TRUE(sameHit(ropes.ropeHit(shot->object, shot->child), rope, below));
    }
}

// A crate in front of the rope is reported, not the rope behind it (the closest hit); a
// ray from the other side reports the rope; a ray that sees all hits sees both.
TEST(RopeRays, ACrateBeforeTheRopeIsTheClosestHit) {
    Physics p;
    BulletWorld ropes(*p.world);
    const StringId rope = hangingRope(ropes);
    btRigidBody& crate = p.box(btVector3(0.1f, 0.1f, 0.1f), 0.0, btVector3(-0.5f, 1.5f, 0));
    p.step(5);
    const auto [from, to] = across(1.525);  // through segment 9 alone (1.50-1.55 m)
    const auto shot = shoot(*p.world, from, to);
    ASSERT_TRUE(shot);
    EXPECT_EQ(shot->object, &crate);
    EXPECT_NEAR(shot->point.x(), -0.6, 1e-4);  // Bullet's own cast at the crate's box
    EXPECT_FALSE(ropes.ropeHit(shot->object, shot->child));  // not a rope
    const auto back = shoot(*p.world, to, from);
    ASSERT_TRUE(back);
    EXPECT_EQ(back->object, ropes.rayObject(rope));
    EXPECT_NEAR(back->point.x(), kRadius, kPointTolerance);
    btCollisionWorld::AllHitsRayResultCallback all(tearables::toBullet(from), tearables::toBullet(to));
    p.world->rayTest(all.m_rayFromWorld, all.m_rayToWorld, all);
    ASSERT_EQ(all.m_collisionObjects.size(), 2);  // one hit each: the crate, the rope's segment 9
    EXPECT_TRUE((all.m_collisionObjects[0] == &crate) != (all.m_collisionObjects[1] == &crate));
    EXPECT_TRUE(all.m_collisionObjects[0] == ropes.rayObject(rope) || all.m_collisionObjects[1] == ropes.rayObject(rope));
}

/// True when some manifold of the dispatcher has `object` as a body.
bool inAManifold(btDispatcher& dispatcher, const btCollisionObject* object) {
    for (int m = 0; m < dispatcher.getNumManifolds(); ++m) {
        const btPersistentManifold* manifold = dispatcher.getManifoldByIndexInternal(m);
        if (manifold->getBody0() == object || manifold->getBody1() == object) return true;
    }
    return false;
}

/// True when the broadphase holds a pair of `a` and `b`.
bool paired(btDiscreteDynamicsWorld& world, const btCollisionObject* a, const btCollisionObject* b) {
    btOverlappingPairCache* pairs = world.getPairCache();
    for (int i = 0; i < pairs->getNumOverlappingPairs(); ++i) {
        const btBroadphasePair& pair = pairs->getOverlappingPairArray()[i];
        const auto* o0 = static_cast<const btCollisionObject*>(pair.m_pProxy0->m_clientObject);
        const auto* o1 = static_cast<const btCollisionObject*>(pair.m_pProxy1->m_clientObject);
        if ((o0 == a && o1 == b) || (o0 == b && o1 == a)) return true;
    }
    return false;
}

/// True when the two objects' broadphase boxes overlap.
bool boxesOverlap(const btCollisionObject* a, const btCollisionObject* b) {
    const btBroadphaseProxy *p = a->getBroadphaseHandle(), *q = b->getBroadphaseHandle();
    return p && q && TestAabbAgainstAabb2(p->m_aabbMin, p->m_aabbMax, q->m_aabbMin, q->m_aabbMax);
}

/// Bullet's pair rule, as a user's own filter would have it (it lets rope objects pair).
struct UsersFilter : btOverlapFilterCallback {
    bool needBroadphaseCollision(btBroadphaseProxy* a, btBroadphaseProxy* b) const override {
        return (a->m_collisionFilterGroup & b->m_collisionFilterMask) && (b->m_collisionFilterGroup & a->m_collisionFilterMask);
    }
};

// A crate falling straight through the rope (tearables' own rigid contacts off, so that
// nothing stops it): their broadphase boxes overlap, but the plugin's pair filter keeps
// the pair out of Bullet's pair cache, and the crate falls freely, v = g t. With a filter
// of the user's installed first (the plugin then adds none) the pair is made, and Bullet
// still makes no manifold for it (checkCollideWithOverride). A crate resting on a ground
// that the lying rope's object overlaps has manifolds with the ground only, and sleeps.
TEST(RopeRays, TheRopesObjectMakesNoBulletContact) {
    for (const bool users_filter : {false, true}) {
        Physics p;
        UsersFilter filter;
        if (users_filter) p.world->getPairCache()->setOverlapFilterCallback(&filter);
        tearables::WorldSettings settings;
        settings.rigid_contacts = false;
        BulletWorld ropes(*p.world, settings);
        StringDesc d = tearables::testing::plainRope({-0.5, 1, 0}, {0.5, 1, 0}, kSegments);
        d.radius = kRadius;
        const StringId rope = ropes.addString(d);
        ropes.attach(rope, 0, btVector3(-0.5f, 1, 0));
        ropes.attach(rope, -1, btVector3(0.5f, 1, 0));
        btRigidBody& crate = p.box(btVector3(0.05f, 0.05f, 0.05f), 1.0, btVector3(0, 1.3f, 0));
        const btCollisionObject* object = ropes.rayObject(rope);
        bool ever_overlapped = false, ever_paired = false;
        const double dt = 0.01;
        for (int i = 0; i < 40; ++i) {  // 0.4 s: from 1.3 m down past the rope at 1 m
            p.step(1, dt);
            ever_overlapped |= boxesOverlap(object, &crate);
            ever_paired |= paired(*p.world, object, &crate);
            EXPECT_FALSE(inAManifold(p.dispatcher, object)) << i;
        }
        EXPECT_TRUE(ever_overlapped);  // the test went through the rope's box
        EXPECT_EQ(ever_paired, users_filter);
        // Bullet's integration: v_n = -g n dt exactly (no damping), in float.
        EXPECT_NEAR(crate.getLinearVelocity().y(), -9.81 * 40 * dt, 1e-4);
        EXPECT_LT(crate.getCenterOfMassPosition().y(), 0.6f);
    }
    {
        Physics p;
        BulletWorld ropes(*p.world);
        btRigidBody& ground = p.box(btVector3(1, 0.05f, 1), 0.0, btVector3(0, -0.05f, 0));
        StringDesc d = tearables::testing::plainRope({-0.5, kRadius, 0.3}, {0.5, kRadius, 0.3}, kSegments);
        d.radius = kRadius;
        const StringId rope = ropes.addString(d);
        btRigidBody& crate = p.box(btVector3(0.05f, 0.05f, 0.05f), 1.0, btVector3(0, 0.06f, 0.3f - 0.1f));
        const btCollisionObject* object = ropes.rayObject(rope);
        for (int i = 0; i < 300 && crate.isActive(); ++i) {
            p.step(1);
            EXPECT_FALSE(inAManifold(p.dispatcher, object)) << i;
        }
        EXPECT_TRUE(boxesOverlap(object, &ground));
        EXPECT_FALSE(crate.isActive());  // asleep: the rope's object joined no island
        EXPECT_TRUE(ropes.lastError().empty()) << ropes.lastError();
    }
}

/// Every body's transform and velocity, and every rope particle, after `steps` of a scene:
/// a crate on a rope pinned at both ends, crates falling side by side onto a rope lying on
/// the ground with a rope swinging down through them, a crate hanging from a rope.
std::vector<btScalar> runScene(bool ray_objects, int steps) {
    Physics p;
    BulletWorld ropes(*p.world);
    ropes.setRopesRayTestable(ray_objects);
    p.box(btVector3(2, 0.05f, 2), 0.0, btVector3(0, -0.05f, 0));
    StringDesc lying = tearables::testing::plainRope({-0.5, 0.012, 0.3}, {0.5, 0.012, 0.3}, kSegments);
    lying.radius = 0.01;
    ropes.addString(lying);
    // Crates falling onto the lying rope, side by side (not onto each other: see the test).
    for (int i = 0; i < 4; ++i)
        p.box(btVector3(0.05f, 0.05f, 0.05f), 1.0, btVector3(-0.3f + 0.2f * static_cast<btScalar>(i), 0.2f, 0.3f));
    const StringId span = ropes.addString(tearables::testing::plainRope({-0.5, 1, 0}, {0.5, 1, 0}, kSegments));
    ropes.attach(span, 0, btVector3(-0.5f, 1, 0));
    ropes.attach(span, -1, btVector3(0.5f, 1, 0));
    p.box(btVector3(0.05f, 0.05f, 0.05f), 1.0, btVector3(0, 1.2f, 0));
    // A rope swinging down from the horizontal through the pile's space: its object's box
    // sweeps over the crates.
    const StringId swinging = ropes.addString(tearables::testing::plainRope({-0.6, 0.7, 0.3}, {0.4, 0.7, 0.3}, kSegments));
    ropes.attach(swinging, 0, btVector3(-0.6f, 0.7f, 0.3f));
    const StringId hanging = ropes.addString(tearables::testing::plainRope({1, 2, 0}, {1, 1.2, 0}, kSegments));
    ropes.attach(hanging, 0, btVector3(1, 2, 0));
    btRigidBody& held = p.box(btVector3(0.05f, 0.05f, 0.05f), 2.0, btVector3(1, 1.15f, 0));
    ropes.attach(hanging, -1, held, btVector3(0, 0.05f, 0));
    p.step(steps);
    std::vector<btScalar> state;
    for (const auto& body : p.bodies) {
        const btTransform& xf = body->getWorldTransform();
        for (int r = 0; r < 3; ++r)
            for (int c = 0; c < 3; ++c) state.push_back(xf.getBasis()[r][c]);
        for (int k = 0; k < 3; ++k)
            state.insert(state.end(), {xf.getOrigin()[k], body->getLinearVelocity()[k], body->getAngularVelocity()[k]});
    }
    for (const StringId id : ropes.core().strings())
        for (const btVector3& x : ropes.positions(id)) state.insert(state.end(), {x.x(), x.y(), x.z()});
    return state;
}

// The ropes' objects change nothing in the simulation: no contact, no island, no pair of
// theirs in Bullet's pair cache, so bodies and ropes are bit for bit the same with them
// and without them, where the bodies touch only ropes and the ground. (Crates piled on
// each other are not: the order in which the broadphase finds their pairs depends on the
// rope objects' leaves in its tree, and with it the order of Bullet's solver; README.)
TEST(RopeRays, TheObjectsChangeNothingInTheSimulation) {
    const std::vector<btScalar> with = runScene(true, 150), without = runScene(false, 150);
    ASSERT_EQ(with.size(), without.size());
    for (std::size_t i = 0; i < with.size(); ++i) EXPECT_EQ(with[i], without[i]) << i;
}

// Removing a rope takes its object out of the world (rays miss); the next string in the
// slot gets an object of its own. Destroying the plugin removes the rest.
TEST(RopeRays, RemovingARopeRemovesItsObject) {
    Physics p;
    const int before = p.world->getNumCollisionObjects();
    auto ropes = std::make_unique<BulletWorld>(*p.world);
    const StringId rope = hangingRope(*ropes);
    const StringId other = hangingRope(*ropes, 0.5);
    p.step(5);
    EXPECT_EQ(p.world->getNumCollisionObjects(), before + 3);  // the sentinel and two ropes
    const auto [from, to] = across(1.525);
    ASSERT_TRUE(shoot(*p.world, from, to));
    ropes->removeString(rope);
    EXPECT_EQ(p.world->getNumCollisionObjects(), before + 2);
    const auto shot = shoot(*p.world, from, to);  // now the other rope, at x = 0.5
    ASSERT_TRUE(shot);
    EXPECT_TRUE(sameHit(ropes->ropeHit(shot->object, shot->child), other, 9));
    const StringId again = hangingRope(*ropes);
    EXPECT_EQ(again.index, rope.index);
    const auto shot2 = shoot(*p.world, from, to);
    ASSERT_TRUE(shot2);
    EXPECT_TRUE(sameHit(ropes->ropeHit(shot2->object, shot2->child), again, 9));
    EXPECT_EQ(shot2->object->getUserIndex2(), static_cast<int>(again.generation));
    ropes.reset();
    EXPECT_EQ(p.world->getNumCollisionObjects(), before);
    EXPECT_FALSE(shoot(*p.world, from, to));
}

// The option off: no object in the world, no hit; on again: the objects follow the ropes.
TEST(RopeRays, TheOptionOffMeansNoHits) {
    Physics p;
    const int before = p.world->getNumCollisionObjects();
    BulletWorld ropes(*p.world);
    EXPECT_TRUE(ropes.ropesRayTestable());
    const StringId rope = hangingRope(ropes);
    const auto [from, to] = across(1.525);
    p.step(5);
    ASSERT_TRUE(shoot(*p.world, from, to));
    ropes.setRopesRayTestable(false);
    EXPECT_FALSE(ropes.ropesRayTestable());
    EXPECT_EQ(p.world->getNumCollisionObjects(), before + 1);  // the sentinel
    EXPECT_EQ(ropes.rayObject(rope), nullptr);
    EXPECT_FALSE(shoot(*p.world, from, to));
    p.step(5);
    const StringId other = hangingRope(ropes, 0.5);
    EXPECT_FALSE(shoot(*p.world, from, to));
    ropes.setRopesRayTestable(true);
    const auto shot = shoot(*p.world, from, to);
    ASSERT_TRUE(shot);
    EXPECT_TRUE(sameHit(ropes.ropeHit(shot->object, shot->child), rope, 9));
    EXPECT_NE(ropes.rayObject(other), nullptr);
}

// Bullet's other queries see the rope through a prism circumscribing each capsule (its
// corners at r / cos(pi / 8), 8% past the radius): a ball swept across the rope stops
// where its surface meets the rope's, within that 8% of r; a ball overlapping the rope is
// reported by contactTest; one 2 r beside it is not.
TEST(RopeRays, SweepsAndContactTestsSeeTheRope) {
    Physics p;
    BulletWorld ropes(*p.world);
    const StringId rope = hangingRope(ropes);
    p.step(5);
    const btCollisionObject* object = ropes.rayObject(rope);
    const double ball = 0.05;  // m
    btSphereShape shape(static_cast<btScalar>(ball));
    const btTransform from(btQuaternion::getIdentity(), btVector3(-1, 1.525f, 0)), to(btQuaternion::getIdentity(), btVector3(1, 1.525f, 0));
    btCollisionWorld::ClosestConvexResultCallback sweep(from.getOrigin(), to.getOrigin());
    p.world->convexSweepTest(&shape, from, to, sweep);
    ASSERT_TRUE(sweep.hasHit());
    EXPECT_EQ(sweep.m_hitCollisionObject, object);
    const double centre = -1.0 + 2.0 * sweep.m_closestHitFraction;  // the ball's centre at the hit
    const double rope_x = middle(ropes, rope, 9).x();
    EXPECT_LE(centre, rope_x - (ball + kRadius) + 1e-4);
    EXPECT_GE(centre, rope_x - (ball + kRadius / std::cos(3.14159265358979 / 8)) - 1e-4);

    struct Touches : btCollisionWorld::ContactResultCallback {
        const btCollisionObject* rope = nullptr;
        bool found = false;
        btScalar addSingleResult(btManifoldPoint&, const btCollisionObjectWrapper* a, int, int, const btCollisionObjectWrapper* b,
                                 int, int) override {
            found |= a->getCollisionObject() == rope || b->getCollisionObject() == rope;
            return 0;
        }
    };
    btCollisionObject probe;
    probe.setCollisionShape(&shape);
    const Vec3 on = middle(ropes, rope, 9);
    probe.setWorldTransform(btTransform(btQuaternion::getIdentity(), tearables::toBullet(on + Vec3(ball, 0, 0))));
    Touches touching;
    touching.rope = object;
    p.world->contactTest(&probe, touching);
    EXPECT_TRUE(touching.found);
    probe.setWorldTransform(btTransform(btQuaternion::getIdentity(), tearables::toBullet(on + Vec3(ball + 2 * kRadius, 0, 0))));
    Touches apart;
    apart.rope = object;
    p.world->contactTest(&probe, apart);
    EXPECT_FALSE(apart.found);
}

// A ray's collision filter selects ropes by the string's group, as it does bodies.
TEST(RopeRays, ARaysFilterSelectsRopesByTheirGroup) {
    Physics p;
    BulletWorld ropes(*p.world);
    StringDesc d = tearables::testing::plainRope({0, 2, 0}, {0, 1, 0}, kSegments);
    d.radius = kRadius;
    const StringId rope = ropes.addString(d, 64, btBroadphaseProxy::AllFilter);
    p.step(2);
    const auto [from, to] = across(1.5);
    btCollisionWorld::ClosestRayResultCallback sees(tearables::toBullet(from), tearables::toBullet(to));
    p.world->rayTest(sees.m_rayFromWorld, sees.m_rayToWorld, sees);
    EXPECT_EQ(sees.m_collisionObject, ropes.rayObject(rope));
    btCollisionWorld::ClosestRayResultCallback blind(tearables::toBullet(from), tearables::toBullet(to));
    blind.m_collisionFilterMask = btBroadphaseProxy::AllFilter & ~64;
    p.world->rayTest(blind.m_rayFromWorld, blind.m_rayToWorld, blind);
    EXPECT_FALSE(blind.hasHit());
}

// ropeHit answers only for this plugin's rope objects and children that exist; a string
// removed through the core is no longer named; a bad point is refused.
TEST(RopeRays, RopeHitRefusesWhatIsNotItsRope) {
    Physics p;
    BulletWorld ropes(*p.world), others(*p.world);
    const StringId rope = hangingRope(ropes);
    const StringId theirs = hangingRope(others, 0.5);
    btRigidBody& crate = p.box(btVector3(0.1f, 0.1f, 0.1f), 0.0, btVector3(-0.5f, 1.5f, 0));
    p.step(2);
    const btCollisionObject* object = ropes.rayObject(rope);
    EXPECT_TRUE(sameHit(ropes.ropeHit(object, 3), rope, 3));
    EXPECT_FALSE(ropes.ropeHit(object, -1));
    EXPECT_FALSE(ropes.ropeHit(object, kSegments));
    EXPECT_FALSE(ropes.ropeHit(&crate, 0));
    EXPECT_FALSE(ropes.ropeHit(nullptr, 0));
    EXPECT_FALSE(ropes.ropeHit(others.rayObject(theirs), 0));  // another plugin's rope
    EXPECT_TRUE(sameHit(others.ropeHit(others.rayObject(theirs), 0), theirs, 0));
    try {
        ropes.ropeHit(object, btVector3(NAN, 0, 0));
        ADD_FAILURE() << "a NaN point was accepted";
    } catch (const tearables::InvalidInput& e) {
        EXPECT_EQ(e.field(), "point");
    }
    try {
        (void)ropes.rayObject(StringId{});
        ADD_FAILURE() << "an invalid id was accepted";
    } catch (const tearables::InvalidInput& e) {
        EXPECT_EQ(e.field(), "string");
    }
    ropes.core().cutSegment(rope, 3);  // through the core: the object follows at the next step
    EXPECT_FALSE(ropes.ropeHit(object, 3));
    ropes.core().removeString(rope);
    EXPECT_FALSE(ropes.ropeHit(object, 5));
    p.step(1);
    EXPECT_EQ(p.world->getNumCollisionObjects(), 2 + 1 + 1);  // two sentinels, their rope, the crate
}

}  // namespace
