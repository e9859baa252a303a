// Bullet's sub-step semantics: stepSimulation(dt, maxSubSteps, fixedTimeStep) takes n
// internal steps a frame. Forces given through the plugin act on all of them (impulse
// F dt_frame), pin moves and kinematic bodies are followed step by step (a crate lifted
// at constant speed weighs m g), and the peak tension of every step stays visible.
#include "tearables/bullet_core.hpp"

#include "bullet_fixture.hpp"

#include <btBulletDynamicsCommon.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <sstream>

namespace {

using tearables::BulletWorld;
using tearables::StringDesc;
using tearables::StringId;
using tearables::Vec3;
using tearables::testing::Physics;

constexpr double kPi = 3.14159265358979323846;

StringDesc rope(const Vec3& from, const Vec3& to, int segments) { return tearables::testing::plainRope(from, to, segments); }

double ropeMass(const StringDesc& d) {
    double m = 0.0;
    for (std::size_t i = 0; i + 1 < d.points.size(); ++i)
        m += d.density * kPi * d.radius * d.radius * (d.points[i + 1] - d.points[i]).norm();
    return m;
}

Vec3 momentum(const BulletWorld& ropes, StringId id) {
    const auto v = ropes.core().view(id);
    Vec3 p = Vec3::Zero();
    for (std::size_t i = 0; i < v.particleCount(); ++i) p += (*v.masses)[i] * (*v.velocities)[i];
    return p;
}

btRigidBody& kinematicBox(Physics& phys, const btVector3& at) {
    btRigidBody& body = phys.box(btVector3(0.1f, 0.1f, 0.1f), 0.0, at);
    phys.world->removeRigidBody(&body);
    body.setCollisionFlags((body.getCollisionFlags() & ~btCollisionObject::CF_STATIC_OBJECT) |
                           btCollisionObject::CF_KINEMATIC_OBJECT);
    body.setActivationState(DISABLE_DEACTIVATION);
    body.setInterpolationWorldTransform(body.getWorldTransform());  // at rest where it starts
    phys.world->addRigidBody(&body);
    return body;
}

}  // namespace

// A force given once per frame through the plugin gives the impulse F dt_frame, with 1, 4
// or 10 internal steps: the momentum of a free rope in zero gravity (internal forces
// conserve it), as a btRigidBody's applyCentralForce would.
TEST(BulletSubsteps, PerFrameForceGivesItsFullImpulse) {
    for (const int k : {1, 4, 10}) {
        Physics phys(0.0);
        BulletWorld ropes(*phys.world);
        const StringId id = ropes.addString(rope({0, 1, 0}, {1, 1, 0}, 20));
        const btScalar dt = btScalar(1) / btScalar(64);
        const btVector3 force(0, 0, 2.0f);
        ropes.applyForce(id, -1, force);
        const int n = phys.world->stepSimulation(dt, 10, dt / btScalar(k));
        ASSERT_EQ(n, k);
        const double expected = 2.0 * static_cast<double>(dt / btScalar(k)) * n;
        const Vec3 p = momentum(ropes, id);
        EXPECT_NEAR(p.z(), expected, 1e-6 * expected) << k << " sub-steps";
        EXPECT_NEAR(p.x(), 0.0, 1e-6 * expected);
        // Cleared after the step, as Bullet's clearForces: the next frame adds nothing.
        phys.world->stepSimulation(dt, 10, dt / btScalar(k));
        EXPECT_NEAR(momentum(ropes, id).z(), expected, 1e-6 * expected) << k << " sub-steps";
    }
}

// The same for a cloth and a paper sheet in zero gravity: a force given once per frame over
// four sub-steps gives the impulse F dt. The cloth's internal forces come in pairs; the
// sheet's implicit Jacobi solve conserves momentum only when converged, so it is pushed as
// a whole (a force m_v a on every vertex: no spring stretches).
TEST(BulletSubsteps, PerFrameForceOnClothAndPaperGivesItsFullImpulse) {
    Physics phys(0.0);
    BulletWorld ropes(*phys.world);
    tearables::ClothDesc c;
    c.resolution = {5, 5};
    c.size = {0.4, 0.4};
    c.areal_density = 0.2;
    tearables::PaperDesc p;
    p.center = Vec3(2, 1, 0);
    p.size[0] = p.size[1] = 0.4;
    p.resolution[0] = p.resolution[1] = 5;
    const tearables::ClothId cloth = ropes.addCloth(c);
    const tearables::PaperId paper = ropes.addPaper(p);
    ropes.applyClothForce(cloth, -1, btVector3(0, 3.0f, 0));
    const std::vector<double>& sheet_mass = *ropes.core().viewPaper(paper).masses;
    double sheet_total = 0.0;
    for (std::uint32_t v = 0; v < sheet_mass.size(); ++v) {
        ropes.applyPaperForce(paper, v, btVector3(0, static_cast<btScalar>(sheet_mass[v] * 3.0), 0));
        sheet_total += sheet_mass[v] * 3.0;
    }
    const btScalar dt = btScalar(1) / btScalar(64);
    ASSERT_EQ(phys.world->stepSimulation(dt, 10, dt / 4), 4);
    const double expected = 3.0 * static_cast<double>(dt);
    auto momentumY = [](const auto& view) {
        double py = 0.0;
        for (std::size_t i = 0; i < view.positions->size(); ++i) py += (*view.masses)[i] * (*view.velocities)[i].y();
        return py;
    };
    EXPECT_NEAR(momentumY(ropes.core().viewCloth(cloth)), expected, 1e-6 * expected);
    const double sheet_expected = sheet_total * static_cast<double>(dt);
    EXPECT_NEAR(momentumY(ropes.core().viewPaper(paper)), sheet_expected, 1e-6 * sheet_expected);
    auto field = [](auto&& call) {
        try {
            call();
        } catch (const tearables::InvalidInput& e) {
            return e.field();
        }
        return std::string("none");
    };
    EXPECT_EQ(field([&] { ropes.applyClothForce(cloth, 25, btVector3(1, 0, 0)); }), "vertex");
    EXPECT_EQ(field([&] { ropes.applyClothForce(cloth, 0, btVector3(NAN, 0, 0)); }), "force");
    EXPECT_EQ(field([&] { ropes.applyPaperForce(paper, 25, btVector3(1, 0, 0)); }), "vertex");
    EXPECT_EQ(field([&] { ropes.applyPaperForce(tearables::PaperId{9}, 0, btVector3(1, 0, 0)); }), "paper");
}

// A 5 kg crate on a 1 m rope, lifted at a constant 0.5 m/s by the top, with four internal
// steps a frame: at constant speed the rope carries (m_crate + m_rope below) g at its top.
// Once by a kinematic body the rope hangs from (2 cm under it), once by moving the rope's
// world pin. Tolerance: 1% of m g is an acceleration of 0.1 m/s^2, a speed change of
// 1.6 mm/s over a frame: a settled lift stays well within it, while the whole frame's
// travel taken on the first step leaves the rope slack at the frame's end (~0.3 N).
TEST(BulletSubsteps, CrateLiftedAtConstantSpeedWeighsMg) {
    for (const bool kinematic : {true, false}) {
        Physics phys;
        const double mass = 5.0;
        btRigidBody& crate = phys.box(btVector3(0.1f, 0.1f, 0.1f), mass, btVector3(0, 0.9f, 0));
        btRigidBody* lifter = kinematic ? &kinematicBox(phys, btVector3(0, 2.12f, 0)) : nullptr;
        BulletWorld ropes(*phys.world);
        const StringDesc d = rope({0, 2.0, 0}, {0, 1.0, 0}, 20);
        const StringId id = ropes.addString(d);
        if (kinematic)
            ropes.attach(id, 0, *lifter, btVector3(0, -0.12f, 0));
        else
            ropes.attach(id, 0, btVector3(0, 2.0f, 0));
        ropes.attach(id, -1, crate, btVector3(0, 0.1f, 0));
        const btScalar dt = btScalar(1) / btScalar(60), h = btScalar(1) / btScalar(240);
        for (int i = 0; i < 120; ++i) phys.world->stepSimulation(dt, 10, h);  // hang still for 2 s
        const double speed = 0.5;
        const double weight = (mass + ropeMass(d)) * 9.81;
        double lo = 1e300, hi = -1e300;
        for (int i = 1; i <= 120; ++i) {
            const btScalar y = static_cast<btScalar>(2.0 + speed * i / 60.0);
            if (kinematic)
                lifter->setWorldTransform(btTransform(btQuaternion::getIdentity(), btVector3(0, y + 0.12f, 0)));
            else
                ropes.movePin(id, 0, btVector3(0, y, 0));
            phys.world->stepSimulation(dt, 10, h);
            if (i <= 60) continue;  // the start of the lift: the crate takes up speed
            const double t = ropes.core().view(id).tension->front();
            lo = std::min(lo, t);
            hi = std::max(hi, t);
        }
        EXPECT_NEAR(lo, weight, 0.01 * weight) << (kinematic ? "kinematic" : "pin");
        EXPECT_NEAR(hi, weight, 0.01 * weight) << (kinematic ? "kinematic" : "pin");
        EXPECT_NEAR(static_cast<double>(crate.getLinearVelocity().y()), speed, 0.03) << (kinematic ? "kinematic" : "pin");
    }
}

// With variable frame times (1/50, 1/75, 1/60 s in turn) and a fixed internal step of
// 1/240 s, a 5 kg crate hanging still reads (m + m_rope) g at the end of every frame.
TEST(BulletSubsteps, VariableFrameTimesKeepTheHangingTension) {
    Physics phys;
    const double mass = 5.0;
    btRigidBody& crate = phys.box(btVector3(0.1f, 0.1f, 0.1f), mass, btVector3(0, 0.9f, 0));
    BulletWorld ropes(*phys.world);
    const StringDesc d = rope({0, 2.0, 0}, {0, 1.0, 0}, 20);
    const StringId id = ropes.addString(d);
    ropes.attach(id, 0, btVector3(0, 2.0f, 0));
    ropes.attach(id, -1, crate, btVector3(0, 0.1f, 0));
    const btScalar frames[3] = {btScalar(1) / 50, btScalar(1) / 75, btScalar(1) / 60};
    for (int i = 0; i < 150; ++i) phys.world->stepSimulation(frames[i % 3], 10, btScalar(1) / 240);
    const double weight = (mass + ropeMass(d)) * 9.81;
    for (int i = 0; i < 60; ++i) {
        phys.world->stepSimulation(frames[i % 3], 10, btScalar(1) / 240);
        EXPECT_NEAR(ropes.core().view(id).tension->front(), weight, 0.01 * weight) << "frame " << i;
    }
}

// A pull that tears a rope on the first of four internal steps: at the frame's end the torn
// segment reads 0 and every other one far less, but the peak keeps the tension it tore at
// (at least the rupture load sigma_r pi r^2) and the tear event is there.
TEST(BulletSubsteps, PeakTensionShowsATearOnAnIntermediateStep) {
    Physics phys(0.0);
    BulletWorld ropes(*phys.world);
    StringDesc d = rope({0, 1, 0}, {1, 1, 0}, 10);
    d.tearable = true;
    const StringId id = ropes.addString(d);
    ropes.attach(id, 0, btVector3(0, 1, 0));
    const double rupture_load = d.material.tensile.rupture * kPi * d.radius * d.radius;
    ropes.core().applyForce(id, -1, Vec3(3.0 * rupture_load, 0, 0));  // the core's force: one step only
    ropes.clearEvents();
    phys.world->stepSimulation(btScalar(1) / 60, 10, btScalar(1) / 240);
    const auto v = ropes.core().view(id);
    int torn = -1;
    for (std::size_t j = 0; j < v.segmentCount(); ++j)
        if ((*v.broken)[j]) torn = static_cast<int>(j);
    ASSERT_GE(torn, 0);
    double frame_end = 0.0;
    for (double t : *v.tension) frame_end = std::max(frame_end, t);
    EXPECT_LT(frame_end, rupture_load);
    const std::vector<double> peak = ropes.peakTension(id);
    ASSERT_EQ(peak.size(), v.segmentCount());
    EXPECT_GE(peak[torn], rupture_load * (1.0 - 1e-12));
    const auto& ev = ropes.events();
    EXPECT_EQ(std::count_if(ev.begin(), ev.end(), [](const tearables::Event& e) { return e.type == tearables::EventType::Tear; }), 1);
    ropes.clearPeakTension(id);
    for (double t : ropes.peakTension(id)) EXPECT_EQ(t, 0.0);
}

// The new calls refuse bad input by name and change nothing.
TEST(BulletSubsteps, BadDrivingIsRefused) {
    Physics phys(0.0);
    BulletWorld ropes(*phys.world);
    const StringId id = ropes.addString(rope({0, 1, 0}, {1, 1, 0}, 4));
    ropes.attach(id, 0, btVector3(0, 1, 0));
    auto field = [](auto&& call) {
        try {
            call();
        } catch (const tearables::InvalidInput& e) {
            return e.field();
        }
        return std::string("none");
    };
    EXPECT_EQ(field([&] { ropes.applyForce(StringId{7}, 0, btVector3(1, 0, 0)); }), "string");
    EXPECT_EQ(field([&] { ropes.applyForce(id, 9, btVector3(1, 0, 0)); }), "particle");
    EXPECT_EQ(field([&] { ropes.applyForce(id, 1, btVector3(NAN, 0, 0)); }), "force");
    EXPECT_EQ(field([&] { ropes.movePin(id, -1, btVector3(0, 0, 0)); }), "particle");  // not pinned
    EXPECT_EQ(field([&] { ropes.movePin(id, 0, btVector3(INFINITY, 0, 0)); }), "point");
    EXPECT_EQ(field([&] { ropes.peakTension(StringId{7}); }), "string");
    phys.world->stepSimulation(btScalar(1) / 60, 10, btScalar(1) / 240);
    Vec3 pin;
    ASSERT_TRUE(ropes.core().pinTarget(id, 0, &pin));
    EXPECT_EQ(pin, Vec3(0, 1, 0));
    EXPECT_NEAR(momentum(ropes, id).x(), 0.0, 1e-12);
}

// Loading a snapshot drops what was given for the next stepSimulation (it belonged to the
// state replaced) and starts new peaks: a force given before the load moves nothing.
TEST(BulletSubsteps, LoadingASnapshotDropsPendingDrivingAndPeaks) {
    Physics phys(0.0);
    BulletWorld ropes(*phys.world);
    const StringId id = ropes.addString(rope({0, 1, 0}, {1, 1, 0}, 10));
    ropes.attach(id, 0, btVector3(0, 1, 0));
    std::stringstream saved;
    ropes.saveSnapshot(saved, {});
    ropes.applyForce(id, -1, btVector3(0, 0, 5));
    phys.world->stepSimulation(btScalar(1) / 60, 10, btScalar(1) / 240);
    ASSERT_GT(ropes.peakTension(id).front(), 0.0);
    ropes.applyForce(id, -1, btVector3(0, 0, 5));
    ropes.movePin(id, 0, btVector3(0, 2, 0));
    ropes.loadSnapshot(saved, {});
    for (double t : ropes.peakTension(id)) EXPECT_EQ(t, 0.0);
    phys.world->stepSimulation(btScalar(1) / 60, 10, btScalar(1) / 240);
    EXPECT_EQ(momentum(ropes, id), Vec3::Zero());
    Vec3 pin;
    ASSERT_TRUE(ropes.core().pinTarget(id, 0, &pin));
    EXPECT_EQ(pin, Vec3(0, 1, 0));
}

// A string removed before the step takes its pending force, pin move and peaks with it: the
// next string added (in the same slot) starts clean.
TEST(BulletSubsteps, RemovingAStringDropsWhatWasGivenForIt) {
    Physics phys(0.0);
    BulletWorld ropes(*phys.world);
    const StringId first = ropes.addString(rope({0, 1, 0}, {1, 1, 0}, 10));
    ropes.attach(first, 0, btVector3(0, 1, 0));
    ropes.applyForce(first, -1, btVector3(0, 0, 5));
    ropes.movePin(first, 0, btVector3(0, 2, 0));
    ropes.removeString(first);
    const StringId next = ropes.addString(rope({0, 1, 0}, {1, 1, 0}, 10));
    ASSERT_EQ(next.index, first.index);  // the slot is reused
    ropes.attach(next, 0, btVector3(0, 1, 0));
    phys.world->stepSimulation(btScalar(1) / 60, 10, btScalar(1) / 240);
    EXPECT_EQ(momentum(ropes, next), Vec3::Zero());
    Vec3 pin;
    ASSERT_TRUE(ropes.core().pinTarget(next, 0, &pin));
    EXPECT_EQ(pin, Vec3(0, 1, 0));
    for (double t : ropes.peakTension(next)) EXPECT_EQ(t, 0.0);
}
