// The Bullet plugin: two-way coupling with rigid bodies, stepping inside stepSimulation,
// lifetimes.
#include "tearables/bullet_core.hpp"

#include "bullet_fixture.hpp"

#include <btBulletDynamicsCommon.h>
#include <gtest/gtest.h>

#include <cmath>
#include <memory>

namespace {

using tearables::BulletWorld;
using tearables::StringDesc;
using tearables::StringId;
using tearables::Vec3;

constexpr double kG = 9.81;
constexpr double kPi = 3.14159265358979323846;

using tearables::testing::Physics;

StringDesc rope(const Vec3& from, const Vec3& to, int segments) { return tearables::testing::plainRope(from, to, segments); }

double ropeWeight(const StringDesc& d, double length) { return d.density * kPi * d.radius * d.radius * length * kG; }

}  // namespace

// A 10 kg board hanging level from two ropes tied to it: it comes to rest, each rope
// carries half its weight within 5%, and it drifts less than 1 mm over 10 s.
TEST(BulletPlugin, BoardHangsLevelFromTwoRopes) {
    Physics phys;
    btRigidBody& board = phys.box(btVector3(0.5f, 0.02f, 0.1f), 10.0, btVector3(0, 1.0f, 0));
    BulletWorld ropes(*phys.world);
    const StringDesc left = rope({-0.4, 2.0, 0}, {-0.4, 1.02, 0}, 40);
    const StringDesc right = rope({0.4, 2.0, 0}, {0.4, 1.02, 0}, 40);
    const StringId a = ropes.addString(left);
    const StringId b = ropes.addString(right);
    ropes.attach(a, 0, btVector3(-0.4f, 2.0f, 0));
    ropes.attach(b, 0, btVector3(0.4f, 2.0f, 0));
    ropes.attach(a, -1, board, btVector3(-0.4f, 0.02f, 0));
    ropes.attach(b, -1, board, btVector3(0.4f, 0.02f, 0));
    phys.step(200);  // settle for 2 s
    const btVector3 start = board.getCenterOfMassPosition();
    double max_drift = 0.0;
    for (int i = 0; i < 1000; ++i) {
        phys.step(1);
        max_drift = std::max(max_drift, static_cast<double>((board.getCenterOfMassPosition() - start).length()));
    }
    EXPECT_LT(max_drift, 1e-3);
    const double half = 0.5 * 10.0 * kG;
    const auto& ta = *ropes.core().view(a).tension;
    const auto& tb = *ropes.core().view(b).tension;
    // The segment at the board carries half the board; the top one adds the rope's weight.
    EXPECT_NEAR(ta.back(), half, 0.05 * half);
    EXPECT_NEAR(tb.back(), half, 0.05 * half);
    EXPECT_NEAR(ta.front(), half + ropeWeight(left, 0.98), 0.05 * half);
    // Level and at rest.
    const btVector3 up = board.getWorldTransform().getBasis() * btVector3(0, 1, 0);
    EXPECT_GT(up.y(), 0.9999f);
    EXPECT_LT(board.getLinearVelocity().length(), 1e-3f);
    EXPECT_TRUE(ropes.lastError().empty()) << ropes.lastError();
}

// A rope holding a 100 kg body does not explode or stretch past 1% (Bullet's own anchored
// soft bodies do), at Bullet's default 60 Hz.
TEST(BulletPlugin, RopeHolds100KgWithoutStretching) {
    Physics phys;
    btRigidBody& weight = phys.box(btVector3(0.2f, 0.2f, 0.2f), 100.0, btVector3(0, 0.8f, 0));
    BulletWorld ropes(*phys.world);
    StringDesc d = rope({0, 2, 0}, {0, 1.0, 0}, 50);
    d.radius = 0.006;  // a 12 mm nylon rope: 981 N is 9 MPa, well below yield
    const StringId id = ropes.addString(d);
    ropes.attach(id, 0, btVector3(0, 2, 0));
    ropes.attach(id, -1, weight, btVector3(0, 0.2f, 0));
    // Give it a kick sideways too: it swings, and still must not stretch.
    weight.setLinearVelocity(btVector3(1.0f, 0, 0));
    double worst = 0.0;
    for (int i = 0; i < 600; ++i) {
        phys.step(1, 1.0 / 60.0);
        const auto v = ropes.core().view(id);
        double len = 0.0;
        for (std::size_t j = 0; j < v.segmentCount(); ++j) len += ((*v.positions)[j + 1] - (*v.positions)[j]).norm();
        worst = std::max(worst, len - 1.0);
        for (const Vec3& p : *v.positions) ASSERT_TRUE(p.allFinite());
    }
    EXPECT_LT(worst, 0.01);
    // At the bottom of its swing the tension exceeds the weight; at rest it equals it.
    const double rope_top = ropes.core().view(id).tension->front();
    EXPECT_GT(rope_top, 0.9 * 100.0 * kG);
    EXPECT_LT(weight.getCenterOfMassPosition().y(), 0.81f);
}

// A pendulum whose bob is a Bullet sphere: tension at the bottom of the swing is
// m g (3 - 2 cos 60deg) within 5%.
TEST(BulletPlugin, PendulumWithRigidBob) {
    Physics phys;
    const double a = kPi / 3.0;
    const double L = 1.0;
    const btVector3 bob_at(static_cast<btScalar>(L * std::sin(a)), static_cast<btScalar>(2.0 - L * std::cos(a)), 0);
    btRigidBody& bob = phys.sphere(0.02, 1.0, bob_at);
    BulletWorld ropes(*phys.world);
    StringDesc d = rope({0, 2, 0}, {bob_at.x(), bob_at.y(), 0}, 20);
    d.radius = 0.0005;
    const StringId id = ropes.addString(d);
    ropes.attach(id, 0, btVector3(0, 2, 0));
    ropes.attach(id, -1, bob, btVector3(0, 0, 0));
    double max_tension = 0.0;
    for (int i = 0; i < 100; ++i) {
        phys.step(1, 0.005);
        max_tension = std::max(max_tension, ropes.core().view(id).tension->back());
    }
    EXPECT_NEAR(max_tension, 1.0 * kG * (3.0 - 2.0 * std::cos(a)), 0.05 * 2.0 * kG);
}

// The body pulls the rope: a crate dropped on a slack rope is caught at the rope's length,
// and the rope's tension spikes at the catch.
TEST(BulletPlugin, SlackRopeCatchesAFallingCrate) {
    Physics phys;
    btRigidBody& crate = phys.box(btVector3(0.1f, 0.1f, 0.1f), 5.0, btVector3(0, 1.9f, 0));
    BulletWorld ropes(*phys.world);
    // 1 m of rope, laid out folded so that it is slack: the crate falls ~1 m before the catch.
    std::vector<Vec3> pts;
    for (int i = 0; i <= 20; ++i) pts.emplace_back(0.025 * (i % 2), 2.0, 0.05 * i);
    StringDesc d = rope({0, 0, 0}, {1, 0, 0}, 1);
    d.points = pts;
    d.radius = 0.006;
    const StringId id = ropes.addString(d);
    ropes.attach(id, 0, btVector3(0, 2.0f, 0));
    ropes.attach(id, -1, crate, btVector3(0, 0.1f, 0));
    double peak = 0.0;
    double lowest = 10.0;
    for (int i = 0; i < 300; ++i) {
        phys.step(1);
        peak = std::max(peak, ropes.core().view(id).tension->front());
        lowest = std::min(lowest, static_cast<double>(crate.getCenterOfMassPosition().y()));
    }
    const double rest_length = ropes.core().view(id).rest_length->size() * std::hypot(0.025, 0.05);
    // Caught: never past the rope's length plus its elastic stretch under the impact
    // (k = E A / L = 3.1e5 N/m; 5 kg at 4.4 m/s: v sqrt(m/k) = 1.8 cm, under 2%).
    EXPECT_GT(lowest, 2.0 - rest_length * 1.02 - 0.1);
    EXPECT_GT(peak, 3.0 * 5.0 * kG);                    // the catch is an impact
    EXPECT_LT(crate.getLinearVelocity().length(), 1.0f);
}

// Removing a body from the Bullet world while a rope holds it drops the attachment with
// an event; the rope goes on.
TEST(BulletPlugin, BodyRemovedWhileAttachedDropsTheAttachment) {
    Physics phys;
    btRigidBody& crate = phys.box(btVector3(0.1f, 0.1f, 0.1f), 2.0, btVector3(0, 0.9f, 0));
    BulletWorld ropes(*phys.world);
    const StringId id = ropes.addString(rope({0, 2, 0}, {0, 1, 0}, 10));
    ropes.attach(id, 0, btVector3(0, 2, 0));
    ropes.attach(id, -1, crate, btVector3(0, 0.1f, 0));
    phys.step(10);
    phys.world->removeRigidBody(&crate);
    ropes.clearEvents();
    phys.step(50);
    ASSERT_FALSE(ropes.events().empty());
    EXPECT_EQ(ropes.events().front().type, tearables::EventType::Release);
    EXPECT_EQ(ropes.events().front().cause, tearables::EventCause::BodyRemoved);
    EXPECT_FALSE(ropes.core().isAttached(id, -1));
    for (const Vec3& p : *ropes.core().view(id).positions) EXPECT_TRUE(p.allFinite());
    phys.world->addRigidBody(&crate);  // so that the fixture removes it cleanly
}

// Destroying the Bullet world first is safe; so is removing the plugin mid-run.
TEST(BulletPlugin, LifetimesInEitherOrder) {
    {
        Physics phys;
        auto ropes = std::make_unique<BulletWorld>(*phys.world);
        const StringId id = ropes->addString(rope({0, 2, 0}, {0, 1, 0}, 10));
        ropes->attach(id, 0, btVector3(0, 2, 0));
        phys.step(5);
        for (auto& b : phys.bodies) phys.world->removeRigidBody(b.get());
        phys.bodies.clear();
        phys.world.reset();  // Bullet world gone first
        EXPECT_FALSE(ropes->attachedToBullet());
        ropes.reset();       // must not touch the dead world
    }
    {
        Physics phys;
        btRigidBody& crate = phys.box(btVector3(0.1f, 0.1f, 0.1f), 1.0, btVector3(0, 0.9f, 0));
        const int objects = phys.world->getNumCollisionObjects();
        auto ropes = std::make_unique<BulletWorld>(*phys.world);
        const StringId id = ropes->addString(rope({0, 2, 0}, {0, 1, 0}, 10));
        ropes->attach(id, 0, btVector3(0, 2, 0));
        ropes->attach(id, -1, crate, btVector3(0, 0.1f, 0));
        phys.step(5);
        EXPECT_TRUE(ropes->attachedToBullet());
        ropes.reset();  // plugin removed (its sentinel and the rope's ray object); the crate now falls freely
        EXPECT_EQ(phys.world->getNumCollisionObjects(), objects);
        const float y = crate.getCenterOfMassPosition().y();
        phys.step(20);
        EXPECT_LT(crate.getCenterOfMassPosition().y(), y - 0.1f);
    }
}

// Bad attachments are refused by name and create nothing.
TEST(BulletPlugin, BadAttachmentsAreRefused) {
    Physics phys;
    btRigidBody& crate = phys.box(btVector3(0.1f, 0.1f, 0.1f), 1.0, btVector3(0, 0.9f, 0));
    BulletWorld ropes(*phys.world);
    const StringId id = ropes.addString(rope({0, 2, 0}, {0, 1, 0}, 10));
    EXPECT_THROW(ropes.attach(id, 11, crate, btVector3(0, 0, 0)), tearables::InvalidInput);
    EXPECT_THROW(ropes.attach(id, -12, btVector3(0, 0, 0)), tearables::InvalidInput);
    btBoxShape shape(btVector3(1, 1, 1));
    btRigidBody outside(btRigidBody::btRigidBodyConstructionInfo(1.0f, nullptr, &shape));
    EXPECT_THROW(ropes.attach(id, 0, outside, btVector3(0, 0, 0)), tearables::InvalidInput);
    EXPECT_FALSE(ropes.core().isAttached(id, 0));
}
