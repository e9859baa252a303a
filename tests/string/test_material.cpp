// Material response (Strings Sec. 5.1-5.4, Fig. 7-8): rupture order, elongation by
// Young's modulus, plasticity in tension, torsional rupture order.
#include "tearables/world.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

namespace {

using tearables::EventCause;
using tearables::EventType;
using tearables::StringDesc;
using tearables::StringId;
using tearables::Vec3;
using tearables::World;

constexpr double kPi = 3.14159265358979323846;

StringDesc hanging(double x) {
    StringDesc d = StringDesc::straight({x, 0, 0}, {x, -0.5, 0}, 20);
    d.radius = 0.001;
    d.material.variation = 1e-4;  // Strings Sec. 7: "up to 0.01%"
    d.damping = 1.0;
    return d;
}

double length(const World& w, StringId id) {
    const auto v = w.view(id);
    double sum = 0.0;
    for (std::size_t j = 0; j < v.segmentCount(); ++j)
        if (!(*v.broken)[j]) sum += ((*v.positions)[j + 1] - (*v.positions)[j]).norm();
    return sum;
}

}  // namespace

// Four ropes of increasing rupture stress under the same slowly growing load tear in that
// order (Fig. 7a).
TEST(Material, RuptureOrderFollowsRuptureStress) {
    World world;
    std::vector<StringId> ids;
    for (int i = 0; i < 4; ++i) {
        StringDesc d = hanging(0.1 * i);
        d.material.tensile.rupture = 5e7 + 1e7 * i;
        d.seed = 10 + i;
        ids.push_back(world.addString(d));
        world.attachToPoint(ids.back(), 0, d.points.front());
    }
    std::vector<int> order;
    for (int step = 0; step < 3000 && order.size() < 4; ++step) {
        const double load = 40.0 * step * 0.01;  // N, grows 40 N/s
        for (int i = 0; i < 4; ++i)
            world.applyForce(ids[i], -1, {0, -load, 0});
        world.step(0.01);
        // The first tear of each rope counts (a torn-off piece pulled on may tear again).
        for (const auto& e : world.events())
            if (e.type == EventType::Tear)
                for (int i = 0; i < 4; ++i)
                    if (e.string == ids[i] && std::find(order.begin(), order.end(), i) == order.end()) order.push_back(i);
    }
    ASSERT_EQ(order.size(), 4u);
    EXPECT_EQ(order, (std::vector<int>{0, 1, 2, 3}));
}

// Lower Young's modulus, same rupture stress: the softer rope is longer when it tears
// (Fig. 7b).
TEST(Material, SofterRopeElongatesMoreBeforeTearing) {
    auto elongation_at_tear = [](double young) {
        World world;
        StringDesc d = hanging(0.0);
        d.material.tensile.young = young;
        d.material.tensile.yield = 6e7;
        d.material.tensile.rupture = 8e7;
        const StringId id = world.addString(d);
        world.attachToPoint(id, 0, {0, 0, 0});
        double last = 0.5;
        for (int step = 0; step < 3000; ++step) {
            world.applyForce(id, -1, {0, -30.0 * step * 0.01, 0});
            world.step(0.01);
            for (const auto& e : world.events())
                if (e.type == EventType::Tear) return last - 0.5;
            last = length(world, id);
        }
        return -1.0;
    };
    const double stiff = elongation_at_tear(3e9);
    const double soft = elongation_at_tear(3e8);
    ASSERT_GT(stiff, 0.0);
    ASSERT_GT(soft, 0.0);
    // Strain at rupture from the curve: yield/E + (rupture - yield)/E_p, E_p = 3e8:
    // 2% + 6.7% for the stiff rope, 20% + 6.7% for the soft one.
    EXPECT_NEAR(stiff / 0.5, 6e7 / 3e9 + 2e7 / 3e8, 0.01);
    EXPECT_NEAR(soft / 0.5, 6e7 / 3e8 + 2e7 / 3e8, 0.02);
    EXPECT_GT(soft, 2.5 * stiff);
}

// Loaded past yield and released, a rope keeps the permanent elongation its curve
// predicts within 10%; loaded below yield it returns to its rest length within 0.1%
// (Fig. 8, top row).
TEST(Material, TensilePlasticityKeepsThePredictedElongation) {
    auto rest_after = [](double load, double* predicted) {
        World world;
        StringDesc d = hanging(0.0);
        d.material.variation = 0.0;
        const auto& c = d.material.tensile;
        const StringId id = world.addString(d);
        world.attachToPoint(id, 0, {0, 0, 0});
        for (int step = 0; step <= 300; ++step) {  // ramp up over 3 s, hold 1 s
            world.applyForce(id, -1, {0, -load * std::min(1.0, step / 200.0), 0});
            world.step(0.01);
        }
        for (int step = 0; step < 500; ++step) world.step(0.01);  // released, settles
        const double stress = load / (kPi * d.radius * d.radius);
        const double curve = stress <= c.yield ? stress / c.young : c.yield / c.young + (stress - c.yield) / c.plastic_modulus;
        *predicted = 0.5 * (stress > c.yield ? curve - stress / c.young : 0.0);
        return length(world, id) - 0.5;
    };
    double predicted = 0.0;
    const double above = rest_after(200.0, &predicted);  // 64 MPa: past the 40 MPa yield
    ASSERT_GT(predicted, 0.01);
    EXPECT_NEAR(above, predicted, 0.1 * predicted);
    const double below = rest_after(60.0, &predicted);   // 19 MPa: elastic
    EXPECT_LT(std::abs(below), 1e-3 * 0.5);
}

// Increasing torsional rupture strain, same twist rate: tears later (Fig. 7c).
TEST(Material, TorsionalRuptureOrder) {
    World world;
    std::vector<StringId> ids;
    for (int i = 0; i < 4; ++i) {
        StringDesc d = StringDesc::straight({0, 0.1 * i, 0}, {1, 0.1 * i, 0}, 20);
        d.material.variation = 1e-4;
        d.material.torsion.yield = 0.02;
        d.material.torsion.rupture = 0.05 + 0.02 * i;
        d.seed = 20 + i;
        ids.push_back(world.addString(d));
        world.attachToPoint(ids.back(), 0, d.points.front());
        world.attachToPoint(ids.back(), -1, d.points.back());
    }
    std::vector<int> order;
    for (int step = 0; step < 4000 && order.size() < 4; ++step) {
        for (int i = 0; i < 4; ++i) world.turnEnd(ids[i], -1, 0.05);
        world.step(0.01);
        for (const auto& e : world.events())
            if (e.type == EventType::Tear) {
                EXPECT_EQ(e.cause, EventCause::Torsion);
                for (int i = 0; i < 4; ++i)
                    if (e.string == ids[i]) order.push_back(i);
            }
    }
    EXPECT_EQ(order, (std::vector<int>{0, 1, 2, 3}));
}

// A rope between two pins, no gravity, one pin moved away at 0.1 m/s (1 mm a step, 0.2% of
// its 0.5 m): its particles are in equilibrium, so the momentum balance alone cannot tell
// its tension (any uniform tension fits); the stretch tells it. It yields when the stretch
// reaches yield / E (1.33%) and tears when the curve reaches rupture: yield / E + (rupture
// - yield) / H = 14.67% of its rest length, each to within a step's move (plus one for the
// step that reads it). Before, it read ~0 N, stretched without end and never tore.
TEST(Material, RopePulledApartBetweenPinsYieldsAndTearsOnItsCurve) {
    tearables::WorldSettings settings;
    settings.gravity = Vec3::Zero();
    World world(settings);
    StringDesc d = StringDesc::straight({0, 0, 0}, {0.5, 0, 0}, 20);
    d.radius = 0.001;
    d.material.variation = 0.0;
    const auto& c = d.material.tensile;
    const StringId id = world.addString(d);
    world.attachToPoint(id, 0, {0, 0, 0});
    world.attachToPoint(id, -1, {0.5, 0, 0});
    const double speed = 0.1, dt = 0.01, rest = 0.5, move = speed * dt;
    double yielded_at = -1.0, torn_at = -1.0;  // the pin's travel when each first happened
    for (int step = 1; step <= 400 && torn_at < 0.0; ++step) {
        world.movePin(id, -1, {rest + speed * dt * step, 0, 0});
        world.step(dt);
        for (const auto& e : world.events()) {
            if (e.type == EventType::Yield && yielded_at < 0.0) yielded_at = speed * dt * step;
            if (e.type == EventType::Tear && torn_at < 0.0) torn_at = speed * dt * step;
        }
    }
    const double yield_stretch = rest * c.yield / c.young;
    const double rupture_stretch = rest * (c.yield / c.young + (c.rupture - c.yield) / c.plastic_modulus);
    ASSERT_GT(yielded_at, 0.0) << "never yielded";
    EXPECT_NEAR(yielded_at, yield_stretch, 2 * move);
    ASSERT_GT(torn_at, 0.0) << "never tore";
    EXPECT_NEAR(torn_at, rupture_stretch, 2 * move);
}
