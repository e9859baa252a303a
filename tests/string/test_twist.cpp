// Twist (Strings Sec. 4): propagation along a clamped string, non-uniform rigidity,
// torsional plasticity and tearing by torsion.
#include "tearables/queries.hpp"
#include "tearables/world.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

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

namespace {

/// The rod with straight tails 1 km long along its held ends (the closure along the end
/// tangents under which Tw + Wr is the link), as a polyline.
std::vector<Vec3> withTails(const std::vector<Vec3>& x) {
    std::vector<Vec3> out = x;
    out.insert(out.begin(), x.front() - 1000.0 * (x[1] - x[0]).normalized());
    out.push_back(x.back() + 1000.0 * (x.back() - x[x.size() - 2]).normalized());
    return out;
}

}  // namespace

// Link conservation (Calugareanu-White-Fuller), kinematic: a rod held straight along x and
// twisted one turn, every particle pinned, is carried by its pins into n = 3 turns of a
// helix of tangent angle alpha = 40 degrees between straight axial ends. Fuller's closed
// form gives the writhe of the helix with its axial tails, n (1 - cos alpha) = 0.7019
// turns, negative for this left-handed helix (the polyline's writhe differs from the
// smooth helix's by its discretisation: 40 points a turn, chords, asserted within 2%); the
// end segments never turn, so the link is still 1 and the twist must change by minus the
// writhe: Tw + Wr = 1 within 1% of the writhe.
TEST(Twist, RodCarriedIntoAHelixTradesTwistForWritheAsFullerSays) {
    tearables::WorldSettings ws;
    ws.gravity = Vec3::Zero();
    ws.string_collisions = false;
    World world(ws);
    const int turns_of_helix = 3, per_turn = 40, tail = 10;
    const double alpha = 40.0 * kPi / 180.0, radius = 0.05;
    const double pitch_angle_step = 2 * kPi / per_turn;
    // The helix: arc length per point ds = radius * step / sin(alpha); axial advance ds cos(alpha).
    const double ds = radius * pitch_angle_step / std::sin(alpha);
    const int helix_points = turns_of_helix * per_turn;
    std::vector<Vec3> target;
    for (int i = 0; i <= tail; ++i) target.emplace_back(i * ds, 0, 0);
    for (int k = 1; k <= helix_points; ++k) {
        const double phi = k * pitch_angle_step;
        target.emplace_back(tail * ds + k * ds * std::cos(alpha), radius * (1.0 - std::cos(phi)), radius * std::sin(phi));
    }
    const Vec3 end = target.back();
    for (int i = 1; i <= tail; ++i) target.push_back(end + Vec3(i * ds, 0, 0));
    // The straight rod these points come from: the same axial positions, on the axis.
    StringDesc d;
    for (const Vec3& p : target) d.points.emplace_back(p.x(), 0, 0);
    d.radius = 0.001;
    d.tearable = false;
    d.material.variation = 0.0;
    d.material.torsion.yield = 500.0;
    d.material.torsion.rupture = 1000.0;
    const StringId id = world.addString(d);
    const int n = static_cast<int>(d.points.size());
    for (int p = 0; p < n; ++p) world.attachToPoint(id, p, d.points[static_cast<std::size_t>(p)]);
    const int twisting = 50, carrying = 200, holding = 50;
    for (int i = 0; i < twisting; ++i) {
        world.turnEnd(id, -1, 2 * kPi / twisting);
        world.step(0.01);
    }
    for (int i = 1; i <= carrying + holding; ++i) {
        const double s = std::min(1.0, static_cast<double>(i) / carrying);
        for (int p = 0; p < n; ++p) {
            const Vec3& a = d.points[static_cast<std::size_t>(p)];
            const Vec3& b = target[static_cast<std::size_t>(p)];
            world.movePin(id, p, a + s * (b - a));
        }
        world.step(0.01);
    }
    const double writhe = tearables::polylineWrithe(withTails(*world.view(id).positions));
    // Left-handed: seen from +x it turns clockwise.
    const double fuller = -turns_of_helix * (1.0 - std::cos(alpha));
    EXPECT_NEAR(writhe, fuller, 0.02 * std::abs(fuller));
    const double twist = tearables::linkMeasure(world, id).twist;
    EXPECT_NEAR(twist + writhe, 1.0, 0.01 * std::abs(fuller));
}

// Link conservation, dynamic: a rod of 1 m held by its two end segments (two pinned
// particles at each end), twisted N = 4 turns at one end, then its ends brought 0.5 m
// together over 5 s: it coils into a plectoneme, trading its twist for writhe (all of it,
// measured: Wr = 3.95-4.03 turns at the end), and Tw + Wr stays N within 5% at every step.
// (A rod that passed through itself would change its link by whole turns.)
TEST(Twist, ClampedRodThatCoilsKeepsItsLink) {
    tearables::WorldSettings ws;
    ws.gravity = Vec3::Zero();
    World world(ws);
    const int segments = 100;
    StringDesc d = StringDesc::straight({0, 0, 0}, {1, 0, 0}, segments);
    d.radius = 0.003;
    d.material.variation = 0.0;
    d.material.torsion.yield = 10.0;
    d.material.torsion.rupture = 20.0;
    d.damping = 3.0;
    for (std::size_t i = 1; i + 1 < d.points.size(); ++i) d.points[i].y() = 1e-4 * std::sin(3.1 * i);
    const StringId id = world.addString(d);
    const double step = 1.0 / segments;
    for (int p : {0, 1}) world.attachToPoint(id, p, {p * step, 0, 0});
    for (int p : {-2, -1}) world.attachToPoint(id, p, {1.0 + (p + 1) * step, 0, 0});
    const double turns = 4.0, h = 0.01;
    const int twisting = 100, closing = 500, settling = 100;
    double worst = 0.0, writhe = 0.0;
    for (int i = 0; i < twisting + closing + settling; ++i) {
        if (i < twisting) world.turnEnd(id, -1, turns * 2 * kPi / twisting);
        if (i >= twisting && i < twisting + closing) {
            const double shift = 0.5 * (i - twisting + 1) / closing;
            world.movePin(id, -2, {1.0 - step - shift, 0, 0});
            world.movePin(id, -1, {1.0 - shift, 0, 0});
        }
        world.step(h);
        if (i >= twisting && i % 5 == 0) {
            writhe = tearables::polylineWrithe(withTails(*world.view(id).positions));
            worst = std::max(worst, std::abs(tearables::linkMeasure(world, id).twist + writhe - turns));
        }
    }
    EXPECT_LT(worst, 0.05 * turns);
    EXPECT_GT(writhe, 0.5 * turns);
}
