// Sleeping and collision filtering with Bullet: only bodies that a string holds or pushes
// are woken, and each string, sheet and cloth has Bullet's collision group and mask,
// checked both ways against each body's broadphase proxy (as addSoftBody(body, group, mask)).
#include "tearables/bullet_core.hpp"
#include "tearables/scene.hpp"

#include "bullet_fixture.hpp"

#include <btBulletDynamicsCommon.h>
#include <gtest/gtest.h>

#include <string>

namespace {

using tearables::BulletWorld;
using tearables::StringDesc;
using tearables::StringId;
using tearables::Vec3;
using tearables::testing::Physics;

constexpr double kG = 9.81;

StringDesc rope(const Vec3& from, const Vec3& to, int segments) { return tearables::testing::plainRope(from, to, segments); }

void frames(Physics& phys, int n) {
    for (int i = 0; i < n; ++i) phys.world->stepSimulation(btScalar(1) / 60, 10, btScalar(1) / 240);
}

double meanY(const BulletWorld& ropes, StringId id) {
    const auto& x = *ropes.core().view(id).positions;
    double y = 0.0;
    for (const Vec3& p : x) y += p.y();
    return y / static_cast<double>(x.size());
}

}  // namespace

// A box resting on the ground 1.5 cm beside a rope that hangs still: inside the rope's
// bounds, but neither held nor pushed, so it falls asleep as Bullet puts any resting body
// to sleep: after gDeactivationTime (2 s) below the sleeping thresholds. 2.5 s allows the
// box half a second to settle on the ground.
TEST(BulletSleep, BoxBesideAHangingRopeFallsAsleep) {
    Physics phys;
    phys.box(btVector3(2, 0.5f, 2), 0.0, btVector3(0, -0.5f, 0));
    btRigidBody& box = phys.box(btVector3(0.1f, 0.1f, 0.1f), 1.0, btVector3(0, 0.1f, 0));
    BulletWorld ropes(*phys.world);
    const StringDesc d = rope({0.117, 1.0, 0}, {0.117, 0.05, 0}, 20);  // surface 1.5 cm from the box's side
    const StringId id = ropes.addString(d);
    ropes.attach(id, 0, btVector3(0.117f, 1.0f, 0));
    frames(phys, 150);  // 2.5 s
    EXPECT_EQ(box.getActivationState(), ISLAND_SLEEPING);
    EXPECT_NEAR(ropes.core().view(id).positions->back().x(), 0.117, 1e-3);  // the rope still hangs there
}

// A rope lying across a box that rests on the ground: its weight pushes the box at every
// step, so the box stays awake through twice Bullet's sleeping time, and the rope still lies
// on its top (y = 0.2 m plus the rope's radius).
TEST(BulletSleep, BoxPushedByARopeStaysAwake) {
    Physics phys;
    phys.box(btVector3(2, 0.5f, 2), 0.0, btVector3(0, -0.5f, 0));
    btRigidBody& box = phys.box(btVector3(0.1f, 0.1f, 0.1f), 1.0, btVector3(0, 0.1f, 0));
    BulletWorld ropes(*phys.world);
    const StringDesc d = rope({-0.3, 0.203, 0}, {0.3, 0.203, 0}, 30);
    const StringId id = ropes.addString(d);
    frames(phys, 240);  // 4 s
    EXPECT_EQ(box.getActivationState(), ACTIVE_TAG);
    EXPECT_NEAR((*ropes.core().view(id).positions)[15].y(), 0.2 + d.radius, 1e-3);
}

// A rope falling onto a static block: the default filter lands on it; a mask without the
// block's group, or a block whose mask lacks the rope's group, lets it fall through freely:
// after 1 s its mean height has dropped by g t^2 / 2 (within g h t, the difference between
// Euler variants over 240 steps of h).
TEST(BulletFilter, GroupsAndMasksAreCheckedBothWays) {
    const double t = 1.0, h = 1.0 / 240.0;
    const double y0 = 0.5, fallen = y0 - 0.5 * kG * t * t;
    struct Case {
        const char* name;
        int rope_group, rope_mask, block_group, block_mask;
        bool passes;
    };
    const Case cases[] = {
        {"default", btBroadphaseProxy::DefaultFilter, btBroadphaseProxy::AllFilter, 4, btBroadphaseProxy::AllFilter, false},
        {"rope mask excludes the block", btBroadphaseProxy::DefaultFilter, ~4, 4, btBroadphaseProxy::AllFilter, true},
        {"block mask excludes the rope", 8, btBroadphaseProxy::AllFilter, 4, ~8, true},
    };
    for (const Case& c : cases) {
        Physics phys;
        btRigidBody& block = phys.box(btVector3(1, 0.1f, 1), 0.0, btVector3(0, -0.1f, 0));
        phys.world->removeRigidBody(&block);
        phys.world->addRigidBody(&block, c.block_group, c.block_mask);
        BulletWorld ropes(*phys.world);
        const StringDesc d = rope({-0.3, y0, 0}, {0.3, y0, 0}, 20);
        const bool is_default = c.rope_group == btBroadphaseProxy::DefaultFilter && c.rope_mask == btBroadphaseProxy::AllFilter;
        const StringId id = is_default ? ropes.addString(d) : ropes.addString(d, c.rope_group, c.rope_mask);
        frames(phys, 60);
        if (c.passes)
            EXPECT_NEAR(meanY(ropes, id), fallen, kG * h * t) << c.name;
        else
            EXPECT_NEAR(meanY(ropes, id), d.radius, 0.01) << c.name;  // resting on the block's top (y = 0)
    }
}

// The scene format carries the filter (signed or unsigned 32-bit), and a bad one is refused
// with its JSON path.
TEST(BulletFilter, SceneFieldsParseAndRefuseBadValues) {
    const tearables::scene::Scene s = tearables::scene::parseScene(
        R"({"strings": [{"name": "rope", "from": [0, 2, 0], "to": [0, 1, 0], "collision_group": 2, "collision_mask": 4294967291},
                        {"name": "plain", "from": [1, 2, 0], "to": [1, 1, 0]}]})");
    EXPECT_EQ(s.strings[0].collision_group, 2);
    EXPECT_EQ(s.strings[0].collision_mask, ~4);
    EXPECT_EQ(s.strings[1].collision_group, btBroadphaseProxy::DefaultFilter);
    EXPECT_EQ(s.strings[1].collision_mask, btBroadphaseProxy::AllFilter);
    try {
        tearables::scene::parseScene(R"({"strings": [{"name": "rope", "from": [0, 2, 0], "to": [0, 1, 0], "collision_mask": 1.5}]})");
        ADD_FAILURE() << "accepted a fractional mask";
    } catch (const tearables::InvalidInput& e) {
        EXPECT_EQ(e.field(), "strings[0].collision_mask");
    }
    try {
        tearables::scene::parseScene(
            R"({"cloths": [{"name": "c", "resolution": [3, 3], "collision_group": 4294967296}]})");
        ADD_FAILURE() << "accepted a group of 33 bits";
    } catch (const tearables::InvalidInput& e) {
        EXPECT_EQ(e.field(), "cloths[0].collision_group");
    }
}

namespace {

double meanY(const std::vector<Vec3>& x) {
    double y = 0.0;
    for (const Vec3& p : x) y += p.y();
    return y / static_cast<double>(x.size());
}

}  // namespace

// A cloth and a paper sheet side by side fall onto a static block of group 4; a mask without
// group 4 lets that one object through (its mean height drops by g t^2 / 2 in t = 1 s,
// within 5 cm), while the other, with the default filter, lands on the block (y = 0).
TEST(BulletFilter, SheetsAndClothsHaveTheirOwnFilter) {
    const double y0 = 0.3, fallen = y0 - 0.5 * kG * 1.0;
    for (const bool cloth_passes : {false, true}) {
        Physics phys;
        btRigidBody& block = phys.box(btVector3(2, 0.1f, 1), 0.0, btVector3(0, -0.1f, 0));
        phys.world->removeRigidBody(&block);
        phys.world->addRigidBody(&block, 4, btBroadphaseProxy::AllFilter);
        BulletWorld ropes(*phys.world);
        tearables::ClothDesc c;
        c.resolution = {9, 9};
        c.size = {0.4, 0.4};
        c.corner = Vec3(-1.2, y0, -0.2);
        c.areal_density = 0.2;
        tearables::PaperDesc p;
        p.center = Vec3(1.0, y0, 0);
        p.size[0] = p.size[1] = 0.4;
        p.resolution[0] = p.resolution[1] = 9;
        const tearables::ClothId cloth = cloth_passes ? ropes.addCloth(c, 1, ~4) : ropes.addCloth(c);
        const tearables::PaperId paper = cloth_passes ? ropes.addPaper(p) : ropes.addPaper(p, 1, ~4);
        frames(phys, 60);
        const double cloth_y = meanY(*ropes.core().viewCloth(cloth).positions);
        const double paper_y = meanY(*ropes.core().viewPaper(paper).positions);
        EXPECT_NEAR(cloth_passes ? cloth_y : paper_y, fallen, 0.05) << (cloth_passes ? "cloth" : "paper");
        EXPECT_NEAR(cloth_passes ? paper_y : cloth_y, 0.0, 0.02) << (cloth_passes ? "paper" : "cloth");
    }
}
