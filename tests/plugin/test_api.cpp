// The Bullet-facing API (issue 31): identity (generation-checked ids, user pointers),
// contacts and events a Bullet user can use, and the everyday controls.
#include "tearables/bullet.hpp"
#include "tearables/snapshot.hpp"

#include "bullet_fixture.hpp"

#include <btBulletDynamicsCommon.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <functional>
#include <sstream>
#include <string>

namespace {

using tearables::BulletWorld;
using tearables::ClothDesc;
using tearables::ClothId;
using tearables::InvalidInput;
using tearables::PaperDesc;
using tearables::PaperId;
using tearables::StringDesc;
using tearables::StringId;
using tearables::Vec3;
using tearables::testing::Physics;

/// The field an InvalidInput names and its problem, or "" when nothing was thrown.
std::string refusal(const std::function<void()>& call, std::string* problem = nullptr) {
    try {
        call();
    } catch (const InvalidInput& e) {
        if (problem) *problem = e.problem();
        return e.field();
    }
    return "";
}

/// The bits of every particle's position and velocity (the world unchanged, bit for bit).
std::string stringBits(const BulletWorld& ropes, StringId id) {
    const auto v = ropes.core().view(id);
    std::string out;
    out.append(reinterpret_cast<const char*>(v.positions->data()), v.positions->size() * sizeof(Vec3));
    out.append(reinterpret_cast<const char*>(v.velocities->data()), v.velocities->size() * sizeof(Vec3));
    return out;
}

StringDesc hangingRope() {
    return tearables::testing::plainRope({0, 2, 0}, {1, 2, 0}, 10);
}

// A string removed and another added in its slot: every call given the old id is refused
// naming "string" (as stale), and the new string is stepped exactly as one that no such
// call was made on.
TEST(Identity, StaleStringIdIsRefusedAndTheWorldUnchanged) {
    Physics a, b;
    BulletWorld ropes(*a.world), control(*b.world);
    btRigidBody& crate = a.box(btVector3(0.1f, 0.1f, 0.1f), 1.0, btVector3(3, 0, 0));
    const StringId old = ropes.addString(hangingRope());
    ropes.removeString(old);
    const StringId now = ropes.addString(hangingRope());
    ASSERT_EQ(now.index, old.index);  // the slot is reused...
    EXPECT_NE(now, old);              // ...with the next generation
    ropes.attach(now, 0, btVector3(0, 2, 0));
    const StringId twin = control.addString(hangingRope());
    control.attach(twin, 0, btVector3(0, 2, 0));

    const std::vector<std::function<void()>> calls = {
        [&] { ropes.applyForce(old, 3, btVector3(100, 0, 0)); },
        [&] { ropes.attach(old, 5, btVector3(0, 0, 0)); },
        [&] { ropes.attach(old, -1, crate, btVector3(0, 0, 0)); },
        [&] { ropes.detach(old, 0); },
        [&] { ropes.movePin(old, 0, btVector3(0, 3, 0)); },
        [&] { ropes.peakTension(old); },
        [&] { ropes.clearPeakTension(old); },
        [&] { ropes.removeString(old); },
        [&] { ropes.setUserPointer(old, &crate); },
        [&] { ropes.userPointer(old); },
        [&] { ropes.core().view(old); },
        [&] { ropes.core().cutSegment(old, 2); },
    };
    for (std::size_t k = 0; k < calls.size(); ++k) {
        std::string problem;
        EXPECT_EQ(refusal(calls[k], &problem), "string") << "call " << k;
        EXPECT_NE(problem.find("stale id"), std::string::npos) << "call " << k << ": " << problem;
    }
    EXPECT_FALSE(ropes.core().contains(old));
    EXPECT_EQ(ropes.userPointer(now), nullptr);
    for (int i = 0; i < 30; ++i) {
        a.step(1);
        b.step(1);
    }
    EXPECT_EQ(stringBits(ropes, now), stringBits(control, twin));
    EXPECT_TRUE(ropes.core().isAttached(now, 0));
    EXPECT_TRUE(ropes.events().empty());  // no Release, no Tear from the refused calls
}

TEST(Identity, StaleClothAndPaperIdsAreRefused) {
    Physics p;
    BulletWorld ropes(*p.world);
    ClothDesc cloth;
    cloth.resolution = {4, 4};
    const ClothId c0 = ropes.addCloth(cloth);
    ropes.removeCloth(c0);
    const ClothId c1 = ropes.addCloth(cloth);
    EXPECT_EQ(c1.index, c0.index);
    PaperDesc paper;
    paper.resolution[0] = 4;
    paper.resolution[1] = 4;
    const PaperId p0 = ropes.addPaper(paper);
    ropes.removePaper(p0);
    const PaperId p1 = ropes.addPaper(paper);
    EXPECT_EQ(p1.index, p0.index);
    std::string problem;
    EXPECT_EQ(refusal([&] { ropes.applyClothForce(c0, 0, btVector3(1, 0, 0)); }, &problem), "cloth");
    EXPECT_NE(problem.find("stale id"), std::string::npos) << problem;
    EXPECT_EQ(refusal([&] { ropes.attachCloth(c0, 0, btVector3(0, 0, 0)); }), "cloth");
    EXPECT_EQ(refusal([&] { ropes.setUserPointer(c0, &problem); }), "cloth");
    EXPECT_EQ(refusal([&] { ropes.removeCloth(c0); }), "cloth");
    EXPECT_EQ(refusal([&] { ropes.applyPaperForce(p0, 0, btVector3(1, 0, 0)); }, &problem), "paper");
    EXPECT_NE(problem.find("stale id"), std::string::npos) << problem;
    EXPECT_EQ(refusal([&] { ropes.attachPaper(p0, 0, btVector3(0, 0, 0)); }), "paper");
    EXPECT_EQ(refusal([&] { ropes.userPointer(p0); }), "paper");
    EXPECT_EQ(refusal([&] { ropes.removePaper(p0); }), "paper");
    EXPECT_TRUE(ropes.core().contains(c1));
    EXPECT_TRUE(ropes.core().contains(p1));
    EXPECT_FALSE(ropes.core().viewCloth(c1).frozen);
}

// A snapshot keeps each slot's generation: the id kept across a removal stays refused in
// the restored world, and the live one names its string there.
TEST(Identity, SnapshotsKeepGenerations) {
    tearables::World world;
    const StringId old = world.addString(hangingRope());
    world.removeString(old);
    const StringId now = world.addString(hangingRope());
    std::stringstream bytes;
    tearables::saveSnapshot(world, bytes);
    tearables::World restored;
    tearables::loadSnapshot(restored, bytes);
    EXPECT_TRUE(restored.contains(now));
    EXPECT_FALSE(restored.contains(old));
    const StringId next = restored.addString(hangingRope());
    EXPECT_EQ(next.index, now.index + 1);
    restored.removeString(now);
    EXPECT_EQ(restored.addString(hangingRope()), (StringId{now.index, now.generation + 1}));
}

// The pointer round-trips, stays with the rope through a tear (the pieces are still one
// StringId), is per object, and goes with the object.
TEST(Identity, UserPointerRoundTripsAndSurvivesATear) {
    Physics p;
    BulletWorld ropes(*p.world);
    StringDesc d = StringDesc::straight({0, 2, 0}, {0, 1, 0}, 10);
    d.material.variation = 0.0;
    const StringId rope = ropes.addString(d);
    const StringId other = ropes.addString(hangingRope());
    ropes.attach(rope, 0, btVector3(0, 2, 0));
    int mine = 0, theirs = 0;
    EXPECT_EQ(ropes.userPointer(rope), nullptr);
    ropes.setUserPointer(rope, &mine);
    ropes.setUserPointer(other, &theirs);
    EXPECT_EQ(ropes.userPointer(rope), &mine);
    EXPECT_EQ(ropes.userPointer(other), &theirs);
    ASSERT_TRUE(ropes.core().cutSegment(rope, 4));
    p.step(20);
    ASSERT_EQ((*ropes.core().view(rope).broken)[4], 1);
    bool torn = false;
    for (const auto& e : ropes.events()) torn |= e.type == tearables::EventType::Tear && e.string == rope;
    EXPECT_TRUE(torn);
    EXPECT_EQ(ropes.userPointer(rope), &mine);  // both pieces: the same id, the same pointer
    ropes.setUserPointer(rope, nullptr);
    EXPECT_EQ(ropes.userPointer(rope), nullptr);
    ropes.setUserPointer(rope, &mine);
    ropes.removeString(rope);
    const StringId again = ropes.addString(d);
    EXPECT_EQ(again.index, rope.index);
    EXPECT_EQ(ropes.userPointer(again), nullptr);  // the new rope in the slot has none
    EXPECT_EQ(ropes.userPointer(other), &theirs);
}

}  // namespace
