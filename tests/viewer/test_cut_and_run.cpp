// The public calls the viewer uses: World::cutSegment (the cut tool) and scene::SceneRun
// (the viewer steps a scene itself, drops crates and blows wind).
#include "tearables/scene.hpp"
#include "tearables/world.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace {

using tearables::InvalidInput;
using tearables::StringDesc;
using tearables::StringId;
using tearables::Vec3;
using tearables::World;

constexpr double kG = 9.81;

}  // namespace

// A hanging rope of 10 segments cut at segment 4: the Tear event (cause request) comes with
// the next step; the 6 particles below fall freely (their momentum grows by exactly their
// weight times the time: the cut leaves no force between the pieces); the piece above hangs
// with each segment carrying the weight below it (within 2 %, as Chain.HangingRope...).
TEST(CutSegment, CutRopeFallsBelowAndHangsAbove) {
    World world;
    StringDesc d = StringDesc::straight({0, 1, 0}, {0, 0, 0}, 10);
    d.name = "rope";
    d.material.variation = 0.0;
    d.bending = 0.0;
    const StringId id = world.addString(d);
    world.attachToPoint(id, 0, {0, 1, 0});
    for (int i = 0; i < 200; ++i) world.step(0.01);
    ASSERT_TRUE(world.events().empty());

    EXPECT_TRUE(world.cutSegment(id, 4));
    EXPECT_FALSE(world.cutSegment(id, 4));   // already cut: nothing changes
    EXPECT_FALSE(world.cutSegment(id, -6));  // the same segment from the end
    EXPECT_EQ((*world.view(id).broken)[4], 1);
    EXPECT_EQ((*world.view(id).tension)[4], 0.0);

    const auto momentumBelow = [&] {
        const auto v = world.view(id);
        Vec3 p = Vec3::Zero();
        double m = 0.0;
        for (std::size_t k = 5; k < v.particleCount(); ++k) {
            p += (*v.masses)[k] * (*v.velocities)[k];
            m += (*v.masses)[k];
        }
        return std::make_pair(p, m);
    };
    const auto [p0, mass_below] = momentumBelow();
    world.step(0.01);
    ASSERT_EQ(world.events().size(), 1u);
    const tearables::Event& e = world.events()[0];
    EXPECT_EQ(e.type, tearables::EventType::Tear);
    EXPECT_EQ(e.cause, tearables::EventCause::Request);
    EXPECT_EQ(e.segment, 4);
    EXPECT_EQ(e.object, "rope");
    for (int i = 1; i < 30; ++i) world.step(0.01);
    const auto [p1, m1] = momentumBelow();
    const double expected = -mass_below * kG * 0.30;  // 30 steps of 0.01 s
    EXPECT_NEAR(p1.y() - p0.y(), expected, 1e-6 * std::abs(expected));
    EXPECT_NEAR(p1.x() - p0.x(), 0.0, 1e-9);

    for (int i = 0; i < 300; ++i) world.step(0.01);
    const auto v = world.view(id);
    double below = 0.0;
    for (int j = 3; j >= 0; --j) {
        below += (*v.masses)[j + 1] * kG;
        EXPECT_NEAR((*v.tension)[j], below, 0.02 * below) << "segment " << j;
    }
}

TEST(CutSegment, BadArgumentsAreRefusedNamingTheField) {
    World world;
    const StringId id = world.addString(StringDesc::straight({0, 1, 0}, {0, 0, 0}, 10));
    try {
        world.cutSegment(id, 10);
        FAIL() << "segment 10 of 10 accepted";
    } catch (const InvalidInput& e) {
        EXPECT_EQ(e.field(), "segment");
    }
    EXPECT_THROW(world.cutSegment(id, -11), InvalidInput);
    world.removeString(id);
    try {
        world.cutSegment(id, 0);
        FAIL() << "a removed string accepted";
    } catch (const InvalidInput& e) {
        EXPECT_EQ(e.field(), "string");
    }
}

// runScene is a SceneRun stepped to the end: the same digest as stepping one by hand.
TEST(SceneRun, SteppedByHandGivesRunScenesDigest) {
    namespace ts = tearables::scene;
    const ts::Scene scene = ts::parseScene(*ts::builtinSceneText("swing"));
    ts::RunOptions options;
    options.steps = 120;
    const ts::RunResult whole = ts::runScene(scene, options);
    ts::SceneRun run(scene, options);
    EXPECT_EQ(run.steps(), 120);
    while (run.step() < run.steps()) run.advance();
    EXPECT_NEAR(run.time(), 1.2, 1e-12);
    EXPECT_EQ(run.finish().digest, whole.digest);
}

// A body added by hand falls as a spawned one; a taken name is refused; an extra wind
// pushes a hanging rope downwind; a bad wind is refused naming it.
TEST(SceneRun, AddBodyAndWind) {
    namespace ts = tearables::scene;
    const ts::Scene scene = ts::parseScene(*ts::builtinSceneText("hanging-rope"));
    ts::SceneRun still(scene), windy(scene);
    ts::Body crate;
    crate.name = "crate";
    crate.position = Vec3(2.0, 5.0, 0.0);
    crate.shape.half_extents = Vec3::Constant(0.1);
    const std::size_t before = still.bodyCount();
    still.addBody(crate);
    EXPECT_EQ(still.bodyCount(), before + 1);
    EXPECT_THROW(still.addBody(crate), InvalidInput);
    EXPECT_THROW(windy.setExtraWind(Vec3(NAN, 0, 0)), InvalidInput);
    EXPECT_THROW(windy.setExtraWind(Vec3(1000, 0, 0)), InvalidInput);
    windy.setExtraWind(Vec3(0, 0, 10));  // across the rope's plane (it hangs in x-y)
    for (int i = 0; i < 50; ++i) {
        still.advance();
        windy.advance();
    }
    // The crate fell freely for 0.5 s: g t^2 / 2 = 1.226 m (Bullet's semi-implicit Euler
    // falls g dt^2 / 2 further per step: 0.025 m over 50 steps).
    const tearables::scene::FrameState f = still.frame();
    EXPECT_NEAR(f.bodies.back().position.y(), 5.0 - 0.5 * kG * 0.25, 0.03);
    const double z_still = f.strings[0].view.positions->back().z();
    const double z_windy = windy.frame().strings[0].view.positions->back().z();
    EXPECT_NEAR(z_still, 0.0, 1e-9);
    EXPECT_GT(z_windy, 0.01);
}
