// Issue 8, runtime faults: what a host can do to the strings while they run must never
// crash, never leave NaN anywhere but in the object that caused it (which is frozen with
// an event that says why), and never corrupt the rigid world the strings share.
#include "tearables/bullet_core.hpp"
#include "tearables/world.hpp"

#include "../plugin/bullet_fixture.hpp"

#include <btBulletDynamicsCommon.h>
#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <limits>
#include <numeric>

namespace {

using tearables::BulletWorld;
using tearables::EventCause;
using tearables::EventType;
using tearables::RigidId;
using tearables::RigidState;
using tearables::StringDesc;
using tearables::StringId;
using tearables::Vec3;
using tearables::World;
using tearables::testing::Physics;

StringDesc rope(const Vec3& from, const Vec3& to, int segments, bool tearable = true) {
    StringDesc d = StringDesc::straight(from, to, segments);
    d.material.variation = 0.0;
    d.tearable = tearable;
    return d;
}

bool allFinite(const World& world, StringId id) {
    const auto v = world.view(id);
    for (std::size_t p = 0; p < v.particleCount(); ++p)
        if (!(*v.positions)[p].allFinite() || !(*v.velocities)[p].allFinite()) return false;
    for (std::size_t j = 0; j < v.segmentCount(); ++j)
        if (!std::isfinite((*v.tension)[j]) || !std::isfinite((*v.twist)[j]) || !std::isfinite((*v.rest_length)[j]))
            return false;
    return true;
}

double totalMass(const World& world, StringId id) {
    const auto& m = *world.view(id).masses;
    return std::accumulate(m.begin(), m.end(), 0.0);
}

bool bodyFinite(const btRigidBody& b) {
    const btTransform& xf = b.getWorldTransform();
    auto ok = [](const btVector3& v) { return std::isfinite(v.x()) && std::isfinite(v.y()) && std::isfinite(v.z()); };
    return ok(xf.getOrigin()) && ok(xf.getBasis().getRow(0)) && ok(xf.getBasis().getRow(1)) &&
           ok(xf.getBasis().getRow(2)) && ok(b.getLinearVelocity()) && ok(b.getAngularVelocity());
}

template <class Events>
int countEvents(const Events& events, EventType type) {
    int n = 0;
    for (const auto& e : events) n += e.type == type;
    return n;
}

// A huge but finite force on a rope's free end: the rope either tears or stays finite;
// it never takes its neighbour down.
TEST(RuntimeFaults, HugeForceTearsOrFreezesOnlyItsString) {
    for (double magnitude : {1e6, 1e12, 1e30, 1e100}) {
        SCOPED_TRACE(magnitude);
        World world;
        const StringId wild = world.addString(rope({0, 1, 0}, {0, 0, 0}, 10));
        const StringId calm = world.addString(rope({1, 1, 0}, {1, 0, 0}, 10, false));
        world.attachToPoint(wild, 0, {0, 1, 0});
        world.attachToPoint(calm, 0, {1, 1, 0});
        const double calm_mass = totalMass(world, calm);
        for (int i = 0; i < 50; ++i) {
            world.applyForce(wild, -1, {-magnitude, -magnitude, 0});  // away from the calm rope
            world.step(0.01);
            ASSERT_TRUE(allFinite(world, wild) || world.view(wild).frozen);
        }
        EXPECT_TRUE(allFinite(world, wild));  // frozen strings are reset to their last finite state
        // No piece travels faster than the speed clamp (a force of 1e30 N would otherwise
        // fling a torn piece 1e26 m in a step, through every string in its way).
        const double reach = world.settings().max_speed * world.time() + 1.0;
        for (const Vec3& p : *world.view(wild).positions) EXPECT_LT(p.norm(), reach);
        EXPECT_TRUE(allFinite(world, calm));
        EXPECT_FALSE(world.view(calm).frozen);
        EXPECT_DOUBLE_EQ(totalMass(world, calm), calm_mass);
        // The calm rope hangs still at its length.
        const auto v = world.view(calm);
        EXPECT_NEAR(((*v.positions).back() - Vec3(1, 0, 0)).norm(), 0.0, 1e-2);
    }
}

// A rope glued to a dynamic body is driven non-finite by a user's force: it is frozen with
// an event saying why, and the body keeps a finite state (the strings' corrections of a
// frozen string never reach it).
TEST(RuntimeFaults, NonFiniteStringFrozenWithoutCorruptingItsBody) {
    World world;
    RigidState crate;
    crate.position = {0, -0.1, 0};
    crate.inverse_mass = 1.0;
    crate.inverse_inertia_local = tearables::Mat3::Identity() * 60.0;
    const RigidId body = world.addRigid(crate);
    const StringId wild = world.addString(rope({0, 1, 0}, {0, 0, 0}, 10));
    const StringId calm = world.addString(rope({1, 1, 0}, {1, 0, 0}, 10, false));
    world.attachToPoint(wild, 0, {0, 1, 0});
    world.attachToRigid(wild, -1, body, {0, 0.1, 0});
    world.attachToPoint(calm, 0, {1, 1, 0});
    for (int i = 0; i < 10; ++i) world.step(0.01);
    world.applyForce(wild, 5, {1e308, 1e308, -1e308});
    world.step(0.01);
    bool frozen_event = false;
    for (const auto& e : world.events())
        frozen_event = frozen_event || (e.type == EventType::Freeze && e.string == wild && e.cause == EventCause::NonFinite);
    EXPECT_TRUE(frozen_event);
    EXPECT_TRUE(world.view(wild).frozen);
    for (int i = 0; i < 50; ++i) world.step(0.01);
    const RigidState& b = world.rigid(body);
    EXPECT_TRUE(b.position.allFinite());
    EXPECT_TRUE(b.orientation.coeffs().allFinite());
    EXPECT_TRUE(b.linear_velocity.allFinite());
    EXPECT_TRUE(b.angular_velocity.allFinite());
    EXPECT_TRUE(b.impulse.allFinite());
    EXPECT_TRUE(allFinite(world, wild));
    EXPECT_TRUE(allFinite(world, calm));
    EXPECT_FALSE(world.view(calm).frozen);
}

// The same through Bullet: the crate the frozen rope held stays a finite Bullet body and
// other Bullet bodies are untouched.
TEST(RuntimeFaults, NonFiniteStringInBulletLeavesTheRigidWorldFinite) {
    Physics phys;
    btRigidBody& crate = phys.box(btVector3(0.1f, 0.1f, 0.1f), 2.0, btVector3(0, 0.9f, 0));
    btRigidBody& ball = phys.sphere(0.1, 1.0, btVector3(2, 0.5f, 0));
    phys.box(btVector3(5, 0.1f, 5), 0.0, btVector3(0, -0.1f, 0));  // ground
    BulletWorld ropes(*phys.world);
    const StringId id = ropes.addString(rope({0, 2, 0}, {0, 1, 0}, 10));
    ropes.attach(id, 0, btVector3(0, 2, 0));
    ropes.attach(id, -1, crate, btVector3(0, 0.1f, 0));
    phys.step(10);
    ropes.core().applyForce(id, 4, {0, 1e308, 1e308});
    phys.step(1);
    EXPECT_TRUE(ropes.core().view(id).frozen);
    EXPECT_EQ(countEvents(ropes.events(), EventType::Freeze), 1);
    phys.step(100);
    EXPECT_TRUE(ropes.lastError().empty()) << ropes.lastError();
    EXPECT_TRUE(bodyFinite(crate));
    EXPECT_TRUE(bodyFinite(ball));
    EXPECT_NEAR(ball.getCenterOfMassPosition().y(), 0.1f, 0.02f);  // the ball rests on the ground
}

// A huge impulse: a crate glued to a rope thrown at 1e4 m/s. The rope tears (or holds);
// everything stays finite.
TEST(RuntimeFaults, HugeImpulseOnAGluedBody) {
    Physics phys;
    btRigidBody& crate = phys.box(btVector3(0.1f, 0.1f, 0.1f), 2.0, btVector3(0, 0.9f, 0));
    BulletWorld ropes(*phys.world);
    const StringId id = ropes.addString(rope({0, 2, 0}, {0, 1, 0}, 20));
    ropes.attach(id, 0, btVector3(0, 2, 0));
    ropes.attach(id, -1, crate, btVector3(0, 0.1f, 0));
    phys.step(5);
    crate.setLinearVelocity(btVector3(1e4f, -1e4f, 3e3f));
    crate.setAngularVelocity(btVector3(0, 1e3f, 0));
    phys.step(100);
    EXPECT_TRUE(ropes.lastError().empty()) << ropes.lastError();
    EXPECT_TRUE(bodyFinite(crate));
    EXPECT_TRUE(allFinite(ropes.core(), id));
}

// Thousands of tears in one step: 3000 ropes pulled far past rupture at once each tear in
// the same step; the events are all there, mass is kept, everything stays finite.
TEST(RuntimeFaults, ThousandsOfTearsInOneStep) {
    World world;
    world.settings().string_collisions = false;  // 3000 ropes side by side: collisions are not the point
    constexpr int kRopes = 3000;
    std::vector<StringId> ids;
    double mass = 0.0;
    for (int i = 0; i < kRopes; ++i) {
        const double x = 0.01 * i;
        ids.push_back(world.addString(rope({x, 1, 0}, {x, 0.8, 0}, 4)));
        world.attachToPoint(ids.back(), 0, {x, 1, 0});
        mass += totalMass(world, ids.back());
    }
    for (StringId id : ids) world.applyForce(id, -1, {0, -1e5, 0});  // rupture is ~1 kN
    world.step(0.01);
    EXPECT_EQ(countEvents(world.events(), EventType::Tear), kRopes);
    double after = 0.0;
    for (StringId id : ids) {
        EXPECT_TRUE(allFinite(world, id));
        after += totalMass(world, id);
    }
    EXPECT_DOUBLE_EQ(after, mass);
    for (int i = 0; i < 5; ++i) world.step(0.01);
    for (StringId id : ids) ASSERT_TRUE(allFinite(world, id));
}

// A string torn into single particles goes on falling as loose particles: no segment left,
// nothing frozen, mass kept, collisions on.
TEST(RuntimeFaults, StringTornIntoSingleParticles) {
    World world;
    StringDesc d = rope({0, 1, 0}, {1, 1, 0}, 12);
    const StringId id = world.addString(d);
    const StringId other = world.addString(rope({0.5, 0.5, -0.5}, {0.5, 0.5, 0.5}, 10, false));
    world.attachToPoint(other, 0, {0.5, 0.5, -0.5});
    world.attachToPoint(other, -1, {0.5, 0.5, 0.5});
    const double mass = totalMass(world, id);
    const int particles = static_cast<int>(world.view(id).particleCount());
    int tears = 0;
    for (int step = 0; step < 200 && tears < particles - 1; ++step) {
        // Every particle pulled away from its neighbours, far past rupture.
        for (int p = 0; p < particles; ++p) world.applyForce(id, p, {(p % 2 ? 1.0 : -1.0) * 5e4, 0, (p % 3 - 1) * 5e4});
        world.step(0.001);
        tears += countEvents(world.events(), EventType::Tear);
        ASSERT_TRUE(allFinite(world, id)) << step;
    }
    const auto v = world.view(id);
    for (std::uint8_t b : *v.broken) EXPECT_EQ(b, 1);
    EXPECT_EQ(tears, particles - 1);
    for (int i = 0; i < 300; ++i) world.step(0.01);  // loose particles fall through the other rope's region
    EXPECT_FALSE(world.view(id).frozen);
    EXPECT_TRUE(allFinite(world, id));
    EXPECT_TRUE(allFinite(world, other));
    EXPECT_DOUBLE_EQ(totalMass(world, id), mass);
    for (const Vec3& p : *world.view(id).positions) EXPECT_LT(p.y(), 0.0);  // they fell
}

// A body removed from the Bullet world and deleted while ropes are glued to it and another
// rope touches it: forgetBody, or removal then a step, leaves no dangling pointer (ASan
// would see one), and the ropes go on.
TEST(RuntimeFaults, BodyRemovedAndDeletedWhileHeldAndTouched) {
    for (bool forget : {false, true}) {
        SCOPED_TRACE(forget ? "forgetBody" : "remove and step");
        Physics phys;
        BulletWorld ropes(*phys.world);
        auto shape = std::make_unique<btBoxShape>(btVector3(0.1f, 0.1f, 0.1f));
        btVector3 inertia;
        shape->calculateLocalInertia(2.0f, inertia);
        auto crate = std::make_unique<btRigidBody>(btRigidBody::btRigidBodyConstructionInfo(2.0f, nullptr, shape.get(), inertia));
        crate->setWorldTransform(btTransform(btQuaternion::getIdentity(), btVector3(0, 0.9f, 0)));
        phys.world->addRigidBody(crate.get());
        const StringId held = ropes.addString(rope({0, 2, 0}, {0, 1, 0}, 10));
        ropes.attach(held, 0, btVector3(0, 2, 0));
        ropes.attach(held, -1, *crate, btVector3(0, 0.1f, 0));
        const StringId under = ropes.addString(rope({-0.5, 0.75, 0}, {0.5, 0.75, 0}, 10, false));  // the crate rests on it
        ropes.attach(under, 0, btVector3(-0.5f, 0.75f, 0));
        ropes.attach(under, -1, btVector3(0.5f, 0.75f, 0));
        phys.step(20);
        phys.world->removeRigidBody(crate.get());
        if (forget) {
            ropes.forgetBody(*crate);
        } else {
            phys.step(1);
        }
        crate.reset();  // deleted
        shape.reset();
        ropes.clearEvents();
        phys.step(50);
        EXPECT_TRUE(ropes.lastError().empty()) << ropes.lastError();
        EXPECT_FALSE(ropes.core().isAttached(held, -1));
        EXPECT_TRUE(allFinite(ropes.core(), held));
        EXPECT_TRUE(allFinite(ropes.core(), under));
    }
}

// Either destruction order, with bodies glued and touching and events pending.
TEST(RuntimeFaults, WorldsDestroyedInEitherOrderWithBodiesHeld) {
    for (bool bullet_first : {true, false}) {
        SCOPED_TRACE(bullet_first ? "Bullet world first" : "tearables world first");
        auto phys = std::make_unique<Physics>();
        btRigidBody& crate = phys->box(btVector3(0.1f, 0.1f, 0.1f), 2.0, btVector3(0, 0.9f, 0));
        phys->box(btVector3(5, 0.1f, 5), 0.0, btVector3(0, 0.5f, 0));  // the rope's tail lies on it
        auto ropes = std::make_unique<BulletWorld>(*phys->world);
        const StringId id = ropes->addString(rope({0, 2, 0}, {1, 0.65, 0}, 20));
        ropes->attach(id, 0, btVector3(0, 2, 0));
        ropes->attach(id, 10, crate, btVector3(0, 0.1f, 0));
        phys->step(10);
        ropes->core().detach(id, 0);  // a pending event
        if (bullet_first) {
            phys.reset();  // removes its bodies, deletes the world and the bodies
            EXPECT_FALSE(ropes->attachedToBullet());
            EXPECT_TRUE(allFinite(ropes->core(), id));
            ropes.reset();
        } else {
            ropes.reset();
            phys->step(10);
            EXPECT_TRUE(bodyFinite(crate));
            phys.reset();
        }
    }
}

}  // namespace

namespace {

// A string driven non-finite while it touches another (string-string collision solves them
// together): only the one the force acted on is frozen; the one under it goes on finite.
TEST(RuntimeFaults, NonFiniteStringDoesNotPoisonAStringItTouches) {
    World world;
    const StringId calm = world.addString(rope({-0.5, 1, 0}, {0.5, 1, 0}, 20, false));
    world.attachToPoint(calm, 0, {-0.5, 1, 0});
    world.attachToPoint(calm, -1, {0.5, 1, 0});
    const StringId wild = world.addString(rope({0, 1.01, -0.5}, {0, 1.01, 0.5}, 20, false));  // lies across it
    for (int i = 0; i < 8; ++i) world.step(0.01);
    // Resting on it: the middles are about two radii (4 mm) apart.
    const double gap = ((*world.view(wild).positions)[10] - (*world.view(calm).positions)[10]).norm();
    ASSERT_LT(gap, 0.006);
    world.applyForce(wild, 10, {1e308, -1e308, 1e308});
    world.step(0.01);
    EXPECT_TRUE(world.view(wild).frozen);
    EXPECT_FALSE(world.view(calm).frozen);
    for (int i = 0; i < 50; ++i) world.step(0.01);
    EXPECT_TRUE(allFinite(world, calm));
    EXPECT_FALSE(world.view(calm).frozen);
}

// A non-finite gravity set on the Bullet world: the plugin's step refuses it (an error
// reported through lastError(), never thrown into Bullet) and changes nothing; with the
// gravity back, the ropes go on.
TEST(RuntimeFaults, NonFiniteBulletGravityIsRefusedByTheStep) {
    Physics phys;
    BulletWorld ropes(*phys.world);
    const StringId id = ropes.addString(rope({0, 2, 0}, {0, 1, 0}, 10));
    ropes.attach(id, 0, btVector3(0, 2, 0));
    phys.step(5);
    const std::vector<Vec3> before = *ropes.core().view(id).positions;
    phys.world->setGravity(btVector3(0, std::numeric_limits<float>::quiet_NaN(), 0));
    phys.step(1);
    EXPECT_NE(ropes.lastError().find("gravity"), std::string::npos) << ropes.lastError();
    EXPECT_EQ(*ropes.core().view(id).positions, before);
    phys.world->setGravity(btVector3(0, -9.81f, 0));
    phys.step(10);
    EXPECT_TRUE(allFinite(ropes.core(), id));
    EXPECT_FALSE(ropes.core().view(id).frozen);
}

}  // namespace
