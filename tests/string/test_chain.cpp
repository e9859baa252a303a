// The string core without Bullet, against analytic results (Strings Sec. 5.2; Yarn Sec. 3.2).
#include "world/world_access.hpp"
#include "tearables/world.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

namespace {

using tearables::StringDesc;
using tearables::StringId;
using tearables::Vec3;
using tearables::World;

constexpr double kPi = 3.14159265358979323846;
constexpr double kG = 9.81;

/// A rope without bending stiffness: these tests are about strain limiting and tension.
StringDesc rope(const Vec3& from, const Vec3& to, int segments) {
    StringDesc d = StringDesc::straight(from, to, segments);
    d.material.variation = 0.0;
    d.bending = 0.0;
    return d;
}

double ropeMass(const StringDesc& d, double length) { return d.density * kPi * d.radius * d.radius * length; }

double length(const tearables::StringView& v) {
    double sum = 0.0;
    for (std::size_t j = 0; j < v.segmentCount(); ++j) sum += ((*v.positions)[j + 1] - (*v.positions)[j]).norm();
    return sum;
}

}  // namespace

// A rope of 1 m hanging from a fixed point with a tip mass 10x its own: at rest its length
// is within 0.1% of rest length, and every segment carries the weight below it within 2%.
TEST(Chain, HangingRopeTensionEqualsWeightBelow) {
    for (int segments : {10, 50, 200}) {
        World world;
        StringDesc d = rope({0, 1, 0}, {0, 0, 0}, segments);
        d.particle_masses = {{-1, 10.0 * ropeMass(d, 1.0)}};
        const StringId id = world.addString(d);
        world.attachToPoint(id, 0, {0, 1, 0});
        for (int i = 0; i < 500; ++i) world.step(0.01);
        const auto v = world.view(id);
        EXPECT_NEAR(length(v), 1.0, 1e-3) << segments;
        double below = 0.0;
        for (int j = segments - 1; j >= 0; --j) {
            below += (*v.masses)[j + 1] * kG;
            EXPECT_NEAR((*v.tension)[j], below, 0.02 * below) << "segment " << j << " of " << segments;
        }
    }
}

// The same rope at Bullet's default 60 Hz with a tip 1000x the rope (the mass ratio is
// what makes Bullet's anchored soft bodies stretch): it lengthens only by the elastic
// strain its Young's modulus gives, T / (E A), within 0.1% of its length.
TEST(Chain, HeavyTipStretchesOnlyElastically) {
    World world;
    StringDesc d = rope({0, 1, 0}, {0, 0, 0}, 100);
    const double rope_mass = ropeMass(d, 1.0);
    d.particle_masses = {{-1, 1000.0 * rope_mass}};
    d.tearable = false;
    const StringId id = world.addString(d);
    world.attachToPoint(id, 0, {0, 1, 0});
    for (int i = 0; i < 300; ++i) world.step(1.0 / 60.0);
    const auto v = world.view(id);
    const double weight = 1001.0 * rope_mass * kG;
    const double elastic = weight / (d.material.tensile.young * kPi * d.radius * d.radius);
    EXPECT_GT(elastic, 2e-3);  // a visible stretch: nylon under 142 N on 2 mm radius
    EXPECT_NEAR(length(v), 1.0 + elastic, 1e-3);
    EXPECT_NEAR((*v.tension)[0], weight, 0.02 * weight);
}

// A light string with a bob released from 60 degrees: tension at the bottom of the swing
// m g (3 - 2 cos 60deg) = 2 m g within 5%.
TEST(Chain, PendulumTensionAtBottomOfSwing) {
    const double L = 1.0;
    const double a = kPi / 3.0;
    World world;
    StringDesc d = rope({0, 0, 0}, {L * std::sin(a), -L * std::cos(a), 0}, 20);
    d.radius = 0.0005;
    const double bob = 1.0;
    d.particle_masses = {{-1, bob}};
    d.tearable = false;
    const StringId id = world.addString(d);
    world.attachToPoint(id, 0, {0, 0, 0});
    double max_tension = 0.0;
    double lowest = 0.0;
    for (int i = 0; i < 100; ++i) {  // a quarter period is ~0.53 s
        world.step(0.005);
        const auto v = world.view(id);
        const Vec3& p = v.positions->back();
        if (p.y() < lowest) lowest = p.y();
        max_tension = std::max(max_tension, (*v.tension)[0]);
    }
    EXPECT_NEAR(lowest, -L, 2e-3);
    const double string_weight = ropeMass(d, L) * kG;
    EXPECT_NEAR(max_tension, bob * kG * (3.0 - 2.0 * std::cos(a)) + string_weight, 0.05 * 2.0 * bob * kG);
}

// Clamped at both ends (Strings Sec. 5.2, case 2): a rope sagging between two pins comes
// to rest with every segment within its limit, and the vertical components of the two
// end tensions carry its whole weight (statics) within 2%.
TEST(Chain, BothEndsClampedCarriesItsWeight) {
    World world;
    // 1.2 m of rope between pins 1 m apart: it hangs in a catenary.
    StringDesc d = rope({0, 0, 0}, {1.2, 0, 0}, 60);
    d.damping = 2.0;
    const StringId id = world.addString(d);
    world.attachToPoint(id, 0, {0, 0, 0});
    world.attachToPoint(id, -1, {1.0, 0, 0});
    for (int i = 0; i < 3000; ++i) world.step(0.01);
    const auto v = world.view(id);
    for (std::size_t j = 0; j < v.segmentCount(); ++j)
        EXPECT_LT(((*v.positions)[j + 1] - (*v.positions)[j]).norm(), (*v.rest_length)[j] * (1 + 1e-3));
    const auto& x = *v.positions;
    const std::size_t m = v.segmentCount();
    // The pins hold the rope up along its end segments.
    const Vec3 e0 = (x[0] - x[1]).normalized();
    const Vec3 e1 = (x[m] - x[m - 1]).normalized();
    const double vertical = (*v.tension)[0] * e0.y() + (*v.tension)[m - 1] * e1.y();
    double weight = 0.0;
    for (std::size_t p = 1; p < m; ++p) weight += (*v.masses)[p] * kG;
    EXPECT_NEAR(vertical, weight, 0.02 * weight);
    // At rest: the solve has converged (no jitter left).
    for (const Vec3& u : *v.velocities) EXPECT_LT(u.norm(), 1e-6);
    // Symmetric sag: the middle is the lowest point and below the pins.
    EXPECT_LT(x[m / 2].y(), -0.2);
}

// Clamped at several points (case 3): pins at both ends and in the middle; each half
// hangs on its own and the middle pin's two segments split the load symmetrically.
TEST(Chain, SeveralClampsSplitTheString) {
    World world;
    StringDesc d = rope({0, 0, 0}, {2.4, 0, 0}, 40);
    d.damping = 2.0;
    const StringId id = world.addString(d);
    world.attachToPoint(id, 0, {0, 0, 0});
    world.attachToPoint(id, 20, {1.0, 0, 0});
    world.attachToPoint(id, -1, {2.0, 0, 0});
    for (int i = 0; i < 1500; ++i) world.step(0.01);
    const auto v = world.view(id);
    EXPECT_NEAR((*v.tension)[0], (*v.tension)[39], 0.02 * (*v.tension)[0]);
    EXPECT_NEAR((*v.tension)[19], (*v.tension)[20], 0.02 * (*v.tension)[19]);
    EXPECT_NEAR((*v.positions)[10].y(), (*v.positions)[30].y(), 1e-3);
    EXPECT_NEAR((*v.positions)[20].y(), 0.0, 1e-12);
}

// Momentum balance (Yarn) against the local estimate (Strings Eq. 12) on a rope at rest:
// the local estimate sees only this step's stretch, so below the clamped segment it
// reads almost nothing while the momentum solve reads the weight.
TEST(Chain, LocalEstimateMissesTheStaticLoadMomentumSeesIt) {
    auto run = [](tearables::TensionEstimator estimator) {
        World world;
        StringDesc d = rope({0, 1, 0}, {0, 0, 0}, 20);
        d.tension = estimator;
        const StringId id = world.addString(d);
        world.attachToPoint(id, 0, {0, 1, 0});
        for (int i = 0; i < 200; ++i) world.step(0.01);
        return *world.view(id).tension;
    };
    const auto momentum = run(tearables::TensionEstimator::Momentum);
    const auto local = run(tearables::TensionEstimator::Local);
    EXPECT_GT(momentum[10], 0.3 * momentum[0]);
    EXPECT_LT(std::abs(local[10]), 0.01 * momentum[10]);
    // At the clamp the local estimate sees one particle's fall only, not the rope's weight.
    EXPECT_LT(local[0], 0.2 * momentum[0]);
}

// A rope under a load that ramps up slowly tears when the load reaches
// sigma_rupture * pi r^2 within 5%, and only one segment tears.
TEST(Chain, RampedLoadTearsAtRuptureStress) {
    World world;
    StringDesc d = rope({0, 1, 0}, {0, 0, 0}, 20);
    d.radius = 0.001;
    d.material.tensile.rupture = 8e7;  // 251 N on 1 mm radius
    const StringId id = world.addString(d);
    world.attachToPoint(id, 0, {0, 1, 0});
    const double rate = 50.0;  // N/s
    double load_at_tear = -1.0;
    int tears = 0;
    for (int i = 0; i < 2000 && tears == 0; ++i) {
        const double load = rate * i * 0.01;
        world.applyForce(id, -1, {0, -load, 0});
        world.step(0.01);
        for (const auto& e : world.events())
            if (e.type == tearables::EventType::Tear) {
                ++tears;
                load_at_tear = load;
                EXPECT_EQ(e.cause, tearables::EventCause::Tension);
            }
    }
    const double expected = 8e7 * kPi * 1e-6;
    ASSERT_EQ(tears, 1);
    // The tear happens where stress is highest: the top segment carries load + weight.
    EXPECT_NEAR(load_at_tear, expected, 0.05 * expected);
    const auto v = world.view(id);
    EXPECT_EQ((*v.broken)[0], 1);
}

// Bad input to the step and to the setters changes nothing and the world steps on.
TEST(Chain, NonFiniteInputIsRefusedAndTheWorldStepsOn) {
    World world;
    const StringId id = world.addString(rope({0, 1, 0}, {0, 0, 0}, 10));
    world.attachToPoint(id, 0, {0, 1, 0});
    EXPECT_THROW(world.applyForce(id, -1, {std::nan(""), 0, 0}), tearables::InvalidInput);
    EXPECT_THROW(world.applyForce(id, 11, {0, 1, 0}), tearables::InvalidInput);
    EXPECT_THROW(world.attachToPoint(id, 3, {0, INFINITY, 0}), tearables::InvalidInput);
    EXPECT_THROW(world.step(std::nan("")), tearables::InvalidInput);
    EXPECT_THROW(world.step(-0.01), tearables::InvalidInput);
    EXPECT_EQ(world.stepCount(), 0);
    for (int i = 0; i < 10; ++i) world.step(0.01);
    for (const Vec3& p : *world.view(id).positions) EXPECT_TRUE(p.allFinite());
}

// CSM bending (Strings Sec. 3): a horizontal cantilever sags less with a larger region
// half-width, monotonically, and with bending off it hangs straight down.
TEST(Chain, CantileverSagsLessWithWiderShapeMatchingRegions) {
    auto tip_sag = [](int w, double bending) {
        World world;
        StringDesc d = StringDesc::straight({0, 0, 0}, {0.3, 0, 0}, 30);
        d.material.variation = 0.0;
        d.csm_half_width = w;
        d.bending = bending;
        d.damping = 2.0;
        const StringId id = world.addString(d);
        world.attachToPoint(id, 0, d.points[0]);  // two pins clamp position and direction
        world.attachToPoint(id, 1, d.points[1]);
        for (int i = 0; i < 600; ++i) world.step(0.01);
        return -world.view(id).positions->back().y();
    };
    double previous = 1e9;
    for (int w = 1; w <= 8; ++w) {
        const double sag = tip_sag(w, 1.0);
        EXPECT_GT(sag, 0.0) << w;
        EXPECT_LT(sag, previous) << "w = " << w;
        previous = sag;
    }
    EXPECT_GT(tip_sag(2, 0.0), 0.28);  // no bending: hangs (nearly) straight down
}

// A string driven to a non-finite state by a user's force is frozen with an event that says
// why; another string in the same world goes on unharmed.
TEST(Chain, NonFiniteStateFreezesThatStringOnly) {
    World world;
    const StringId wild = world.addString(rope({0, 1, 0}, {0, 0, 0}, 10));
    const StringId calm = world.addString(rope({1, 1, 0}, {1, 0, 0}, 10));
    world.attachToPoint(wild, 0, {0, 1, 0});
    world.attachToPoint(calm, 0, {1, 1, 0});
    world.applyForce(wild, -1, {1e308, 1e308, 0});  // finite, but it overflows in the step
    world.step(0.01);
    bool frozen_event = false;
    for (const auto& e : world.events())
        frozen_event = frozen_event || (e.type == tearables::EventType::Freeze && e.string == wild &&
                                        e.cause == tearables::EventCause::NonFinite);
    EXPECT_TRUE(frozen_event);
    EXPECT_TRUE(world.view(wild).frozen);
    for (int i = 0; i < 100; ++i) world.step(0.01);
    for (const Vec3& p : *world.view(wild).positions) EXPECT_TRUE(p.allFinite());
    for (const Vec3& p : *world.view(calm).positions) EXPECT_TRUE(p.allFinite());
    const auto v = world.view(calm);
    double below = 0.0;  // everything but the pinned particle hangs on the first segment
    for (std::size_t p = 1; p < v.particleCount(); ++p) below += (*v.masses)[p] * kG;
    EXPECT_NEAR(v.tension->front(), below, 0.02 * below);
}

// The chain solve converges within its default budget: stepping with the default number of
// Newton iterations gives what stepping with the most (64) gives, to the solve's tolerance,
// for a rope swinging down with a heavy tip (Strings' Table 1 setting) and for a sagging
// rope between two pins settling into a catenary, whose segments go slack and taut. Before
// the Hessian's geometric term took the linearised tension (strain_limit.cpp), a
// catenary at rest stopped unconverged at the budget (8) in every step: it needed ~11.
TEST(Chain, SolveConvergesWithinItsDefaultBudget) {
    struct Case {
        int segments;
        double length, span, tip;
        int steps;
    };
    for (const Case& c : {Case{100, 1.0, 0.0, 10.0, 150}, Case{60, 1.2, 1.0, 0.0, 1000}}) {
        auto run = [&](int iterations) {
            tearables::WorldSettings settings;
            settings.strain_iterations = iterations;
            World world(settings);
            StringDesc d = rope({0, 0, 0}, {c.length, 0, 0}, c.segments);
            d.damping = 2.0;
            if (c.span > 0.0) {  // hung as a V between the pins (no self-contact on the way)
                const double depth = std::sqrt(0.25 * (c.length * c.length - c.span * c.span));
                for (int i = 0; i <= c.segments; ++i) {
                    const double t = 2.0 * i / c.segments;  // 0..2 along the two arms
                    const double arm = t <= 1.0 ? t : 2.0 - t;
                    d.points[static_cast<std::size_t>(i)] = Vec3(0.5 * c.span * t, -depth * arm, 0.0);
                }
            }
            if (c.tip > 0.0) d.particle_masses = {{-1, c.tip * ropeMass(d, c.length)}};
            const StringId id = world.addString(d);
            world.attachToPoint(id, 0, {0, 0, 0});
            if (c.span > 0.0) world.attachToPoint(id, -1, {c.span, 0, 0});
            for (int i = 0; i < c.steps; ++i) world.step(0.01);
            return *world.view(id).positions;
        };
        const auto budget = run(tearables::WorldSettings{}.strain_iterations);
        const auto converged = run(64);
        double worst = 0.0;
        for (std::size_t i = 0; i < budget.size(); ++i) worst = std::max(worst, (budget[i] - converged[i]).norm());
        EXPECT_LT(worst, 1e-6) << c.segments << " segments";
    }
}

// The warm start of the strain solve (strain_limit.cpp, warmStart) moves where Newton's
// iterations begin, not where they end: a rope hanging still, one swinging down from the
// horizontal, and one whose 45 N pull is let go of (where the last step's correction
// would throw the tip up by the pull's h^2 / m: the start is refused, and without that
// test the tip ended 0.2 m away) follow the same path within the solver's tolerance with
// the warm start as without. The rope at rest converges in one iteration a step instead
// of two.
TEST(Chain, WarmStartChangesTheIterationsNotTheMotion) {
    enum Case { kHanging, kSwinging, kReleased };
    for (const Case c : {kHanging, kSwinging, kReleased}) {
        World worlds[2];
        StringId ids[2];
        for (int w = 0; w < 2; ++w) {
            tearables::detail::WorldAccess::setColdStrainStarts(worlds[w], w == 1);
            StringDesc d = rope({0, 0, 0}, c == kSwinging ? Vec3(1, 0, 0) : Vec3(0, -1, 0), 100);
            d.tearable = false;
            d.particle_masses = {{-1, 10.0 * ropeMass(d, 1.0)}};
            ids[w] = worlds[w].addString(d);
            worlds[w].attachToPoint(ids[w], 0, {0, 0, 0});
        }
        long iterations[2] = {0, 0};
        double apart = 0.0;
        for (int step = 0; step < 300; ++step) {
            for (int w = 0; w < 2; ++w) {
                if (c == kReleased && step < 100) worlds[w].applyForce(ids[w], -1, {0, -45.0, 0});
                worlds[w].step(0.01);
                const auto& s = (*tearables::detail::WorldAccess::parts(worlds[w]).strings)[0];
                iterations[w] += s.diagnostics.strain_newton_iterations;
            }
            const auto& warm = *worlds[0].view(ids[0]).positions;
            const auto& cold = *worlds[1].view(ids[1]).positions;
            for (std::size_t i = 0; i < warm.size(); ++i) apart = std::max(apart, (warm[i] - cold[i]).norm());
        }
        EXPECT_LT(apart, 1e-5) << "case " << c;
        if (c == kHanging) EXPECT_LT(iterations[0], 0.6 * static_cast<double>(iterations[1]));
        // A rope swinging fast gains nothing from the warm start; it must not lose much.
        EXPECT_LT(iterations[0], 1.2 * static_cast<double>(iterations[1])) << "case " << c;
    }
}

// Chord iterations (strain_limit.cpp: a step solved again with the last factorisation)
// change what an iteration costs, not where the solve ends: a rope with a heavy tip
// swinging down from the horizontal (Strings' Table 1 setting), and a sagging rope
// between two pins settling into a catenary (its segments go slack and taut, where a
// chord iteration is refused), follow the path of Newton-only solves within the solver's
// tolerance, and make fewer factorisations once past their first swing or sag (steps
// 150-300; measured: 0.84 and 0.63 of the Newton-only solves').
TEST(Chain, ChordIterationsChangeTheCostNotTheMotion) {
    for (const bool catenary : {false, true}) {
        World worlds[2];
        StringId ids[2];
        for (int w = 0; w < 2; ++w) {
            tearables::detail::WorldAccess::setNewtonStrainOnly(worlds[w], w == 1);
            StringDesc d = rope({0, 0, 0}, {1, 0, 0}, 100);
            d.tearable = false;
            if (catenary) {
                for (int i = 0; i <= 100; ++i) {
                    const double t = 2.0 * i / 100;  // a V between pins 0.8 m apart
                    d.points[static_cast<std::size_t>(i)] = Vec3(0.4 * t, -0.3 * (t <= 1.0 ? t : 2.0 - t), 0.0);
                }
            } else {
                d.particle_masses = {{-1, 10.0 * ropeMass(d, 1.0)}};
            }
            ids[w] = worlds[w].addString(d);
            worlds[w].attachToPoint(ids[w], 0, {0, 0, 0});
            if (catenary) worlds[w].attachToPoint(ids[w], -1, {0.8, 0, 0});
        }
        long factorisations[2] = {0, 0}, chords = 0;  // factorisations from step 150
        double apart = 0.0;
        for (int step = 0; step < 300; ++step) {
            for (int w = 0; w < 2; ++w) {
                worlds[w].step(0.01);
                const auto& s = (*tearables::detail::WorldAccess::parts(worlds[w]).strings)[0];
                if (step >= 150)
                    factorisations[w] += s.diagnostics.strain_newton_iterations - s.diagnostics.strain_chord_iterations;
                if (w == 0) chords += s.diagnostics.strain_chord_iterations;
            }
            const auto& a = *worlds[0].view(ids[0]).positions;
            const auto& b = *worlds[1].view(ids[1]).positions;
            for (std::size_t i = 0; i < a.size(); ++i) apart = std::max(apart, (a[i] - b[i]).norm());
        }
        EXPECT_LT(apart, 1e-5) << (catenary ? "catenary" : "swinging");
        EXPECT_GT(chords, 0) << (catenary ? "catenary" : "swinging");
        EXPECT_LT(factorisations[0], 0.9 * static_cast<double>(factorisations[1])) << (catenary ? "catenary" : "swinging");
    }
}
