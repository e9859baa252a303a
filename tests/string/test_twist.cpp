// Twist (Strings Sec. 4): propagation along a clamped string, non-uniform rigidity,
// torsional plasticity and tearing by torsion.
#include "tearables/world.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace {

using tearables::StringDesc;
using tearables::StringId;
using tearables::Vec3;
using tearables::World;

constexpr double kPi = 3.14159265358979323846;

/// A straight string of 1 m clamped at both ends, in zero gravity.
struct Clamped {
    World world{[] {
        tearables::WorldSettings s;
        s.gravity = Vec3::Zero();
        return s;
    }()};
    StringId id;
    explicit Clamped(StringDesc d) {
        id = world.addString(d);
        world.attachToPoint(id, 0, d.points.front());
        world.attachToPoint(id, -1, d.points.back());
    }
    const std::vector<double>& twist() const { return *world.view(id).twist; }
};

StringDesc straight(int segments) {
    StringDesc d = StringDesc::straight({0, 0, 0}, {1, 0, 0}, segments);
    d.material.variation = 0.0;
    d.material.torsion.yield = 10.0;  // stays elastic here
    d.material.torsion.rupture = 20.0;
    return d;
}

}  // namespace

// Twist one end by a fixed angle and hold it: at rest the twist along the string is
// linear within 5% (Fig. 2, Fig. 6d).
TEST(Twist, HeldTwistIsLinearAlongAUniformString) {
    Clamped c(straight(40));
    const double angle = kPi;
    for (int i = 0; i < 100; ++i) {
        c.world.turnEnd(c.id, -1, angle / 100);
        c.world.step(0.01);
    }
    for (int i = 0; i < 200; ++i) c.world.step(0.01);
    const auto& t = c.twist();
    ASSERT_EQ(t.size(), 40u);
    EXPECT_NEAR(t.front(), 0.0, 1e-12);
    EXPECT_NEAR(t.back(), angle, 1e-12);
    for (std::size_t j = 0; j < t.size(); ++j) {
        const double expected = angle * static_cast<double>(j) / 39.0;
        EXPECT_NEAR(t[j], expected, 0.05 * angle) << j;
    }
}

// An untwisted string that nothing twists skips its twist solve (solveTwist's fast path):
// its angles stay exactly zero while it hangs and swings, and the first turn of an end
// is answered at once, the clamped end at the turned angle and its neighbour after it.
TEST(Twist, UntwistedStringStaysUntwistedAndAnswersTheFirstTurn) {
    tearables::WorldSettings settings;
    World world(settings);
    StringDesc d = straight(40);
    const StringId id = world.addString(d);
    world.attachToPoint(id, 0, d.points.front());  // swings down under gravity
    for (int i = 0; i < 50; ++i) {
        world.step(0.01);
        for (double t : *world.view(id).twist) ASSERT_EQ(t, 0.0) << "step " << i;
    }
    world.turnEnd(id, 0, 0.1);
    world.step(0.01);
    const auto& t = *world.view(id).twist;
    EXPECT_NEAR(t.front(), 0.1, 1e-12);
    EXPECT_GT(t[1], 0.0);
    EXPECT_LT(t[1], 0.1);
}

// A range of higher torsional rigidity (twice the region width) twists less, by the
// rigidity ratio within 10% (Fig. 6e).
TEST(Twist, RigidRangeTwistsLessByTheRigidityRatio) {
    StringDesc d = straight(60);
    d.twist_half_width.assign(60, 2);
    for (int j = 20; j < 40; ++j) d.twist_half_width[j] = 4;
    Clamped c(d);
    for (int i = 0; i < 100; ++i) {
        c.world.turnEnd(c.id, -1, kPi / 100);
        c.world.step(0.01);
    }
    for (int i = 0; i < 200; ++i) c.world.step(0.01);
    const auto& t = c.twist();
    const double soft_rate = (t[15] - t[5]) / 10.0;   // inside the first soft range
    const double rigid_rate = (t[35] - t[25]) / 10.0; // inside the rigid range
    const double soft_rate2 = (t[55] - t[45]) / 10.0;
    EXPECT_NEAR(soft_rate / rigid_rate, 2.0, 0.2);
    EXPECT_NEAR(soft_rate, soft_rate2, 0.02 * soft_rate);
}

// Released, a twisted string with a free end untwists (rotational velocity, Eq. 4-5).
TEST(Twist, FreeEndUntwists) {
    World world;
    StringDesc d = straight(20);
    d.points = StringDesc::straight({0, 0, 0}, {0, -0.5, 0}, 20).points;
    const StringId id = world.addString(d);
    world.attachToPoint(id, 0, {0, 0, 0});
    world.attachToPoint(id, -1, {0, -0.5, 0});
    for (int i = 0; i < 50; ++i) {
        world.turnEnd(id, -1, 4 * kPi / 50);
        world.step(0.01);
    }
    const double twisted = world.view(id).twist->back() - world.view(id).twist->front();
    EXPECT_NEAR(twisted, 4 * kPi, 1e-9);
    world.detach(id, -1);
    for (int i = 0; i < 300; ++i) world.step(0.01);
    const auto& t = *world.view(id).twist;
    EXPECT_LT(std::abs(t.back() - t.front()), 0.05 * twisted);
}

// Past its torsional yield strain a joint keeps part of its twist (Fig. 8, bottom row);
// below yield it returns.
TEST(Twist, TorsionalPlasticityKeepsTwistPastYield) {
    auto run = [](double turns) {
        World world;
        StringDesc d = straight(20);
        d.points = StringDesc::straight({0, 0, 0}, {0, -0.5, 0}, 20).points;
        d.material.torsion.yield = 0.01;
        d.material.torsion.rupture = 1.0;
        const StringId id = world.addString(d);
        world.attachToPoint(id, 0, {0, 0, 0});
        world.attachToPoint(id, -1, {0, -0.5, 0});
        for (int i = 0; i < 50; ++i) {
            world.turnEnd(id, -1, turns * 2 * kPi / 50);
            world.step(0.01);
        }
        world.detach(id, -1);
        for (int i = 0; i < 400; ++i) world.step(0.01);
        const auto& t = *world.view(id).twist;
        return t.back() - t.front();
    };
    // gamma = r dtheta/ds = 0.002 * theta / 0.5: yield 0.01 is 2.5 rad of total twist.
    EXPECT_LT(std::abs(run(0.3)), 0.05);  // 1.9 rad: elastic, returns
    // 2 turns: gamma 0.0503; curve stress G gy + Gp (gamma - gy) = 1.40e7 Pa; the
    // permanent strain gamma - stress/G = 0.0363 is 9.07 rad over the string.
    const double gamma = 0.002 * 4.0 * kPi / 0.5;
    const double stress = 1e9 * 0.01 + 1e8 * (gamma - 0.01);
    const double kept = (gamma - stress / 1e9) * 0.5 / 0.002;
    EXPECT_NEAR(std::abs(run(2.0)), kept, 0.1 * kept);
}

// A string twisted past its torsional rupture strain tears by torsion.
TEST(Twist, TearsByTorsionAtRupture) {
    World world;
    StringDesc d = straight(20);
    d.material.torsion.yield = 0.05;
    d.material.torsion.rupture = 0.1;  // 0.002 * theta / 1 m = 0.1 at 50 rad
    const StringId id = world.addString(d);
    world.attachToPoint(id, 0, {0, 0, 0});
    world.attachToPoint(id, -1, {1, 0, 0});
    double angle_at_tear = -1.0;
    for (int i = 0; i < 2000 && angle_at_tear < 0; ++i) {
        world.turnEnd(id, -1, 0.05);
        world.step(0.01);
        for (const auto& e : world.events())
            if (e.type == tearables::EventType::Tear) {
                EXPECT_EQ(e.cause, tearables::EventCause::Torsion);
                angle_at_tear = world.endTwist(id, -1);
            }
    }
    ASSERT_GT(angle_at_tear, 0.0);
    EXPECT_NEAR(angle_at_tear, 50.0, 0.1 * 50.0);
}

// Twisting a slack string clamped at both ends makes it buckle out of its line (Fig. 6b-c:
// the loop and the telephone-cord spiral), through the twist force of Eq. 6; without the
// twist it stays in its plane.
TEST(Twist, TwistedSlackStringBucklesOutOfItsLine) {
    auto deviation = [](double turns) {
        tearables::WorldSettings ws;
        ws.gravity = Vec3::Zero();
        World world(ws);
        StringDesc d = StringDesc::straight({0, 0, 0}, {1, 0, 0}, 60);
        d.material.variation = 0.0;
        d.material.torsion.yield = 5.0;
        d.material.torsion.rupture = 10.0;
        d.damping = 1.0;
        // A tiny in-plane wiggle, so that the straight line is not an exact equilibrium.
        for (std::size_t i = 1; i + 1 < d.points.size(); ++i) d.points[i].y() = 1e-4 * std::sin(3.1 * i);
        const StringId id = world.addString(d);
        world.attachToPoint(id, 0, {0, 0, 0});
        world.attachToPoint(id, -1, {0.9, 0, 0});  // 10% slack
        for (int i = 0; i < 600; ++i) {
            if (i < 400) world.turnEnd(id, -1, turns * 2 * kPi / 400);
            world.step(0.01);
        }
        double out_of_plane = 0.0;
        for (const Vec3& p : *world.view(id).positions) out_of_plane = std::max(out_of_plane, std::abs(p.z()));
        return out_of_plane;
    };
    EXPECT_LT(deviation(0.0), 1e-6);
    EXPECT_GT(deviation(12.0), 0.03);
}
