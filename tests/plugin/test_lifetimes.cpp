// The lifetimes the README calls safe, one test each: destroying the plugin first;
// destroying the Bullet world first and stepping the plugin's core afterwards; removing a
// held body and deleting it after a step or after forgetBody(); deleting a body that a
// rope only touched once it has left the world. CTest also runs this file built with
// AddressSanitizer (tearables_lifetime_asan), where a read of freed Bullet memory fails.
#include "tearables/bullet_core.hpp"

#include "bullet_fixture.hpp"

#include <btBulletDynamicsCommon.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <memory>

namespace {

using tearables::BulletWorld;
using tearables::ClothDesc;
using tearables::ClothId;
using tearables::EventCause;
using tearables::EventType;
using tearables::PaperDesc;
using tearables::PaperId;
using tearables::StringDesc;
using tearables::StringId;
using tearables::Vec3;
using tearables::World;
using tearables::testing::Physics;

StringDesc rope(const Vec3& from, const Vec3& to, int segments) {
    StringDesc d = StringDesc::straight(from, to, segments);
    d.material.variation = 0.0;
    d.tearable = false;
    return d;
}

/// Removes `body` from the world and deletes it, as a user would.
void destroyBody(Physics& phys, btRigidBody& body) {
    if (phys.world) phys.world->removeRigidBody(&body);
    const auto it = std::find_if(phys.bodies.begin(), phys.bodies.end(), [&](const auto& b) { return b.get() == &body; });
    ASSERT_NE(it, phys.bodies.end());
    phys.bodies.erase(it);
}

/// Steps the core `n` times by h and counts the Release events of cause body_removed.
int stepCore(World& core, int n, double h = 0.01) {
    int released = 0;
    for (int i = 0; i < n; ++i) {
        core.step(h);
        for (const auto& e : core.events())
            if (e.type == EventType::Release && e.cause == EventCause::BodyRemoved) ++released;
    }
    return released;
}

bool allFinite(const std::vector<Vec3>& points) {
    return std::all_of(points.begin(), points.end(), [](const Vec3& p) { return p.allFinite(); });
}

// The plugin destroyed first: it leaves Bullet's world (its sentinel and each string's ray object) and a
// crate it held falls freely.
TEST(Lifetimes, PluginDestroyedFirst) {
    Physics phys;
    btRigidBody& crate = phys.box(btVector3(0.1f, 0.1f, 0.1f), 1.0, btVector3(0, 0.9f, 0));
    const int objects = phys.world->getNumCollisionObjects();
    auto ropes = std::make_unique<BulletWorld>(*phys.world);
    const StringId id = ropes->addString(rope({0, 2, 0}, {0, 1, 0}, 10));
    ropes->attach(id, 0, btVector3(0, 2, 0));
    ropes->attach(id, -1, crate, btVector3(0, 0.1f, 0));
    phys.step(5);
    EXPECT_EQ(phys.world->getNumCollisionObjects(), objects + 2);  // its sentinel and the rope's ray object
    ropes.reset();
    EXPECT_EQ(phys.world->getNumCollisionObjects(), objects);
    const float y = crate.getCenterOfMassPosition().y();
    phys.step(20);  // free fall for 0.2 s: 0.2 m
    EXPECT_LT(crate.getCenterOfMassPosition().y(), y - 0.1f);
}

// The Bullet world (and its bodies) destroyed first, with a rope glued to a crate and
// lying on a ground box, a sheet and a cloth glued to the crate: stepping the core
// afterwards touches nothing of Bullet, releases every attachment to the gone crate (one
// event each) and keeps everything finite; destroying the plugin then is safe too.
TEST(Lifetimes, BulletWorldDestroyedFirstThenCoreSteps) {
    Physics phys;
    btRigidBody& crate = phys.box(btVector3(0.1f, 0.1f, 0.1f), 1.0, btVector3(0, 0.9f, 0));
    phys.box(btVector3(1, 0.05f, 1), 0.0, btVector3(0, 0.45f, 0));  // ground under the rope
    auto ropes = std::make_unique<BulletWorld>(*phys.world);
    const StringId hanging = ropes->addString(rope({0, 2, 0}, {0, 1, 0}, 10));
    ropes->attach(hanging, 0, btVector3(0, 2, 0));
    ropes->attach(hanging, -1, crate, btVector3(0, 0.1f, 0));
    const StringId lying = ropes->addString(rope({-0.5, 0.52, 0.5}, {0.5, 0.52, 0.5}, 10));  // touches the ground
    PaperDesc sheet;
    sheet.center = Vec3(0.3, 0.9, 0);
    sheet.size[0] = sheet.size[1] = 0.1;
    sheet.resolution[0] = sheet.resolution[1] = 4;
    const PaperId paper = ropes->addPaper(sheet);
    ropes->attachPaper(paper, 0, crate, btVector3(0.1f, 0, 0));
    ClothDesc cloth;
    cloth.name = "cloth";
    cloth.resolution = {4, 4};
    cloth.size = {0.1, 0.1};
    cloth.corner = Vec3(-0.4, 0.9, 0);
    const ClothId patch = ropes->addCloth(cloth);
    ropes->attachCloth(patch, 0, crate, btVector3(-0.1f, 0, 0));
    phys.step(5);
    ASSERT_TRUE(ropes->core().isAttached(hanging, -1));

    World& kept = ropes->core();  // a reference taken while Bullet lived
    for (auto& b : phys.bodies) phys.world->removeRigidBody(b.get());
    phys.world.reset();
    phys.bodies.clear();
    EXPECT_FALSE(ropes->attachedToBullet());
    const int released = stepCore(ropes->core(), 10);
    EXPECT_EQ(released, 3);  // the rope's, the sheet's and the cloth's hold on the crate
    EXPECT_FALSE(ropes->core().isAttached(hanging, -1));
    EXPECT_EQ(stepCore(kept, 10), 0);
    EXPECT_TRUE(allFinite(*kept.view(hanging).positions));
    EXPECT_TRUE(allFinite(*kept.view(lying).positions));
    EXPECT_TRUE(allFinite(*kept.viewPaper(paper).positions));
    EXPECT_TRUE(allFinite(*kept.viewCloth(patch).positions));
    ropes.reset();
}

// A held body removed from the world at any time: its attachment goes at the next step
// (one event); deleting it after that step is safe.
TEST(Lifetimes, HeldBodyRemovedThenDeletedAfterAStep) {
    Physics phys;
    btRigidBody& crate = phys.box(btVector3(0.1f, 0.1f, 0.1f), 2.0, btVector3(0, 0.9f, 0));
    BulletWorld ropes(*phys.world);
    const StringId id = ropes.addString(rope({0, 2, 0}, {0, 1, 0}, 10));
    ropes.attach(id, 0, btVector3(0, 2, 0));
    ropes.attach(id, -1, crate, btVector3(0, 0.1f, 0));
    phys.step(5);
    phys.world->removeRigidBody(&crate);
    ropes.clearEvents();
    phys.step(1);
    const auto& ev = ropes.events();
    EXPECT_EQ(std::count_if(ev.begin(), ev.end(), [](const auto& e) { return e.cause == EventCause::BodyRemoved; }), 1);
    destroyBody(phys, crate);
    phys.step(20);
    EXPECT_TRUE(ropes.lastError().empty()) << ropes.lastError();
    EXPECT_TRUE(allFinite(*ropes.core().view(id).positions));
}

// forgetBody() lets the user delete a held body at once, without a step in between.
TEST(Lifetimes, ForgetBodyThenDeleteAtOnce) {
    Physics phys;
    btRigidBody& crate = phys.box(btVector3(0.1f, 0.1f, 0.1f), 2.0, btVector3(0, 0.9f, 0));
    BulletWorld ropes(*phys.world);
    const StringId id = ropes.addString(rope({0, 2, 0}, {0, 1, 0}, 10));
    ropes.attach(id, 0, btVector3(0, 2, 0));
    ropes.attach(id, -1, crate, btVector3(0, 0.1f, 0));
    phys.step(5);
    ropes.forgetBody(crate);
    destroyBody(phys, crate);
    phys.step(20);
    EXPECT_FALSE(ropes.core().isAttached(id, -1));
    EXPECT_TRUE(ropes.lastError().empty()) << ropes.lastError();
    EXPECT_TRUE(allFinite(*ropes.core().view(id).positions));
}

// A ball resting on a rope (a contact, no attachment) removed and deleted at once: the
// plugin never reads it again; the rope goes on.
TEST(Lifetimes, TouchedBodyRemovedAndDeletedAtOnce) {
    Physics phys;
    BulletWorld ropes(*phys.world);
    const StringId id = ropes.addString(rope({-0.5, 1, 0}, {0.5, 1, 0}, 20));
    ropes.attach(id, 0, btVector3(-0.5f, 1, 0));
    ropes.attach(id, -1, btVector3(0.5f, 1, 0));
    btRigidBody& ball = phys.sphere(0.05, 0.5, btVector3(0, 1.06f, 0));
    phys.step(30);
    destroyBody(phys, ball);
    phys.step(30);
    EXPECT_TRUE(ropes.lastError().empty()) << ropes.lastError();
    EXPECT_TRUE(allFinite(*ropes.core().view(id).positions));
}

}  // namespace
