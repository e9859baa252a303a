// Islands: strings coupled through the movable bodies they hold are solved as one system
// with those bodies (src/island/). Checked against statics: a structure at rest carries
// exactly its weight at its anchors, and every island's solve converges each step.
#include "tearables/bullet_core.hpp"

#include "benchmarks/island_scenes.hpp"
#include "bullet_fixture.hpp"

#include <btBulletDynamicsCommon.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace {

using tearables::BulletWorld;
using tearables::IslandSummary;
using tearables::StringDesc;
using tearables::StringId;
using tearables::Vec3;
using tearables::testing::Physics;

constexpr double kG = 9.81;
constexpr double kPi = 3.14159265358979323846;

StringDesc rope(const Vec3& from, const Vec3& to, int segments) { return tearables::testing::plainRope(from, to, segments); }

double ropeMass(const StringDesc& d, double length) { return d.density * kPi * d.radius * d.radius * length; }

/// The total momentum of the bodies (Bullet's m v) and of string `id`'s particles, N s.
Vec3 totalMomentum(const std::vector<btRigidBody*>& bodies, const BulletWorld& ropes, StringId id) {
    Vec3 p = Vec3::Zero();
    for (const btRigidBody* b : bodies) p += tearables::toCore(b->getLinearVelocity()) / static_cast<double>(b->getInvMass());
    const auto v = ropes.core().view(id);
    for (std::size_t i = 0; i < v.particleCount(); ++i) p += (*v.masses)[i] * (*v.velocities)[i];
    return p;
}

/// Two boards hung one below the other: two ropes from the anchors to the upper board,
/// two from the upper board to the lower one. Returns the total mass hung.
struct TwoBoards {
    Physics phys;
    btRigidBody* upper = nullptr;
    btRigidBody* lower = nullptr;
    BulletWorld ropes;
    StringId top[2], bottom[2];
    double mass = 0.0;
    explicit TwoBoards(double x0)
        : upper(&phys.box(btVector3(0.5f, 0.02f, 0.1f), 6.0, btVector3(static_cast<btScalar>(x0), 1.0f, 0))),
          lower(&phys.box(btVector3(0.5f, 0.02f, 0.1f), 3.0, btVector3(static_cast<btScalar>(x0), 0.5f, 0))),
          ropes(*phys.world) {
        mass = 9.0;
        for (int side = 0; side < 2; ++side) {
            const double x = x0 + (side == 0 ? -0.4 : 0.4);
            const StringDesc t = rope({x, 2.0, 0}, {x, 1.02, 0}, 40);
            top[side] = ropes.addString(t);
            ropes.attach(top[side], 0, btVector3(static_cast<btScalar>(x), 2.0f, 0));
            ropes.attach(top[side], -1, *upper, btVector3(static_cast<btScalar>(x - x0), 0.02f, 0));
            const StringDesc b = rope({x, 0.98, 0}, {x, 0.52, 0}, 20);
            bottom[side] = ropes.addString(b);
            ropes.attach(bottom[side], 0, *upper, btVector3(static_cast<btScalar>(x - x0), -0.02f, 0));
            ropes.attach(bottom[side], -1, *lower, btVector3(static_cast<btScalar>(x - x0), 0.02f, 0));
            mass += ropeMass(t, 0.98) + ropeMass(b, 0.46);
        }
    }
};

}  // namespace

// Four ropes and two boards are one island, and its solve converges every step (where
// the strings' sweeps over shared bodies left millimetres). At rest the anchors carry the
// whole weight: the two top segments' tensions add up to m g within 0.5% (the tension
// solve's regularisation biases it by ~1e-6 per segment).
TEST(Islands, RopesSharingBoardsAreOneConvergedIsland) {
    TwoBoards rig(0.0);
    double worst_residual = 0.0;
    for (int i = 0; i < 300; ++i) {
        rig.phys.step(1);
        const std::vector<IslandSummary>& islands = rig.ropes.core().lastIslands();
        ASSERT_EQ(islands.size(), 1u);
        EXPECT_EQ(islands[0].strings, 4u);
        EXPECT_EQ(islands[0].bodies, 2u);
        worst_residual = std::max(worst_residual, islands[0].residual);
    }
    EXPECT_LT(worst_residual, 1.0);
    double pull = 0.0;
    for (StringId id : rig.top) pull += rig.ropes.core().view(id).tension->front();
    EXPECT_NEAR(pull, rig.mass * kG, 0.005 * rig.mass * kG);
    EXPECT_LT(rig.lower->getLinearVelocity().length(), 1e-3f);
}

// Structures that share no body are separate islands; a rope pinned at both ends and
// touching nothing that moves is in none.
TEST(Islands, StructuresSharingNothingAreSeparateIslands) {
    TwoBoards rig(0.0);
    btRigidBody& board = rig.phys.box(btVector3(0.3f, 0.02f, 0.1f), 2.0, btVector3(3.0f, 1.0f, 0));
    for (double x : {2.8, 3.2}) {
        const StringId id = rig.ropes.addString(rope({x, 2.0, 0}, {x, 1.02, 0}, 30));
        rig.ropes.attach(id, 0, btVector3(static_cast<btScalar>(x), 2.0f, 0));
        rig.ropes.attach(id, -1, board, btVector3(static_cast<btScalar>(x - 3.0), 0.02f, 0));
    }
    const StringId pinned = rig.ropes.addString(rope({-3, 2, 0}, {-2, 2, 0}, 20));
    rig.ropes.attach(pinned, 0, btVector3(-3, 2, 0));
    rig.ropes.attach(pinned, -1, btVector3(-2, 2, 0));
    rig.phys.step(5);
    const std::vector<IslandSummary>& islands = rig.ropes.core().lastIslands();
    ASSERT_EQ(islands.size(), 2u);
    EXPECT_EQ(islands[0].strings + islands[1].strings, 6u);
    EXPECT_EQ(islands[0].bodies + islands[1].bodies, 3u);
    for (const IslandSummary& island : islands) EXPECT_LT(island.residual, 1.0);
}

// Momentum in an island: in zero gravity a heavy rope (1.6 kg, bending on) glued at its
// ends to two free 1 kg boxes, pushed sideways at its middle by F for 0.2 s, then left:
// the total momentum of rope and boxes is F t (the island's bodies take every reaction,
// shape matching's included). To rounding while the boxes barely turn (the first 0.3 s);
// over 1 s, as they spin, within 0.5%: a held point's turn is linearised within each
// Newton iteration, which leaks m_p theta^2 r / (2 h) of its particle's momentum.
TEST(Islands, HeavyRopeBetweenFreeBodiesKeepsTheImpulseItWasGiven) {
    Physics phys(0.0);
    tearables::WorldSettings settings;
    settings.string_collisions = false;  // the string-pair solve holds bodies still (README)
    BulletWorld ropes(*phys.world, settings);
    StringDesc d = StringDesc::straight({-0.5, 0, 0}, {0.5, 0, 0}, 40);
    d.radius = 0.005;
    d.density = 20000.0;
    d.tearable = false;
    d.material.variation = 0.0;
    const StringId id = ropes.addString(d);
    btRigidBody* ends[2];
    for (int end : {0, 1}) {
        const double x = end == 0 ? -0.56 : 0.56;
        ends[end] = &phys.box(btVector3(0.05f, 0.05f, 0.05f), 1.0, btVector3(static_cast<btScalar>(x), 0, 0));
        ends[end]->setActivationState(DISABLE_DEACTIVATION);
        ropes.attach(id, end == 0 ? 0 : -1, *ends[end], btVector3(static_cast<btScalar>(end == 0 ? 0.06 : -0.06), 0, 0));
    }
    const double force = 20.0, dt = 0.01;
    auto momentum = [&] { return totalMomentum({ends[0], ends[1]}, ropes, id); };
    double worst = 0.0, early = 0.0;
    for (int i = 0; i < 100; ++i) {
        if (i < 20) ropes.applyForce(id, 20, btVector3(0, static_cast<btScalar>(force), 0));
        phys.step(1, dt);
        const Vec3 expected(0.0, force * dt * std::min(i + 1, 20), 0.0);
        const double error = (momentum() - expected).norm() / (force * dt * 20);
        worst = std::max(worst, error);
        if (i < 30) early = std::max(early, error);
    }
    EXPECT_LT(early, 1e-6);
    EXPECT_LT(worst, 5e-3);
}

// Two 1 kg, 0.1 m boxes joined by a slack rope arched over them (so both move in the
// island), no gravity, thrown at each other at 6, 12 and 20 m/s (10-33 cm a 1/60 s step,
// up to three times their width): they meet and stop face to face, and never pass or
// sink into each other. The contacts give under the force that stops them within a step,
// F = m v / h (up to 600 N), by F / k with k = 100 m / h^2 (3.6e5 N/m): under 2 mm, so
// their centres stay 0.1 m apart to 3 mm. All forces are internal: the total momentum,
// zero, stays so to the solve's tolerance, a move of 1e-6 of the 6.3 cm segments: at most
// 2 kg x 63 nm / h = 7.6e-6 N s a step, 3e-4 N s over the 40 steps. Bullet's first
// manifold of two boxes meeting is often one edge, and the boxes are apart a step before
// they meet: this needs their corners and speculative contacts (docs/island-plan.md).
TEST(Islands, BoxesThrownAtEachOtherMeetAndStop) {
    for (double v : {3.0, 6.0, 10.0}) {
        Physics p(0.0);
        // The slack rope folds onto itself as the boxes meet; string-string contacts are
        // solved after the island with its bodies held, which leaks momentum (README,
        // known limits), so they are off here: this is about the boxes.
        tearables::WorldSettings settings;
        settings.string_collisions = false;
        BulletWorld ropes(*p.world, settings);
        const tearables::island::ClosingBoxes boxes = tearables::island::buildClosingBoxes(p, ropes, v);
        btRigidBody &a = *boxes.a, &b = *boxes.b;
        const StringId id = boxes.rope;
        double closest = 1e300, drift = 0.0;
        for (int i = 0; i < 40; ++i) {
            p.step(1, 1.0 / 60.0);
            closest = std::min(closest, static_cast<double>(b.getCenterOfMassPosition().x() - a.getCenterOfMassPosition().x()));
            drift = std::max(drift, totalMomentum({&a, &b}, ropes, id).norm());
        }
        ASSERT_TRUE(ropes.lastError().empty()) << ropes.lastError();
        EXPECT_GT(closest, 0.1 - 3e-3) << "at " << v << " m/s each";
        EXPECT_LT(drift, 3e-4) << "at " << v << " m/s each";
    }
}

// A 2 kg box thrown at 4 m/s, in zero gravity, onto a rope glued at its ends to two free
// 1 kg boxes: the box presses and drags the rope (friction rolls and twists it), and
// every force between box, rope and end boxes is internal, so the total momentum stays
// 8 N s. A solve stopped at its tolerance (a move of strain_tolerance times the shortest
// segment, 1e-6 x 25 mm) leaves at most sum(m) dx / h = 4.1 kg x 25 nm / 0.01 s = 1e-5 N s
// a step: over 100 steps 1.3e-4 of 8 N s. The twist forces and the contacts the
// step runs into once leaked 0.1-0.6% here.
TEST(Islands, BoxThrownAtARopeBetweenFreeBodiesKeepsItsMomentum) {
    for (const double density : {1150.0, 20000.0}) {
        Physics phys(0.0);
        BulletWorld ropes(*phys.world);
        StringDesc d = StringDesc::straight({-0.5, 0, 0}, {0.5, 0, 0}, 40);
        d.radius = 0.005;
        d.density = density;
        d.tearable = false;
        d.material.variation = 0.0;
        const StringId id = ropes.addString(d);
        std::vector<btRigidBody*> bodies;
        for (int end : {0, 1}) {
            const double x = end == 0 ? -0.56 : 0.56;
            btRigidBody& b = phys.box(btVector3(0.05f, 0.05f, 0.05f), 1.0, btVector3(static_cast<btScalar>(x), 0, 0));
            b.setActivationState(DISABLE_DEACTIVATION);
            ropes.attach(id, end == 0 ? 0 : -1, b, btVector3(static_cast<btScalar>(end == 0 ? 0.06 : -0.06), 0, 0));
            bodies.push_back(&b);
        }
        btRigidBody& thrown = phys.box(btVector3(0.1f, 0.1f, 0.1f), 2.0, btVector3(0.02f, 0.3f, 0));
        thrown.setLinearVelocity(btVector3(0, -4, 0));
        thrown.setActivationState(DISABLE_DEACTIVATION);
        bodies.push_back(&thrown);
        auto momentum = [&] { return totalMomentum(bodies, ropes, id); };
        const Vec3 p0 = momentum();
        double drift = 0.0, touching = 0.0;
        for (int i = 0; i < 100; ++i) {
            phys.step(1, 0.01);
            drift = std::max(drift, (momentum() - p0).norm() / p0.norm());
            for (const IslandSummary& island : ropes.core().lastIslands()) touching = std::max(touching, static_cast<double>(island.bodies));
        }
        EXPECT_EQ(touching, 3.0) << "the box reached the rope (density " << density << ")";
        EXPECT_LT(drift, 1.3e-4) << "density " << density;
    }
}

// The rig above with a second such rope across the first, 12 mm below it (a 2 mm gap),
// held by two free boxes of its own: the thrown box presses the first rope onto the second,
// so the momentum passes through the contacts between the strings as well as through the
// bodies. The strings' contacts are solved in the island with the bodies
// (ClusterIslandMember), so every force is internal and the bound is the solve's
// tolerance, as above (6.1 kg, 100 steps: 1.3e-4 of these throws' momentum at 0.5 m/s
// and less above). With the bodies held still in the strings' joint solve, 4.2% and 2.9%
// of it leaked. (Faster throws still take the held solve in the steps where the
// island's solve with the strings' contacts does not converge: docs/island-plan.md.)
TEST(Islands, BoxPressingARopeOntoACrossingRopeKeepsItsMomentum) {
    for (const double speed : {0.5, 1.5}) {
        Physics phys(0.0);
        tearables::WorldSettings settings;
        settings.island_string_contacts = true;
        BulletWorld ropes(*phys.world, settings);
        std::vector<btRigidBody*> bodies;
        std::vector<StringId> ids;
        auto holdRope = [&](const Vec3& from, const Vec3& to) {
            ids.push_back(tearables::island::ropeHeldByBoxes(phys, ropes, from, to, StringDesc{}.density, bodies));
        };
        holdRope({-0.5, 0, 0}, {0.5, 0, 0});
        holdRope({0, -0.012, -0.5}, {0, -0.012, 0.5});
        btRigidBody& thrown = phys.box(btVector3(0.1f, 0.1f, 0.1f), 2.0, btVector3(0.02f, 0.3f, 0));
        thrown.setLinearVelocity(btVector3(0, static_cast<btScalar>(-speed), 0));
        thrown.setActivationState(DISABLE_DEACTIVATION);
        bodies.push_back(&thrown);
        auto momentum = [&] {
            Vec3 p = Vec3::Zero();
            for (const StringId id : ids) p += totalMomentum(id == ids[0] ? bodies : std::vector<btRigidBody*>{}, ropes, id);
            return p;
        };
        const Vec3 p0 = momentum();
        double drift = 0.0;
        for (int i = 0; i < 100; ++i) {
            phys.step(1, 0.01);
            drift = std::max(drift, (momentum() - p0).norm() / p0.norm());
        }
        // The lower rope and its boxes got their momentum only through the upper rope's
        // contacts with it (without them it would pass through, untouched): over the
        // second they take up a share of it (12% at 1.5 m/s), on their way to the third
        // of it their mass (2.09 of 6.18 kg) has once everything moves together.
        const Vec3 lower = totalMomentum({bodies[2], bodies[3]}, ropes, ids[1]);
        EXPECT_GT(lower.dot(p0) / p0.squaredNorm(), 0.05) << "speed " << speed;
        EXPECT_LT(drift, 1.3e-4) << "speed " << speed;
    }
}

// The end of a rope squeezed between the box it is glued to and a box thrown at it, in zero
// gravity: a rope of 20 segments of 25 mm glued by its first particle to the middle of a free
// 1 kg box's bottom face and lying along that face, a 2 kg box thrown up at 2 m/s onto that
// face, under the glue point. The thrown box presses the rope's first segment, whose glued
// end moves with the held box: that end's share of the contact force is the held box's, so
// the total momentum stays 4 N s (where the share acted on no body, the thrown box bounced
// back off the rope at once, 150% off). A solve stopped at its tolerance (a move of
// strain_tolerance times the shortest segment) leaves at most sum(m) dx / h a step (the
// momentum test above), over the run's steps.
TEST(Islands, BoxThrownOntoARopesGluedEndKeepsItsMomentum) {
    for (const double density : {1150.0, 20000.0}) {
        Physics phys(0.0);
        BulletWorld ropes(*phys.world);
        StringDesc d = StringDesc::straight({0, -0.055, 0}, {0.5, -0.055, 0}, 20);
        d.radius = 0.005;
        d.density = density;
        d.tearable = false;
        d.material.variation = 0.0;
        const StringId id = ropes.addString(d);
        btRigidBody& held = phys.box(btVector3(0.05f, 0.05f, 0.05f), 1.0, btVector3(0, 0, 0));
        held.setActivationState(DISABLE_DEACTIVATION);
        ropes.attach(id, 0, held, btVector3(0, -0.05f, 0));
        btRigidBody& thrown = phys.box(btVector3(0.1f, 0.1f, 0.1f), 2.0, btVector3(0, -0.3f, 0));
        thrown.setLinearVelocity(btVector3(0, 2, 0));
        thrown.setActivationState(DISABLE_DEACTIVATION);
        const std::vector<btRigidBody*> bodies{&held, &thrown};
        auto momentum = [&] { return totalMomentum(bodies, ropes, id); };
        double mass = 3.0;
        for (double m : *ropes.core().view(id).masses) mass += m;
        const Vec3 p0 = momentum();
        const int steps = 60;
        const double h = 0.01, tolerance = ropes.core().settings().strain_tolerance * 0.025;
        const double bound = steps * mass * tolerance / h / p0.norm();
        double drift = 0.0;
        bool squeezed = false;
        for (int i = 0; i < steps; ++i) {
            phys.step(1, h);
            ASSERT_TRUE(ropes.lastError().empty()) << ropes.lastError();
            drift = std::max(drift, (momentum() - p0).norm() / p0.norm());
            // The rope's glued segment touched (only the thrown box can touch it) while the
            // two boxes met.
            const auto& touching = ropes.core().lastContacts();
            squeezed = squeezed || (!ropes.core().lastBodyContacts().empty() &&
                                    std::any_of(touching.begin(), touching.end(),
                                                [](const tearables::RigidContact& c) { return c.segment == 0; }));
        }
        EXPECT_TRUE(squeezed) << "the glued segment was between the boxes (density " << density << ")";
        EXPECT_GT(held.getLinearVelocity().y(), 0.5f) << "the held box was pushed away (density " << density << ")";
        EXPECT_LT(drift, bound) << "density " << density;
    }
}

// A crate 20x heavier than the board it rests on, the board hung on two ropes. Bullet's
// solver alone pushed the board from under the crate and the ropes lifted it back into
// it, step after step: a 10 kg crate went through a 3 kg board within 0.25 s. Taken from
// Bullet with their contacts into the ropes' island, the crate rests on the board: its
// centre stays within 2 mm (the bound) of where it rests on the board's top face
// (the contacts' penalty sinks it by g h^2 / 100, 0.01 mm here), and the statics add up:
// the contacts carry the crate's weight and the anchors the whole weight, each within 0.5%
// (the tension solve's regularisation biases it by ~1e-6 a segment).
TEST(Islands, HeavyCrateRestsOnALightRopedBoard) {
    const double board_mass = 1.5, crate_mass = 30.0, board_half = 0.015, crate_half = 0.1;
    Physics phys;
    btRigidBody& board = phys.box(btVector3(0.5f, static_cast<btScalar>(board_half), 0.15f), board_mass, btVector3(0, 1.0f, 0));
    btRigidBody& crate = phys.box(btVector3(0.1f, 0.1f, 0.1f), crate_mass,
                                  btVector3(0, static_cast<btScalar>(1.0 + board_half + crate_half + 0.0005), 0));
    crate.setFriction(0.8f);
    board.setActivationState(DISABLE_DEACTIVATION);
    crate.setActivationState(DISABLE_DEACTIVATION);
    BulletWorld ropes(*phys.world);
    double mass = board_mass + crate_mass;
    StringId hang[2];
    for (int side = 0; side < 2; ++side) {
        const double x = side == 0 ? -0.4 : 0.4;
        const StringDesc d = rope({x, 2.0, 0}, {x, 1.0 + board_half, 0}, 40);
        hang[side] = ropes.addString(d);
        ropes.attach(hang[side], 0, btVector3(static_cast<btScalar>(x), 2.0f, 0));
        ropes.attach(hang[side], -1, board, btVector3(static_cast<btScalar>(x), static_cast<btScalar>(board_half), 0));
        mass += ropeMass(d, 1.0 - board_half);
    }
    double deepest = 0.0;
    for (int i = 0; i < 300; ++i) {
        phys.step(1);
        const btVector3 local = board.getWorldTransform().invXform(crate.getCenterOfMassPosition());
        deepest = std::max(deepest, (board_half + crate_half) - static_cast<double>(local.y()));
        ASSERT_LT(deepest, 0.002) << "step " << i;
    }
    double pull = 0.0;
    for (StringId id : hang) pull += ropes.core().view(id).tension->front();
    EXPECT_NEAR(pull, mass * kG, 0.005 * mass * kG);
    double carried = 0.0;
    for (const tearables::BodyContact& c : ropes.core().lastBodyContacts()) carried += c.force * std::abs(c.normal.y());
    EXPECT_NEAR(carried, crate_mass * kG, 0.005 * crate_mass * kG);
}

// The bridge's statics (the `bridge` scene's bridge: 8 boards of 4 kg on 18 ropes, 746
// segments), settled 1 s, then two 10 kg crates set down at rest on boards 3 and 4 and 3 s
// more. Over the last 0.5 s the four pinned ends pull up the weight of every particle,
// board and crate: each pinned particle's reaction is -T u_y + m g (T the end segment's
// tension, u its direction away from the pin), and their sum equals the total weight
// within 0.5% on average (issue 30's statics target), within 2% at every step while the
// crates' landing still rings. No rope tears and no crate falls through.
TEST(Islands, BridgeAnchorsCarryTheWholeWeightWithCratesOnIt) {
    tearables::island::Rig rig;
    const auto bridge = tearables::island::buildBridge(rig, {});
    for (auto* b : bridge.boards) b->setActivationState(DISABLE_DEACTIVATION);
    for (int i = 0; i < 100; ++i) rig.step();
    double weight = kG * bridge.board_mass * static_cast<double>(bridge.boards.size());
    for (StringId id : bridge.ropes) weight += kG * tearables::island::ropeMass(rig.ropes->core(), id);
    std::vector<btRigidBody*> crates;
    for (int board : {3, 4}) {
        const btTransform at = bridge.boards[static_cast<std::size_t>(board)]->getWorldTransform();
        btRigidBody& crate = rig.phys.box(btVector3(0.1f, 0.1f, 0.1f), 10.0,
                                          at.getOrigin() + at.getBasis().getColumn(1) * (0.04f + 0.1f + 0.0005f));
        crate.setWorldTransform(btTransform(at.getRotation(), crate.getWorldTransform().getOrigin()));
        crate.setFriction(0.8f);
        crate.setActivationState(DISABLE_DEACTIVATION);
        crates.push_back(&crate);
        weight += kG * 10.0;
    }
    const int steps = 300, window = 50;
    double sum = 0.0, worst = 0.0;
    for (int i = 1; i <= steps; ++i) {
        rig.step();
        if (i <= steps - window) continue;
        const double pull = tearables::island::anchorPull(rig.ropes->core(), bridge, kG);
        sum += pull / weight;
        worst = std::max(worst, std::abs(pull / weight - 1.0));
    }
    EXPECT_NEAR(sum / window, 1.0, 0.005);
    EXPECT_LT(worst, 0.02);
    for (const auto& e : rig.ropes->events()) EXPECT_NE(e.type, tearables::EventType::Tear);
    for (const btRigidBody* c : crates) EXPECT_GT(c->getCenterOfMassPosition().y(), 1.5f);
}

// Newton's convergence is quadratic in an island of boards hung on ropes: the Hessian
// holds the whole second-order turn of every held point, (F . r) I - (F r^T + r F^T) / 2 of
// its pull F at arm r, its negative part included where the body's inertia keeps the
// system positive definite. A step of the bridge at rest starts (warm) ~1e4 tolerances
// from its solution: quadratically that is 1e4, 1e2, 1, 1e-4, three or four iterations;
// with the negative part left out the moves shrink by a constant ~15x an iteration
// (measured), five iterations every step (1e4 / 15^4 > 1).
TEST(Islands, BridgeAtRestConvergesQuadratically) {
    tearables::island::Rig rig;
    const auto bridge = tearables::island::buildBridge(rig, {});
    for (auto* b : bridge.boards) b->setActivationState(DISABLE_DEACTIVATION);
    for (int i = 0; i < 100; ++i) rig.step();
    for (int i = 0; i < 20; ++i) {
        rig.step();
        const std::vector<IslandSummary>& islands = rig.ropes->core().lastIslands();
        ASSERT_EQ(islands.size(), 1u);
        EXPECT_EQ(islands[0].bodies, bridge.boards.size());
        EXPECT_LT(islands[0].residual, 1.0) << "step " << i;
        EXPECT_LE(islands[0].iterations, 4) << "step " << i;
    }
}

// Joints in an island: a drawbridge, a 3 kg board hinged to the world at one end and held
// level by a rope from above its other end, with a crate twenty times its mass on it; the
// hinge a btHingeConstraint (no limit, limits, or a weak motor), or two ball joints
// (btPoint2PointConstraint) at the ends of the same axis. The joints, the rope, the crate's contacts and the board are one
// island, so no solver undoes another: the crate rests on the board within 2 mm (where
// Bullet solved the joints and the crate, and the strings the rope, a 60 kg crate sank
// 65-106 mm into it), and the moments about the hinge's axis balance: the rope's pull at
// its end times its arm is g (m_board x_board + m_crate x_crate), with the arms where the
// bodies are (0.5%).
TEST(Islands, HingedBoardHeldByARopeCarriesAHeavyCrate) {
    for (const int kind : {0, 1, 2, 3}) {
        const bool balls = kind == 2;
        SCOPED_TRACE(kind == 0   ? "a hinge"
                     : kind == 1 ? "a hinge with limits it does not reach"
                     : kind == 2 ? "two ball joints"
                                 : "a hinge with a weak motor");
        Physics phys;
        btRigidBody& board = phys.box(btVector3(0.5f, 0.025f, 0.15f), 3.0, btVector3(0.5f, 1.0f, 0));
        board.setActivationState(DISABLE_DEACTIVATION);
        std::vector<std::unique_ptr<btTypedConstraint>> joints;
        if (balls) {
            for (float z : {-0.15f, 0.15f})
                joints.push_back(std::make_unique<btPoint2PointConstraint>(board, btVector3(-0.5f, 0, z)));
        } else {
            auto hinge = std::make_unique<btHingeConstraint>(board, btVector3(-0.5f, 0, 0), btVector3(0, 0, 1));
            if (kind == 1) hinge->setLimit(-1.0f, 1.0f);
            // A motor holding the board still with at most 0.1 N m, within the moments'
            // 0.5% (about 1.5 N m): the hinge stays the island's.
            if (kind == 3) hinge->enableAngularMotor(true, 0.0f, 1e-3f);
            joints.push_back(std::move(hinge));
        }
        for (auto& j : joints) phys.world->addConstraint(j.get(), true);
        BulletWorld ropes(*phys.world);
        const StringId id = ropes.addString(rope({0.95, 2.0, 0}, {0.95, 1.025, 0}, 40));
        ropes.attach(id, 0, btVector3(0.95f, 2.0f, 0));
        ropes.attach(id, -1, board, btVector3(0.45f, 0.025f, 0));
        btRigidBody& crate = phys.box(btVector3(0.1f, 0.1f, 0.1f), 60.0, btVector3(0.5f, 1.0f + 0.025f + 0.1f + 0.0005f, 0));
        crate.setActivationState(DISABLE_DEACTIVATION);
        double deepest = 0.0;
        for (int i = 0; i < 300; ++i) {
            phys.step(1);
            const btTransform b = board.getWorldTransform();
            // The crate's lowest corners, in the board's frame: above its top face (y = 0.025).
            for (float x : {-0.1f, 0.1f})
                for (float z : {-0.1f, 0.1f}) {
                    const btVector3 corner = crate.getWorldTransform() * btVector3(x, -0.1f, z);
                    deepest = std::max(deepest, 0.025 - static_cast<double>(b.invXform(corner).y()));
                }
            ASSERT_TRUE(ropes.lastError().empty()) << ropes.lastError();
        }
        EXPECT_LT(deepest, 0.002);
        // Moments about the hinge's axis (z through x = 0, y = 1).
        const auto view = ropes.core().view(id);
        const Vec3 end = view.positions->back(), below = (*view.positions)[view.positions->size() - 2];
        const Vec3 pull = view.tension->back() * (below - end).normalized();  // the rope's pull on the board
        const double turning = end.x() * pull.y() - (end.y() - 1.0) * pull.x();
        const double load = kG * (3.0 * static_cast<double>(board.getCenterOfMassPosition().x()) +
                                  60.0 * static_cast<double>(crate.getCenterOfMassPosition().x()));
        EXPECT_NEAR(turning, load, 0.005 * load);
        EXPECT_LT(crate.getLinearVelocity().length(), 1e-2f);
        for (auto& j : joints) phys.world->removeConstraint(j.get());
    }
}

// A hinge's limits are hard stops in the island: a 3 kg board hinged to the world at one
// end with limits of +-0.1 rad, a rope hanging from its free end (which puts it in an
// island), falls from level and comes to rest on the limit: turned by 0.1 rad, less the
// stop's give (its torque m g L/2 cos 0.1 over the penalty's 100 I / h^2: ~1e-4 rad).
TEST(Islands, HingeLimitStopsAFallingBoard) {
    Physics phys;
    btRigidBody& board = phys.box(btVector3(0.5f, 0.025f, 0.15f), 3.0, btVector3(0.5f, 1.0f, 0));
    board.setActivationState(DISABLE_DEACTIVATION);
    btHingeConstraint hinge(board, btVector3(-0.5f, 0, 0), btVector3(0, 0, 1));
    hinge.setLimit(-0.1f, 0.1f);
    phys.world->addConstraint(&hinge, true);
    BulletWorld ropes(*phys.world);
    const StringId id = ropes.addString(rope({0.95, 0.975, 0}, {0.95, 0.475, 0}, 20));
    ropes.attach(id, 0, board, btVector3(0.45f, -0.025f, 0));
    for (int i = 0; i < 200; ++i) phys.step(1);
    ASSERT_TRUE(ropes.lastError().empty()) << ropes.lastError();
    ASSERT_EQ(ropes.core().lastIslands().size(), 1u);
    // Turned down (clockwise about +z) by the limit.
    const btQuaternion q = board.getOrientation();
    const double turn = 2.0 * std::atan2(static_cast<double>(q.z()), static_cast<double>(q.w()));
    EXPECT_NEAR(turn, -0.1, 1e-3);
    EXPECT_LT(board.getAngularVelocity().length(), 1e-2f);
    // Its hinge end stayed on the hinge.
    const btVector3 pivot = board.getWorldTransform() * btVector3(-0.5f, 0, 0);
    EXPECT_LT(pivot.distance(btVector3(0, 1, 0)), 1e-3f);
    phys.world->removeConstraint(&hinge);
}

namespace {
/// A 3 kg board 1 m long hinged to the world at one end about z, level, its hinge's motor
/// driving it at `rate` (Bullet's target velocity) with at most `impulse` N m s a step of
/// 1/100 s, with a rope of 20 segments hanging from its free end (which puts it in an
/// island) or none (Bullet solves it). Returns the board's turn rate about z after `steps`.
double motorRun(double rate, double impulse, bool with_rope, int steps) {
    Physics phys;
    btRigidBody& board = phys.box(btVector3(0.5f, 0.025f, 0.15f), 3.0, btVector3(0.5f, 1.0f, 0));
    board.setActivationState(DISABLE_DEACTIVATION);
    btHingeConstraint hinge(board, btVector3(-0.5f, 0, 0), btVector3(0, 0, 1));
    hinge.enableAngularMotor(true, static_cast<btScalar>(rate), static_cast<btScalar>(impulse));
    phys.world->addConstraint(&hinge, true);
    BulletWorld ropes(*phys.world);
    if (with_rope) {
        const StringId id = ropes.addString(rope({0.95, 0.975, 0}, {0.95, 0.475, 0}, 20));
        ropes.attach(id, 0, board, btVector3(0.45f, -0.025f, 0));
    }
    for (int i = 0; i < steps; ++i) phys.step(1);
    EXPECT_TRUE(ropes.lastError().empty()) << ropes.lastError();
    EXPECT_EQ(ropes.core().lastIslands().size(), with_rope ? 1u : 0u);
    const btVector3 pivot = board.getWorldTransform() * btVector3(-0.5f, 0, 0);
    EXPECT_LT(pivot.distance(btVector3(0, 1, 0)), 2e-3f) << "the board's end left the hinge";
    phys.world->removeConstraint(&hinge);
    return static_cast<double>(board.getAngularVelocity().z());
}
}  // namespace

// A hinge's motor in an island drives the bodies' relative turn rate to its target, as
// Bullet's own solver does, with at most its impulse a step: a 3 kg board hinged at one end
// (gravity's torque about the hinge m g L / 2 = 14.7 N m, and the hanging rope's) is lifted
// at the motor's rate where the motor's largest torque (impulse / h) exceeds gravity's, and
// falls where it does not.
TEST(Islands, HingeMotorTurnsABoardAtItsRateUpToItsTorque) {
    const StringDesc hanging = rope({0.95, 0.975, 0}, {0.95, 0.475, 0}, 20);
    const double gravity_torque = kG * (3.0 * 0.5 + ropeMass(hanging, 0.5) * 0.95), h = 0.01;
    // Bullet alone, a strong motor: which way its target turns the board.
    const double bullet = motorRun(1.0, 10.0 * gravity_torque * h, false, 30);
    ASSERT_NEAR(std::abs(bullet), 1.0, 0.02);
    const double up = bullet > 0.0 ? 1.0 : -1.0;  // the target that lifts the board (turns it about +z)
    // In the island, the same motor: the same rate and direction, within the motor's give
    // (its torque over its stiffness, 1000 I / h^2 with I ~ 0.26 kg m^2: ~0.06% of the rate).
    EXPECT_NEAR(motorRun(1.0, 10.0 * gravity_torque * h, true, 30), bullet, 0.01);
    // Lifting, with 1.3 and 0.7 times gravity's torque at most: it rises at the target rate
    // (reached within about 0.3 s: 0.3 of gravity's torque left on ~1.1 kg m^2 about the
    // hinge, board and rope), or falls.
    EXPECT_NEAR(motorRun(up, 1.3 * gravity_torque * h, true, 60), 1.0, 0.01);
    EXPECT_LT(motorRun(up, 0.7 * gravity_torque * h, true, 30), -0.1);
}

namespace {
/// The joints of a body's frame joint to the world that the sliding tests build: a slider
/// (btSliderConstraint, its axis a frame's x), a 6-dof joint (btGeneric6DofConstraint) and
/// its successor (btGeneric6DofSpring2Constraint), one of whose subclasses is btFixedConstraint.
enum class Frame { Slider, SixDof, SixDofSpring2 };
const char* frameName(Frame f) { return f == Frame::Slider ? "slider" : f == Frame::SixDof ? "6-dof" : "6-dof spring 2"; }

/// A joint of `body` to the world at its local frame `frame`: free along the frame's
/// `axis` (0-2) within [lower, upper] (lower > upper: free), every other coordinate locked
/// (a slider: its x axis is the slide, so `frame` should carry x to the wanted axis).
std::unique_ptr<btTypedConstraint> slideJoint(Frame kind, btRigidBody& body, const btTransform& frame, int axis, btScalar lower,
                                              btScalar upper, bool reference_a = true) {
    if (kind == Frame::Slider) {
        auto slider = std::make_unique<btSliderConstraint>(body, frame, reference_a);
        slider->setLowerLinLimit(lower);
        slider->setUpperLinLimit(upper);
        slider->setLowerAngLimit(0);
        slider->setUpperAngLimit(0);
        return slider;
    }
    btVector3 lo(0, 0, 0), hi(0, 0, 0);
    lo[axis] = lower;
    hi[axis] = upper;
    if (kind == Frame::SixDof) {
        auto d6 = std::make_unique<btGeneric6DofConstraint>(body, frame, true);
        d6->setLinearLowerLimit(lo);
        d6->setLinearUpperLimit(hi);
        d6->setAngularLowerLimit(btVector3(0, 0, 0));
        d6->setAngularUpperLimit(btVector3(0, 0, 0));
        return d6;
    }
    auto d6 = std::make_unique<btGeneric6DofSpring2Constraint>(body, frame);
    d6->setLinearLowerLimit(lo);
    d6->setLinearUpperLimit(hi);
    d6->setAngularLowerLimit(btVector3(0, 0, 0));
    d6->setAngularUpperLimit(btVector3(0, 0, 0));
    return d6;
}

/// A slider's frame whose x axis (the slide) is the world's y.
btTransform upright() { return btTransform(btQuaternion(btVector3(0, 0, 1), static_cast<btScalar>(kPi / 2))); }
}  // namespace

// Sliders and 6-dof joints in an island: a 3 kg platform that slides up and down a
// vertical guide (a joint to the world, free along y only), held by a rope from above at
// its end, with a 60 kg crate on its middle. The guide carries no vertical force, so the
// rope's pull is the whole weight, 63 g (0.5%), while the guide's locked coordinates take
// the rope's off-centre moment (its joint feedback reports both); the crate rests on the
// platform within 2 mm, and the platform stays level within the angular locks' give (the
// moment, 150 N m, over 100 I / h^2: 1.5 mrad). Where Bullet
// solved the guide and the strings the rope, the two solvers fought over the platform.
// The same with a spring along the 6-dof spring-2 guide (at rest where the platform
// starts): the spring and the rope share the weight.
TEST(Islands, SlidingPlatformHeldByARopeCarriesAHeavyCrate) {
    for (const auto& [kind, sprung] : {std::pair{Frame::Slider, false}, std::pair{Frame::SixDof, false},
                                       std::pair{Frame::SixDofSpring2, false}, std::pair{Frame::SixDofSpring2, true}}) {
        SCOPED_TRACE(std::string(frameName(kind)) + (sprung ? " on a spring" : ""));
        Physics phys;
        btRigidBody& platform = phys.box(btVector3(0.3f, 0.025f, 0.2f), 3.0, btVector3(0, 1.0f, 0));
        platform.setActivationState(DISABLE_DEACTIVATION);
        auto guide = slideJoint(kind, platform, kind == Frame::Slider ? upright() : btTransform::getIdentity(), 1, 1, -1);
        if (sprung) {
            auto& d6 = static_cast<btGeneric6DofSpring2Constraint&>(*guide);
            d6.enableSpring(1, true);
            d6.setStiffness(1, 2000.0f);
            d6.setDamping(1, 100.0f);
            d6.setEquilibriumPoint(1, 0);
        }
        btJointFeedback feedback;
        guide->setJointFeedback(&feedback);
        guide->enableFeedback(true);
        phys.world->addConstraint(guide.get(), true);
        BulletWorld ropes(*phys.world);
        const StringId id = ropes.addString(rope({0.25, 2.0, 0}, {0.25, 1.025, 0}, 40));
        ropes.attach(id, 0, btVector3(0.25f, 2.0f, 0));
        ropes.attach(id, -1, platform, btVector3(0.25f, 0.025f, 0));
        btRigidBody& crate = phys.box(btVector3(0.1f, 0.1f, 0.1f), 60.0, btVector3(0, 1.0f + 0.025f + 0.1f + 0.0005f, 0));
        crate.setActivationState(DISABLE_DEACTIVATION);
        double deepest = 0.0;
        for (int i = 0; i < 300; ++i) {
            phys.step(1);
            const btTransform b = platform.getWorldTransform();
            for (float x : {-0.1f, 0.1f})
                for (float z : {-0.1f, 0.1f}) {
                    const btVector3 corner = crate.getWorldTransform() * btVector3(x, -0.1f, z);
                    deepest = std::max(deepest, 0.025 - static_cast<double>(b.invXform(corner).y()));
                }
            ASSERT_TRUE(ropes.lastError().empty()) << ropes.lastError();
        }
        ASSERT_EQ(ropes.core().lastBodyJoints().size(), 1u) << "the guide is the island's";
        EXPECT_LT(deepest, 0.002);
        const auto view = ropes.core().view(id);
        const Vec3 end = view.positions->back(), below = (*view.positions)[view.positions->size() - 2];
        const double pull = view.tension->back() * (below - end).normalized().y();
        // The guide's force on the platform (its B: the world is A) has no vertical part but
        // its spring's, k times the platform's drop (the crate's landing yields the rope by
        // some 10 cm; k is Bullet's limit of 2 kN/m for 3 kg at h = 1/100 s, 3 / (16 h^2)),
        // and the rope carries the rest of the weight; the guide's couple balances the pull's
        // moment about the platform's centre, 0.25 m from the rope (the crate's and the
        // platform's weights act at the centre).
        const double spring = sprung ? 3.0 / (16.0 * 0.01 * 0.01) * (1.0 - static_cast<double>(platform.getCenterOfMassPosition().y())) : 0.0;
        EXPECT_NEAR(pull, 63.0 * kG - spring, 0.005 * 63.0 * kG);
        EXPECT_NEAR(static_cast<double>(feedback.m_appliedForceBodyB.y()), spring, 0.005 * 63.0 * kG);
        EXPECT_NEAR(static_cast<double>(feedback.m_appliedTorqueBodyB.z()), -0.25 * pull, 0.01 * 0.25 * pull);
        EXPECT_LT(crate.getLinearVelocity().length(), 1e-2f);
        // The guide held the platform level and on its line.
        EXPECT_LT(platform.getWorldTransform().getBasis().getColumn(1).angle(btVector3(0, 1, 0)), 5e-3f);
        EXPECT_LT(std::hypot(static_cast<double>(platform.getCenterOfMassPosition().x()), static_cast<double>(platform.getCenterOfMassPosition().z())),
                  1e-3);
        phys.world->removeConstraint(guide.get());
    }
}

// A weld between two movable bodies (btFixedConstraint, a 6-dof joint with every
// coordinate locked): two 3 kg boards welded end to end, each hung by a rope at its outer
// end. The pair is one rigid beam, so by symmetry each rope carries half the weight, 3 g
// (0.5%), and the weld carries the bending moment (3 g times the 0.5 m from each board's
// centre to its rope, 14.7 N m): the beam stays straight within the locks' give (the
// moment over 100 I / h^2, I = 0.25 kg m^2 for a board: 6e-5 rad) and level.
TEST(Islands, WeldedBoardsHungAtTheirEndsAreOneBeam) {
    Physics phys;
    btRigidBody& left = phys.box(btVector3(0.5f, 0.025f, 0.15f), 3.0, btVector3(-0.5f, 1.0f, 0));
    btRigidBody& right = phys.box(btVector3(0.5f, 0.025f, 0.15f), 3.0, btVector3(0.5f, 1.0f, 0));
    for (btRigidBody* b : {&left, &right}) b->setActivationState(DISABLE_DEACTIVATION);
    btFixedConstraint weld(left, right, btTransform(btQuaternion::getIdentity(), btVector3(0.5f, 0, 0)),
                           btTransform(btQuaternion::getIdentity(), btVector3(-0.5f, 0, 0)));
    phys.world->addConstraint(&weld, true);
    BulletWorld ropes(*phys.world);
    StringId ids[2];
    for (int side = 0; side < 2; ++side) {
        const double x = side == 0 ? -0.95 : 0.95;
        ids[side] = ropes.addString(rope({x, 2.0, 0}, {x, 1.025, 0}, 40));
        ropes.attach(ids[side], 0, btVector3(static_cast<btScalar>(x), 2.0f, 0));
        ropes.attach(ids[side], -1, side == 0 ? left : right, btVector3(side == 0 ? -0.45f : 0.45f, 0.025f, 0));
    }
    for (int i = 0; i < 300; ++i) {
        phys.step(1);
        ASSERT_TRUE(ropes.lastError().empty()) << ropes.lastError();
    }
    ASSERT_EQ(ropes.core().lastBodyJoints().size(), 1u) << "the weld is the island's";
    ASSERT_EQ(ropes.core().lastIslands().size(), 1u);
    for (StringId id : ids) {
        const auto view = ropes.core().view(id);
        const Vec3 end = view.positions->back(), below = (*view.positions)[view.positions->size() - 2];
        EXPECT_NEAR(view.tension->back() * (below - end).normalized().y(), 3.0 * kG, 0.005 * 3.0 * kG);
    }
    const btVector3 xl = left.getWorldTransform().getBasis().getColumn(0), xr = right.getWorldTransform().getBasis().getColumn(0);
    EXPECT_LT(xl.angle(xr), 1e-3f) << "the weld bent";
    EXPECT_LT(xl.angle(btVector3(1, 0, 0)), 5e-3f) << "the beam tilted";
    const btVector3 ends[2] = {left.getWorldTransform() * btVector3(0.5f, 0, 0), right.getWorldTransform() * btVector3(-0.5f, 0, 0)};
    EXPECT_LT(ends[0].distance(ends[1]), 1e-3f) << "the weld parted";
    phys.world->removeConstraint(&weld);
}

namespace {
/// A 3 kg platform on a vertical guide (slideJoint along y, within [lower, upper] of the
/// slide's coordinate) that falls from rest for 1 s, with a light rope hanging from it
/// (which puts it in an island) or none (Bullet solves the guide). Returns its drop.
double guidedDrop(Frame kind, btScalar lower, btScalar upper, bool reference_a, bool with_rope) {
    Physics phys;
    btRigidBody& platform = phys.box(btVector3(0.3f, 0.025f, 0.2f), 3.0, btVector3(0, 1.0f, 0));
    platform.setActivationState(DISABLE_DEACTIVATION);
    auto guide = slideJoint(kind, platform, kind == Frame::Slider ? upright() : btTransform::getIdentity(), 1, lower, upper, reference_a);
    phys.world->addConstraint(guide.get(), true);
    BulletWorld ropes(*phys.world);
    if (with_rope) {
        const StringId id = ropes.addString(rope({0.25, 0.975, 0}, {0.25, 0.575, 0}, 16));
        ropes.attach(id, 0, platform, btVector3(0.25f, -0.025f, 0));
    }
    for (int i = 0; i < 100; ++i) phys.step(1);
    EXPECT_TRUE(ropes.lastError().empty()) << ropes.lastError();
    EXPECT_EQ(ropes.core().lastBodyJoints().size(), with_rope ? 1u : 0u);
    EXPECT_LT(platform.getWorldTransform().getBasis().getColumn(1).angle(btVector3(0, 1, 0)), 5e-3f);
    phys.world->removeConstraint(guide.get());
    return 1.0 - static_cast<double>(platform.getCenterOfMassPosition().y());
}
}  // namespace

// A slider's or 6-dof joint's limits are hard stops in the island, in Bullet's conventions:
// a platform that may drop 0.2 m along its guide falls onto that limit and rests there as
// Bullet's own solver rests it (the give of the stop, m g over 100 m / h^2: 1e-5 m). The
// slider's limits bound b's coordinate from a's pivot, or (linear reference b) a's from b's.
TEST(Islands, GuideLimitStopsAFallingPlatformAsBulletDoes) {
    for (const Frame kind : {Frame::Slider, Frame::SixDof, Frame::SixDofSpring2}) {
        for (const bool reference_a : {true, false}) {
            if (!reference_a && kind != Frame::Slider) continue;
            SCOPED_TRACE(std::string(frameName(kind)) + (reference_a ? "" : ", linear reference b"));
            // The slide's coordinate goes down with the platform (x is the world's y) from
            // a's pivot, and up with it from b's.
            const btScalar lower = reference_a ? -0.2f : 0.0f, upper = reference_a ? 0.0f : 0.2f;
            const double bullet = guidedDrop(kind, lower, upper, reference_a, false);
            ASSERT_NEAR(bullet, 0.2, 2e-3) << "Bullet's own rest on the limit";
            EXPECT_NEAR(guidedDrop(kind, lower, upper, reference_a, true), bullet, 1e-3);
        }
    }
}

// An angular limit of a 6-dof joint or a slider in the island: a 3 kg board held at one end
// by a 6-dof joint to the world, locked but for its turn about z, limited to +-0.1 rad, or
// on a slider along x 0.15 m to one side of its centre, locked along it, its turn about that
// line limited likewise, with a rope hanging from its free end, falls from level onto its
// limit and rests there as Bullet's own solver rests it (without the rope), 0.1 rad down
// (1 mrad), its end still at the joint.
TEST(Islands, AngularLimitStopsAFallingBoardAsBulletDoes) {
    for (const Frame kind : {Frame::SixDof, Frame::SixDofSpring2, Frame::Slider}) {
        SCOPED_TRACE(frameName(kind));
        const bool slider = kind == Frame::Slider;
        const btVector3 pivot(-0.5f, 0, slider ? -0.15f : 0.0f);  // in the board's frame
        double turns[2];
        for (const bool with_rope : {false, true}) {
            Physics phys;
            btRigidBody& board = phys.box(btVector3(0.5f, 0.025f, 0.15f), 3.0, btVector3(0.5f, 1.0f, 0));
            board.setActivationState(DISABLE_DEACTIVATION);
            const btTransform frame(btQuaternion::getIdentity(), pivot);
            std::unique_ptr<btTypedConstraint> joint;
            if (kind == Frame::SixDof) {
                auto d6 = std::make_unique<btGeneric6DofConstraint>(board, frame, true);
                d6->setLinearLowerLimit(btVector3(0, 0, 0));
                d6->setLinearUpperLimit(btVector3(0, 0, 0));
                d6->setAngularLowerLimit(btVector3(0, 0, -0.1f));
                d6->setAngularUpperLimit(btVector3(0, 0, 0.1f));
                joint = std::move(d6);
            } else if (kind == Frame::SixDofSpring2) {
                auto d6 = std::make_unique<btGeneric6DofSpring2Constraint>(board, frame);
                d6->setLinearLowerLimit(btVector3(0, 0, 0));
                d6->setLinearUpperLimit(btVector3(0, 0, 0));
                d6->setAngularLowerLimit(btVector3(0, 0, -0.1f));
                d6->setAngularUpperLimit(btVector3(0, 0, 0.1f));
                joint = std::move(d6);
            } else {
                auto s = std::make_unique<btSliderConstraint>(board, frame, true);
                s->setLowerLinLimit(0);
                s->setUpperLinLimit(0);
                s->setLowerAngLimit(-0.1f);
                s->setUpperAngLimit(0.1f);
                joint = std::move(s);
            }
            phys.world->addConstraint(joint.get(), true);
            BulletWorld ropes(*phys.world);
            if (with_rope) {
                const StringId id = ropes.addString(rope({0.95, 0.975, 0}, {0.95, 0.475, 0}, 20));
                ropes.attach(id, 0, board, btVector3(0.45f, -0.025f, 0));
            }
            for (int i = 0; i < 200; ++i) phys.step(1);
            ASSERT_TRUE(ropes.lastError().empty()) << ropes.lastError();
            EXPECT_EQ(ropes.core().lastBodyJoints().size(), with_rope ? 1u : 0u);
            const btQuaternion q = board.getOrientation();
            turns[with_rope ? 1 : 0] = 2.0 * std::atan2(static_cast<double>(slider ? q.x() : q.z()), static_cast<double>(q.w()));
            // At rest in the island; Bullet's slider limit bounces (its restitution, 1 -
            // dampingLimAng, is 1 by default) where the island's stops are inelastic.
            if (with_rope || !slider) EXPECT_LT(board.getAngularVelocity().length(), 1e-2f);
            const btVector3 end = board.getWorldTransform() * pivot;
            EXPECT_LT(end.distance(btVector3(0, 1, pivot.z())), 1e-3f);
            phys.world->removeConstraint(joint.get());
        }
        // Down: clockwise about +z for the board held at its end; about +x for the board
        // hanging off the slider's line on the +z side.
        const double down = slider ? 0.1 : -0.1;
        EXPECT_NEAR(turns[0], down, 5e-3) << "Bullet's own rest on the limit";
        EXPECT_NEAR(turns[1], down, 1e-3);
    }
}

namespace {
/// A 3 kg platform on a vertical guide (slideJoint along y, free), its motor driving the
/// slide's coordinate at Bullet's target `rate` with at most `force` N, for `steps` steps of
/// 1/100 s from rest, with a light rope hanging from it (the island's) or none (Bullet's).
/// Returns the platform's vertical velocity.
double guideMotorRun(Frame kind, double rate, double force, bool reference_a, bool with_rope, int steps) {
    Physics phys;
    btRigidBody& platform = phys.box(btVector3(0.3f, 0.025f, 0.2f), 3.0, btVector3(0, 1.0f, 0));
    platform.setActivationState(DISABLE_DEACTIVATION);
    auto guide = slideJoint(kind, platform, kind == Frame::Slider ? upright() : btTransform::getIdentity(), 1, 1, -1, reference_a);
    const auto v = static_cast<btScalar>(rate), f = static_cast<btScalar>(force);
    if (kind == Frame::Slider) {
        auto& slider = static_cast<btSliderConstraint&>(*guide);
        slider.setPoweredLinMotor(true);
        slider.setTargetLinMotorVelocity(v);
        slider.setMaxLinMotorForce(f);
    } else if (kind == Frame::SixDof) {
        btTranslationalLimitMotor& motor = *static_cast<btGeneric6DofConstraint&>(*guide).getTranslationalLimitMotor();
        motor.m_enableMotor[1] = true;
        motor.m_targetVelocity[1] = v;
        motor.m_maxMotorForce[1] = f;
    } else {
        auto& d6 = static_cast<btGeneric6DofSpring2Constraint&>(*guide);
        d6.enableMotor(1, true);
        d6.setTargetVelocity(1, v);
        d6.setMaxMotorForce(1, f);
    }
    phys.world->addConstraint(guide.get(), true);
    BulletWorld ropes(*phys.world);
    if (with_rope) {
        const StringId id = ropes.addString(rope({0.25, 0.975, 0}, {0.25, 0.575, 0}, 16));
        ropes.attach(id, 0, platform, btVector3(0.25f, -0.025f, 0));
    }
    for (int i = 0; i < steps; ++i) phys.step(1);
    EXPECT_TRUE(ropes.lastError().empty()) << ropes.lastError();
    EXPECT_EQ(ropes.core().lastBodyJoints().size(), with_rope ? 1u : 0u);
    phys.world->removeConstraint(guide.get());
    return static_cast<double>(platform.getLinearVelocity().y());
}
}  // namespace

// A slider's and a 6-dof joint's motors in an island drive their coordinate at the target
// rate, in Bullet's direction, up to their force: a 3 kg platform on a vertical guide (with
// a light rope, 16 segments, hanging from it) is moved at Bullet's own rate (1%; the motor
// gives L / (k h) under its load L ~ 30 N, k = 1000 m / h^2: 1e-4 of the rate), lifted
// where the motor's force is 1.3 times the weight and falling where it is 0.7 times.
TEST(Islands, GuideMotorDrivesItsPlatformAsBulletDoes) {
    const double weight = kG * (3.0 + ropeMass(rope({0, 0, 0}, {0, 0.4, 0}, 16), 0.4));
    for (const Frame kind : {Frame::Slider, Frame::SixDof, Frame::SixDofSpring2}) {
        for (const bool reference_a : {true, false}) {
            if (!reference_a && kind != Frame::Slider) continue;
            SCOPED_TRACE(std::string(frameName(kind)) + (reference_a ? "" : ", linear reference b"));
            const double bullet = guideMotorRun(kind, 0.5, 10.0 * weight, reference_a, false, 30);
            ASSERT_NEAR(std::abs(bullet), 0.5, 0.01) << "Bullet's own rate";
            EXPECT_NEAR(guideMotorRun(kind, 0.5, 10.0 * weight, reference_a, true, 30), bullet, 0.005);
            const double up = bullet > 0.0 ? 0.5 : -0.5;  // the target that lifts the platform
            EXPECT_NEAR(guideMotorRun(kind, up, 1.3 * weight, reference_a, true, 60), 0.5, 0.005);
            EXPECT_LT(guideMotorRun(kind, up, 0.7 * weight, reference_a, true, 30), -0.1);
        }
    }
}

namespace {
/// A board's turn about a joint's free axis: its angle (from the quaternion) and rate, rad, rad/s.
struct Turn {
    double angle = 0.0, rate = 0.0;
};

/// A 3 kg board held at one end by a 6-dof joint to the world (or a slider along x, its
/// turn about x free) that leaves only its turn about `axis` (x or z) free, driven by the
/// joint's angular motor at Bullet's target `rate` with at most `torque` (a 6-dof spring-2
/// joint's motor as a servo toward `servo` rad where given), gravity off, for `steps`
/// steps of 1/100 s, with a rope hanging from its far end (the island's) or none. Returns
/// the board's turn about that axis.
Turn turnMotorRun(Frame kind, double rate, double torque, bool with_rope, int steps = 30, std::optional<double> servo = std::nullopt) {
    Physics phys(0.0);
    btRigidBody& board = phys.box(btVector3(0.5f, 0.025f, 0.15f), 3.0, btVector3(0.5f, 1.0f, 0));
    board.setActivationState(DISABLE_DEACTIVATION);
    const btTransform frame(btQuaternion::getIdentity(), btVector3(-0.5f, 0, 0));
    const auto v = static_cast<btScalar>(rate), t = static_cast<btScalar>(torque);
    std::unique_ptr<btTypedConstraint> joint;
    int axis = 2;
    if (kind == Frame::Slider) {
        axis = 0;
        auto slider = std::make_unique<btSliderConstraint>(board, frame, true);
        slider->setLowerLinLimit(0);
        slider->setUpperLinLimit(0);
        slider->setLowerAngLimit(1);
        slider->setUpperAngLimit(-1);
        slider->setPoweredAngMotor(true);
        slider->setTargetAngMotorVelocity(v);
        slider->setMaxAngMotorForce(t);
        joint = std::move(slider);
    } else if (kind == Frame::SixDof) {
        auto d6 = std::make_unique<btGeneric6DofConstraint>(board, frame, true);
        d6->setAngularLowerLimit(btVector3(0, 0, 1));
        d6->setAngularUpperLimit(btVector3(0, 0, -1));
        d6->getRotationalLimitMotor(2)->m_enableMotor = true;
        d6->getRotationalLimitMotor(2)->m_targetVelocity = v;
        d6->getRotationalLimitMotor(2)->m_maxMotorForce = t;
        joint = std::move(d6);
    } else {
        auto d6 = std::make_unique<btGeneric6DofSpring2Constraint>(board, frame);
        d6->setLinearLowerLimit(btVector3(0, 0, 0));
        d6->setLinearUpperLimit(btVector3(0, 0, 0));
        d6->setAngularLowerLimit(btVector3(0, 0, 1));
        d6->setAngularUpperLimit(btVector3(0, 0, -1));
        d6->enableMotor(5, true);
        d6->setTargetVelocity(5, v);
        d6->setMaxMotorForce(5, t);
        if (servo) {
            d6->setServo(5, true);
            d6->setServoTarget(5, static_cast<btScalar>(*servo));
        }
        joint = std::move(d6);
    }
    phys.world->addConstraint(joint.get(), true);
    BulletWorld ropes(*phys.world);
    if (with_rope) {
        const StringId id = ropes.addString(rope({0.95, 0.975, 0}, {0.95, 0.775, 0}, 8));
        ropes.attach(id, 0, board, btVector3(0.45f, -0.025f, 0));
    }
    for (int i = 0; i < steps; ++i) phys.step(1);
    EXPECT_TRUE(ropes.lastError().empty()) << ropes.lastError();
    EXPECT_EQ(ropes.core().lastBodyJoints().size(), with_rope ? 1u : 0u);
    phys.world->removeConstraint(joint.get());
    const btQuaternion q = board.getOrientation();
    return {2.0 * std::atan2(static_cast<double>(q[axis]), static_cast<double>(q.w())), static_cast<double>(board.getAngularVelocity()[axis])};
}
}  // namespace

// The angular motors of a slider and of 6-dof joints in an island turn a board at Bullet's
// own rate and direction (a strong motor, no gravity: 1% of the 1 rad/s).
TEST(Islands, AngularMotorsTurnABoardAsBulletDoes) {
    for (const Frame kind : {Frame::Slider, Frame::SixDof, Frame::SixDofSpring2}) {
        SCOPED_TRACE(frameName(kind));
        const double bullet = turnMotorRun(kind, 1.0, 100.0, false).rate;
        ASSERT_NEAR(std::abs(bullet), 1.0, 0.02) << "Bullet's own rate";
        EXPECT_NEAR(turnMotorRun(kind, 1.0, 100.0, true).rate, bullet, 0.01);
    }
}

namespace {
/// A 3 kg platform on a vertical btGeneric6DofSpring2Constraint to the world, free along y
/// only, on a spring along y (stiffness k, damping c, at rest where the platform starts),
/// released from rest, with a light rope hanging from it (the island's) or none (Bullet's):
/// its height over 200 steps of 1/100 s, and the platform's and rope's mass.
struct SpringRun {
    std::vector<double> y;
    double mass = 0.0;
};
SpringRun springRun(double k, double c, bool with_rope) {
    Physics phys;
    btRigidBody& platform = phys.box(btVector3(0.3f, 0.025f, 0.2f), 3.0, btVector3(0, 1.0f, 0));
    platform.setActivationState(DISABLE_DEACTIVATION);
    auto guide = slideJoint(Frame::SixDofSpring2, platform, btTransform::getIdentity(), 1, 1, -1);
    auto& d6 = static_cast<btGeneric6DofSpring2Constraint&>(*guide);
    d6.enableSpring(1, true);
    d6.setStiffness(1, static_cast<btScalar>(k));
    d6.setDamping(1, static_cast<btScalar>(c));
    d6.setEquilibriumPoint(1, 0);
    phys.world->addConstraint(guide.get(), true);
    BulletWorld ropes(*phys.world);
    SpringRun run;
    run.mass = 3.0;
    if (with_rope) {
        const StringDesc hanging = rope({0.25, 0.975, 0}, {0.25, 0.575, 0}, 16);
        const StringId id = ropes.addString(hanging);
        ropes.attach(id, 0, platform, btVector3(0.25f, -0.025f, 0));
        run.mass += ropeMass(hanging, 0.4);
    }
    for (int i = 0; i < 200; ++i) {
        phys.step(1);
        run.y.push_back(static_cast<double>(platform.getCenterOfMassPosition().y()) - 1.0);
    }
    EXPECT_TRUE(ropes.lastError().empty()) << ropes.lastError();
    EXPECT_EQ(ropes.core().lastBodyJoints().size(), with_rope ? 1u : 0u);
    phys.world->removeConstraint(guide.get());
    return run;
}

/// The times (s, steps of 1/100 s) of a sampled motion's lowest points, each where its
/// velocity turns from down to up, placed by the parabola through the three samples around it.
std::vector<double> lowestPoints(const std::vector<double>& y) {
    std::vector<double> out;
    for (std::size_t i = 1; i + 1 < y.size(); ++i)
        if (y[i] < y[i - 1] && y[i] <= y[i + 1]) {
            const double curvature = y[i - 1] - 2.0 * y[i] + y[i + 1];
            const double shift = curvature > 0.0 ? 0.5 * (y[i - 1] - y[i + 1]) / curvature : 0.0;
            out.push_back(0.01 * (static_cast<double>(i + 1) + shift));
        }
    return out;
}
}  // namespace

// A 6-dof spring joint's springs in an island act as Bullet applies them (each step the
// spring's force where the step starts, -k (q - rest) - c dq/dt): a 3 kg platform on a
// vertical spring of 300 N/m, released at the spring's rest length with a light rope
// hanging from it, oscillates about its static sag m g / k with the period 2 pi sqrt(m / k)
// (0.63 s; 1%: the step's phase error, sqrt(k / m) h = 0.1, is 0.2%) and keeps its swing
// (symplectic, as Bullet's: its lowest point after two periods within 3% of the first,
// 2 m g / k down), where a spring solved implicitly would lose a quarter of its swing a
// period. Damped (c = sqrt(k m), a damping ratio of 1/2) it settles at the sag, within
// 0.5%, as Bullet's own solver settles it; and a spring too stiff for the step is limited
// as Bullet limits it.
TEST(Islands, SixDofSpringsActAsBulletsSprings) {
    const double k = 300.0;
    for (const bool with_rope : {false, true}) {
        SCOPED_TRACE(with_rope ? "island" : "Bullet");
        const SpringRun run = springRun(k, 0.0, with_rope);
        const double sag = run.mass * kG / k, period = 2.0 * kPi * std::sqrt(run.mass / k);
        const std::vector<double> lows = lowestPoints(run.y);
        ASSERT_GE(lows.size(), 2u);
        EXPECT_NEAR(lows[1] - lows[0], period, 0.01 * period);
        EXPECT_NEAR(lows[0], 0.5 * period, 0.02 * period);
        // The lowest points of the first and third swings (at 0.32 s and 1.58 s).
        const double first = *std::min_element(run.y.begin(), run.y.begin() + 64);
        const double third = *std::min_element(run.y.begin() + 127, run.y.begin() + 190);
        EXPECT_NEAR(first, -2.0 * sag, 0.03 * 2.0 * sag);
        EXPECT_NEAR(third, first, 0.03 * 2.0 * sag) << "the swing was damped";
        const SpringRun damped = springRun(k, std::sqrt(k * run.mass), with_rope);
        EXPECT_NEAR(damped.y.back(), -sag, 0.005 * sag);
        // Too stiff for the step (sqrt(k / m) h = 5.8), the spring is limited as Bullet limits
        // it (setStiffness's default): to 3 kg / (16 h^2), a quarter of the rate of steps.
        const SpringRun stiff = springRun(1e6, 0.0, with_rope);
        const double limited = 2.0 * kPi * std::sqrt(stiff.mass / (3.0 / (16.0 * 0.01 * 0.01)));
        const std::vector<double> stiff_lows = lowestPoints(stiff.y);
        ASSERT_GE(stiff_lows.size(), 2u);
        EXPECT_NEAR(stiff_lows[1] - stiff_lows[0], limited, 0.01 * limited);
    }
}

namespace {
/// A 1 kg wheel (a 0.1 m ball) on a btHinge2Constraint below a 5 kg chassis, spinning at
/// 5 rad/s about its axle (z) and hanging on the joint's suspension spring (along y, 400 N/m,
/// damped at 20 N s/m, at rest where the wheel starts), for 2 s of steps of 1/100 s. The
/// chassis is hung by two ropes at its ends (the island's) or static (Bullet's). Returns the
/// wheel's drop relative to the chassis and its spin.
std::pair<double, double> hinge2Run(bool with_ropes) {
    Physics phys;
    btRigidBody& chassis = phys.box(btVector3(0.5f, 0.05f, 0.15f), with_ropes ? 5.0 : 0.0, btVector3(0, 1.0f, 0));
    btRigidBody& wheel = phys.sphere(0.1, 1.0, btVector3(0, 0.7f, 0));
    for (btRigidBody* b : {&chassis, &wheel}) b->setActivationState(DISABLE_DEACTIVATION);
    wheel.setAngularVelocity(btVector3(0, 0, 5));
    btVector3 anchor(0, 0.7f, 0), axis1(0, 1, 0), axis2(0, 0, 1);
    btHinge2Constraint joint(chassis, wheel, anchor, axis1, axis2);
    joint.setStiffness(2, 400.0f);
    joint.setDamping(2, 20.0f);
    phys.world->addConstraint(&joint, true);
    BulletWorld ropes(*phys.world);
    if (with_ropes) {
        for (const double x : {-0.45, 0.45}) {
            const StringId id = ropes.addString(rope({x, 2.0, 0}, {x, 1.05, 0}, 40));
            ropes.attach(id, 0, btVector3(static_cast<btScalar>(x), 2.0f, 0));
            ropes.attach(id, -1, chassis, btVector3(static_cast<btScalar>(x), 0.05f, 0));
        }
    }
    for (int i = 0; i < 200; ++i) phys.step(1);
    EXPECT_TRUE(ropes.lastError().empty()) << ropes.lastError();
    EXPECT_EQ(ropes.core().lastBodyJoints().size(), with_ropes ? 1u : 0u);
    phys.world->removeConstraint(&joint);
    const double drop = static_cast<double>(chassis.getCenterOfMassPosition().y() - wheel.getCenterOfMassPosition().y()) - 0.3;
    return {drop, static_cast<double>(wheel.getAngularVelocity().z())};
}
}  // namespace

// A btHinge2Constraint (a wheel's suspension and axle, a 6-dof spring-2 joint) in an island:
// a 1 kg wheel spinning on its axle below a 5 kg chassis hung by ropes sags on the
// suspension spring by m g / k (2.45 cm; 1%) as under Bullet's own solver, and spins on
// (its axle free: 5 rad/s within 1%).
TEST(Islands, Hinge2WheelHangsOnItsSuspensionAsBulletDoes) {
    const auto bullet = hinge2Run(false), island = hinge2Run(true);
    const double sag = kG / 400.0;
    ASSERT_NEAR(bullet.first, sag, 0.01 * sag) << "Bullet's own sag";
    EXPECT_NEAR(island.first, sag, 0.01 * sag);
    EXPECT_NEAR(island.second, 5.0, 0.05);
    EXPECT_NEAR(island.second, bullet.second, 0.05);
}

namespace {
/// Two wheels (1 kg discs, radius 0.1 m: I = m r^2 / 2 about their axles) on hinges to the
/// world about z, 0.3 m apart, geared (btGearConstraint, axes z, ratio 2), gravity off; the
/// first spun at 2 rad/s, the second at rest. With a light rope glued to the second's axle
/// outside its face (the island's: no moment about the axle) or none (Bullet's). Returns
/// both wheels' turn rates about z after `steps` steps of 1/100 s, and the gear's applied
/// impulse in the first step.
struct GearRun {
    double first = 0.0, second = 0.0, impulse = 0.0;
};
GearRun gearRun(bool with_rope, int steps) {
    Physics phys(0.0);
    btRigidBody* wheels[2];
    for (int k = 0; k < 2; ++k) {
        wheels[k] = &phys.add(std::make_unique<btCylinderShapeZ>(btVector3(0.1f, 0.1f, 0.02f)), 1.0, btVector3(0.3f * static_cast<btScalar>(k), 1.0f, 0));
        wheels[k]->setActivationState(DISABLE_DEACTIVATION);
    }
    wheels[0]->setAngularVelocity(btVector3(0, 0, 2));
    btHingeConstraint axle0(*wheels[0], btVector3(0, 0, 0), btVector3(0, 0, 1));
    btHingeConstraint axle1(*wheels[1], btVector3(0, 0, 0), btVector3(0, 0, 1));
    btGearConstraint gear(*wheels[0], *wheels[1], btVector3(0, 0, 1), btVector3(0, 0, 1), 2.0f);
    for (btTypedConstraint* c : {static_cast<btTypedConstraint*>(&axle0), static_cast<btTypedConstraint*>(&axle1),
                                 static_cast<btTypedConstraint*>(&gear)})
        phys.world->addConstraint(c, true);
    BulletWorld ropes(*phys.world);
    if (with_rope) {
        const StringId id = ropes.addString(rope({0.3, 1.0, 0.05}, {0.3, 0.8, 0.05}, 8));
        ropes.attach(id, 0, *wheels[1], btVector3(0, 0, 0.05f));
    }
    GearRun run;
    for (int i = 0; i < steps; ++i) {
        phys.step(1);
        if (i == 0) run.impulse = static_cast<double>(gear.getAppliedImpulse());
    }
    EXPECT_TRUE(ropes.lastError().empty()) << ropes.lastError();
    EXPECT_EQ(ropes.core().lastBodyJoints().size(), with_rope ? 3u : 0u);
    for (btTypedConstraint* c : {static_cast<btTypedConstraint*>(&gear), static_cast<btTypedConstraint*>(&axle1),
                                 static_cast<btTypedConstraint*>(&axle0)})
        phys.world->removeConstraint(c);
    run.first = static_cast<double>(wheels[0]->getAngularVelocity().z());
    run.second = static_cast<double>(wheels[1]->getAngularVelocity().z());
    return run;
}
}  // namespace

// A gear in an island ties its wheels' rates as Bullet's does, omega_0 + 2 omega_1 = 0: two
// equal wheels, the first spun at 2 rad/s, engage by one impulse J along the row (1, 2):
// omega_0 = 2 + J / I, omega_1 = 2 J / I, so J = -2 I / 5 and the wheels turn at 1.6 and
// -0.8 rad/s (1%), and keep turning so, as under Bullet's own solver; the gear reports the
// engaging impulse, |J| = 2 I / 5 = 0.002 N m s (1%), as its applied impulse.
TEST(Islands, GearTiesItsWheelsRatesAsBulletDoes) {
    for (const int steps : {5, 50}) {
        SCOPED_TRACE(steps);
        const GearRun bullet = gearRun(false, steps), island = gearRun(true, steps);
        ASSERT_NEAR(bullet.first, 1.6, 0.016) << "Bullet's own";
        ASSERT_NEAR(bullet.second, -0.8, 0.008) << "Bullet's own";
        EXPECT_NEAR(island.first, 1.6, 0.016);
        EXPECT_NEAR(island.second, -0.8, 0.008);
        EXPECT_NEAR(std::abs(island.impulse), 0.002, 2e-5);
        EXPECT_NEAR(island.impulse, bullet.impulse, 2e-5);
    }
}

// A 6-dof spring joint's servo in an island turns its coordinate toward the target at the
// motor's speed and stops there, as Bullet's own servo does: a board turned to 0.5 rad and
// to -0.5 rad at 1 rad/s turns at Bullet's rate (1%) on its way, and rests at the target
// within 1 mrad after 1 s (Bullet's rests within 1%).
TEST(Islands, SixDofServoTurnsABoardToItsTargetAsBulletDoes) {
    for (const double target : {0.5, -0.5}) {
        SCOPED_TRACE(target);
        const auto run = [&](bool with_rope, int steps) { return turnMotorRun(Frame::SixDofSpring2, 1.0, 100.0, with_rope, steps, target); };
        const Turn bullet_moving = run(false, 20), bullet_rest = run(false, 100);
        ASSERT_NEAR(std::abs(bullet_moving.rate), 1.0, 0.02) << "Bullet's own rate";
        ASSERT_NEAR(std::abs(bullet_rest.angle), std::abs(target), 0.01 * std::abs(target)) << "Bullet's own rest";
        const Turn moving = run(true, 20), rest = run(true, 100);
        EXPECT_NEAR(moving.rate, bullet_moving.rate, 0.01);
        EXPECT_NEAR(rest.angle, bullet_rest.angle, 1e-3);
        EXPECT_NEAR(std::abs(rest.angle), std::abs(target), 1e-3);
        EXPECT_LT(std::abs(rest.rate), 1e-2);
    }
}

namespace {
/// A 3 kg board held at one end by a cone-twist joint to the world (btConeTwistConstraint,
/// its twist axis, the frame's x, along the board, the frame turned by `roll` about it),
/// swing spans 0.3 (about the frame's z) and 0.5 (about its y), twist span 0.2, anchored
/// to a static body at the board's end (the joint's b), falling
/// from level for 2 s, with a rope hanging from its free end (the island's) or none
/// (Bullet's). Returns the board's turn about the world's z (it swings down about z).
double coneTwistRest(double roll, bool with_rope) {
    Physics phys;
    btRigidBody& board = phys.box(btVector3(0.5f, 0.025f, 0.15f), 3.0, btVector3(0.5f, 1.0f, 0));
    board.setActivationState(DISABLE_DEACTIVATION);
    btRigidBody& anchor = phys.box(btVector3(0.01f, 0.01f, 0.01f), 0.0, btVector3(0, 1.0f, 0));
    const btQuaternion rolled(btVector3(1, 0, 0), static_cast<btScalar>(roll));
    btConeTwistConstraint joint(board, anchor, btTransform(rolled, btVector3(-0.5f, 0, 0)), btTransform(rolled));
    joint.setLimit(0.3f, 0.5f, 0.2f);
    phys.world->addConstraint(&joint, true);
    BulletWorld ropes(*phys.world);
    if (with_rope) {
        const StringId id = ropes.addString(rope({0.95, 0.975, 0}, {0.95, 0.475, 0}, 20));
        ropes.attach(id, 0, board, btVector3(0.45f, -0.025f, 0));
    }
    for (int i = 0; i < 200; ++i) phys.step(1);
    EXPECT_TRUE(ropes.lastError().empty()) << ropes.lastError();
    EXPECT_EQ(ropes.core().lastBodyJoints().size(), with_rope ? 1u : 0u);
    const btVector3 end = board.getWorldTransform() * btVector3(-0.5f, 0, 0);
    EXPECT_LT(end.distance(btVector3(0, 1, 0)), 2e-3f) << "the board's end left the joint";
    if (with_rope) EXPECT_LT(board.getAngularVelocity().length(), 1e-2f);
    phys.world->removeConstraint(&joint);
    const btVector3 along = board.getWorldTransform().getBasis().getColumn(0);
    return std::atan2(static_cast<double>(along.y()), static_cast<double>(along.x()));
}
}  // namespace

// A cone-twist joint's cone in the island, in Bullet's convention (an ellipse of the two
// swing spans, each about its own axis of the frame): a board held at one end swings down
// onto the cone and rests there as Bullet's own solver rests it. The swing is about the
// world's z: with the frame as is, about the frame's z, so the cone stops it at span1 =
// 0.3 rad; with the frame rolled a quarter turn about the board, about the frame's y, at
// span2 = 0.5 rad (1 mrad).
TEST(Islands, ConeTwistLimitHoldsABoardAsBulletDoes) {
    for (const double roll : {0.0, kPi / 2}) {
        SCOPED_TRACE(roll == 0.0 ? "frame as is" : "frame rolled a quarter turn");
        const double limit = roll == 0.0 ? 0.3 : 0.5;
        EXPECT_NEAR(coneTwistRest(roll, false), -limit, 0.005) << "Bullet's own rest on the cone";
        EXPECT_NEAR(coneTwistRest(roll, true), -limit, 0.001);
    }
}

namespace {
/// What a ball joint did over a run of blockOnABallJoint.
struct JointRun {
    double applied = 0.0;  ///< the joint's applied impulse, averaged over the run's second half, N s
    Vec3 force_a = Vec3::Zero(), force_b = Vec3::Zero();  ///< its feedback's forces, averaged likewise, N
    int broke_at = -1;     ///< the step after which it was disabled (-1: never)
    double y_break = 0.0, v_break = 0.0;  ///< the lower block's height and vertical speed then
    double y_end = 0.0;    ///< its height at the end
    int in_island = 0;     ///< steps on which the island solved the joint (World::lastBodyJoints)
};

/// A 2 kg block hung from a pin by a 0.5 m rope (which puts it in an island), and a 3 kg
/// block hung 10 cm below it by a ball joint (btPoint2PointConstraint) of breaking impulse
/// `breaking` (N s), both at rest where they start; `steps` steps of h.
JointRun blockOnABallJoint(double breaking, int steps, double h, bool weld = false) {
    Physics phys;
    btRigidBody& upper = phys.box(btVector3(0.05f, 0.05f, 0.05f), 2.0, btVector3(0, 1.0f, 0));
    btRigidBody& lower = phys.box(btVector3(0.05f, 0.05f, 0.05f), 3.0, btVector3(0, 0.9f, 0));
    for (btRigidBody* b : {&upper, &lower}) b->setActivationState(DISABLE_DEACTIVATION);
    btPoint2PointConstraint ball(upper, lower, btVector3(0, -0.05f, 0), btVector3(0, 0.05f, 0));
    btFixedConstraint fixed(upper, lower, btTransform(btQuaternion::getIdentity(), btVector3(0, -0.05f, 0)),
                            btTransform(btQuaternion::getIdentity(), btVector3(0, 0.05f, 0)));
    btTypedConstraint& joint = weld ? static_cast<btTypedConstraint&>(fixed) : ball;
    joint.setBreakingImpulseThreshold(static_cast<btScalar>(breaking));
    btJointFeedback feedback;
    joint.setJointFeedback(&feedback);
    joint.enableFeedback(true);
    phys.world->addConstraint(&joint, true);
    BulletWorld ropes(*phys.world);
    const StringId id = ropes.addString(rope({0, 1.55, 0}, {0, 1.05, 0}, 20));
    ropes.attach(id, 0, btVector3(0, 1.55f, 0));
    ropes.attach(id, -1, upper, btVector3(0, 0.05f, 0));
    JointRun run;
    int averaged = 0;
    for (int i = 0; i < steps; ++i) {
        phys.step(1, h);
        run.in_island += static_cast<int>(ropes.core().lastBodyJoints().size() == 1);
        if (run.broke_at < 0 && !joint.isEnabled()) {
            run.broke_at = i;
            run.y_break = static_cast<double>(lower.getCenterOfMassPosition().y());
            run.v_break = static_cast<double>(lower.getLinearVelocity().y());
        }
        if (2 * i >= steps && joint.isEnabled()) {
            run.applied += static_cast<double>(joint.getAppliedImpulse());
            run.force_a += tearables::toCore(feedback.m_appliedForceBodyA);
            run.force_b += tearables::toCore(feedback.m_appliedForceBodyB);
            ++averaged;
        }
    }
    EXPECT_TRUE(ropes.lastError().empty()) << ropes.lastError();
    if (averaged > 0) {
        run.applied /= averaged;
        run.force_a /= averaged;
        run.force_b /= averaged;
    }
    run.y_end = static_cast<double>(lower.getCenterOfMassPosition().y());
    phys.world->removeConstraint(&joint);
    return run;
}
}  // namespace

// A joint the island solves leaves on its constraint what Bullet's solver would: the
// impulse it applied and its joint feedback. The ball joint (or a weld, btFixedConstraint,
// whose rows are along and about the upper block's axes) carries the lower block: on
// average over a second it pulls the upper block (A) down and the lower (B) up by m g (the
// rope's bounce averages out), and its applied impulse, the sum of its world-axis rows'
// impulses on A, is -m g h. A joint whose impulse reaches its breaking threshold breaks,
// as in Bullet: disabled, and the block falls freely from there (Bullet's semi-implicit
// Euler: v0 t - g h^2 n (n + 1) / 2 after n steps), while a threshold three times the load
// (above the sudden load's twofold bounce) holds it.
TEST(Islands, BallJointAndWeldReportTheirImpulseAndBreakAtTheirThreshold) {
    for (const bool weld : {false, true}) {
        SCOPED_TRACE(weld ? "a weld" : "a ball joint");
        const double m = 3.0, h = 1.0 / 240.0, load = m * kG * h;
        const JointRun held = blockOnABallJoint(3.0 * load, 480, h, weld);
        EXPECT_EQ(held.broke_at, -1);
        // A breakable joint is the island's, not Bullet's, from the second step (the plugin
        // claims a rope's bodies at the end of a step, for the next).
        EXPECT_EQ(held.in_island, 479);
        EXPECT_NEAR(held.y_end, 0.9, 0.01);
        EXPECT_NEAR(held.applied, -load, 0.01 * load);
        EXPECT_NEAR(held.force_a.y(), -m * kG, 0.01 * m * kG);
        EXPECT_NEAR(held.force_b.y(), m * kG, 0.01 * m * kG);
        EXPECT_LT(std::hypot(held.force_a.x(), held.force_a.z()), 0.01 * m * kG);

        const int steps = 240;
        const JointRun broke = blockOnABallJoint(0.5 * load, steps, h, weld);
        ASSERT_GE(broke.broke_at, 0);
        ASSERT_LT(broke.broke_at, 60);
        EXPECT_EQ(broke.in_island, broke.broke_at);  // the island broke it; disabled, it is Bullet's
        const double n = steps - 1 - broke.broke_at, drop = -broke.v_break * n * h + 0.5 * kG * h * h * n * (n + 1);
        EXPECT_NEAR(broke.y_break - broke.y_end, drop, 0.01 * drop);
    }
}

// A joint to the world reports the world's side as Bullet's feedback does: the reaction.
// A 2 kg block hangs from a world point by a ball joint, with a 1 m rope hanging from it
// (which puts it in an island): the joint's feedback holds the block and the rope up, m g
// on A over the last half second (the rope's settling averages out), and the world (B)
// takes the opposite force (to rounding).
TEST(Islands, JointToTheWorldReportsTheReaction) {
    Physics phys;
    btRigidBody& block = phys.box(btVector3(0.05f, 0.05f, 0.05f), 2.0, btVector3(0, 1.0f, 0));
    block.setActivationState(DISABLE_DEACTIVATION);
    btPoint2PointConstraint joint(block, btVector3(0, 0.05f, 0));
    btJointFeedback feedback;
    joint.setJointFeedback(&feedback);
    joint.enableFeedback(true);
    phys.world->addConstraint(&joint, true);
    BulletWorld ropes(*phys.world);
    const StringDesc d = rope({0, 0.95, 0}, {0, -0.05, 0}, 40);
    const StringId id = ropes.addString(d);
    ropes.attach(id, 0, block, btVector3(0, -0.05f, 0));
    const double weight = (2.0 + ropeMass(d, 1.0)) * kG, h = 1.0 / 240.0;
    Vec3 on_a = Vec3::Zero();
    int averaged = 0;
    for (int i = 0; i < 480; ++i) {
        phys.step(1, h);
        ASSERT_TRUE(ropes.lastError().empty()) << ropes.lastError();
        if (i < 360) continue;
        ASSERT_EQ(ropes.core().lastBodyJoints().size(), 1u);
        on_a += tearables::toCore(feedback.m_appliedForceBodyA);
        ++averaged;
        const Vec3 a = tearables::toCore(feedback.m_appliedForceBodyA), b = tearables::toCore(feedback.m_appliedForceBodyB);
        EXPECT_LT((a + b).norm(), 1e-5 * weight) << "step " << i;
    }
    on_a /= averaged;
    EXPECT_NEAR(on_a.y(), weight, 0.01 * weight);
    EXPECT_LT(std::hypot(on_a.x(), on_a.z()), 0.01 * weight);
    phys.world->removeConstraint(&joint);
}

namespace {
/// A 5 kg crate (friction mu against a board of friction 1: Bullet's combined friction is
/// their product) on a 1.5 kg board hung level from two parallel 1 m ropes, with gravity
/// tilted by `tilt` in x and the ropes along it (at rest from the start). Returns how far
/// the crate has slid on the board after 1 s and after 2 s, m.
std::pair<double, double> crateSlideOnRopedBoard(double mu, double tilt) {
    const double board_half = 0.015, crate_half = 0.1;
    Physics phys;
    phys.world->setGravity(btVector3(static_cast<btScalar>(kG * std::sin(tilt)), static_cast<btScalar>(-kG * std::cos(tilt)), 0));
    btRigidBody& board = phys.box(btVector3(0.5f, static_cast<btScalar>(board_half), 0.15f), 1.5, btVector3(0, 1.0f, 0));
    btRigidBody& crate = phys.box(btVector3(0.1f, 0.1f, 0.1f), 5.0,
                                  btVector3(0, static_cast<btScalar>(1.0 + board_half + crate_half), 0));
    board.setFriction(1.0f);
    crate.setFriction(static_cast<btScalar>(mu));
    board.setActivationState(DISABLE_DEACTIVATION);
    crate.setActivationState(DISABLE_DEACTIVATION);
    BulletWorld ropes(*phys.world);
    const Vec3 up(-std::sin(tilt), std::cos(tilt), 0);
    for (int side = 0; side < 2; ++side) {
        const double x = side == 0 ? -0.4 : 0.4;
        const Vec3 end(x, 1.0 + board_half, 0), pin = end + 1.0 * up;
        const StringId id = ropes.addString(rope(pin, end, 40));
        ropes.attach(id, 0, tearables::toBullet(pin));
        ropes.attach(id, -1, board, btVector3(static_cast<btScalar>(x), static_cast<btScalar>(board_half), 0));
    }
    auto onBoard = [&] { return board.getWorldTransform().invXform(crate.getCenterOfMassPosition()); };
    const btVector3 start = onBoard();
    phys.step(100);
    const btVector3 one = onBoard();
    phys.step(100);
    return {static_cast<double>((one - start).length()), static_cast<double>((onBoard() - start).length())};
}
}  // namespace

// Coulomb's friction between two bodies of an island: a crate on a board
// that hangs from ropes, gravity tilted by theta. Below tan(theta) = mu the crate sticks:
// after the first second (the contact's first steps, without a normal force to weigh
// friction by yet, let it settle by a few mm) it creeps by at most the stick range, 1 um a
// step, 0.1 mm in 100 steps; asserted below 1 mm. Above it the crate slides from rest at
// a = g cos(theta) (tan(theta) - mu), so the first second's travel d gives the friction
// coefficient the solve applied, tan(theta) - 2 d / (g cos(theta)), to be mu within 2%
// (a settling of 4 mm shifts it by 0.001).
TEST(Islands, CrateOnARopedBoardSticksBelowAndSlidesAboveCoulombsLaw) {
    const double mu = 0.5;
    const auto held = crateSlideOnRopedBoard(mu, std::atan(0.95 * mu));
    EXPECT_LT(held.second - held.first, 1e-3) << "at 0.95 mu the crate should stick";
    const double tilt = std::atan(1.05 * mu);
    const auto slid = crateSlideOnRopedBoard(mu, tilt);
    const double applied = std::tan(tilt) - 2.0 * slid.first / (kG * std::cos(tilt));
    EXPECT_NEAR(applied, mu, 0.02 * mu) << "sliding at 1.05 mu: " << slid.first << " m in 1 s";
}
