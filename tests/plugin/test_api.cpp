// The Bullet-facing API (issue 31): identity (generation-checked ids, user pointers),
// contacts and events a Bullet user can use, and the everyday controls.
#include "tearables/bullet_core.hpp"
#include "tearables/presets.hpp"
#include "tearables/snapshot.hpp"

#include "bullet_fixture.hpp"

#include <btBulletDynamicsCommon.h>
#include <gtest/gtest.h>

#include <algorithm>
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

// --- contacts and events ------------------------------------------------------------------

// A box resting on two parallel ropes between pins (on one it would balance on a knife
// edge): over half a second, the impulses the ropes' contacts report on the box are the
// box's momentum balance, sum J = m (v_end - v_start) + m g T (Bullet integrates gravity;
// the ropes are the only other things it touches). The reported forces are the solve's
// own (its penalties' multipliers and the friction of its last pass), so they meet it to
// the solve's tolerance (measured: 1e-7 of m g T; asserted to 1e-3).
TEST(Contacts, ABoxOnARopeIsHeldByTheReportedForces) {
    Physics p;
    BulletWorld ropes(*p.world);
    const StringId front = ropes.addString(tearables::testing::plainRope({-0.5, 1, 0.03}, {0.5, 1, 0.03}, 40));
    const StringId back = ropes.addString(tearables::testing::plainRope({-0.5, 1, -0.03}, {0.5, 1, -0.03}, 40));
    for (const StringId id : {front, back}) {
        const Vec3 z(0, 0, id == front ? 0.03 : -0.03);
        ropes.attach(id, 0, tearables::toBullet(Vec3(-0.5, 1, 0) + z));
        ropes.attach(id, -1, tearables::toBullet(Vec3(0.5, 1, 0) + z));
    }
    const double m = 2.0, g = 9.81, h = 1.0 / 240.0;
    btRigidBody& box = p.box(btVector3(0.05f, 0.05f, 0.05f), m, btVector3(0, 1.06f, 0));
    box.setActivationState(DISABLE_DEACTIVATION);
    int called = 0;
    std::size_t reported = 0;
    ropes.setContactCallback([&](const tearables::BulletContact& c) {
        ++called;
        EXPECT_EQ(c.body, &box);
        EXPECT_TRUE(c.string == front || c.string == back);
    });
    p.step(240, h);  // 1 s: settled
    ASSERT_TRUE(ropes.lastError().empty()) << ropes.lastError();
    const btVector3 v0 = box.getLinearVelocity();
    const int steps = 120;
    Vec3 impulse = Vec3::Zero();
    for (int i = 0; i < steps; ++i) {
        called = 0;
        p.step(1, h);
        reported = ropes.contacts().size();
        EXPECT_EQ(static_cast<std::size_t>(called), reported);
        for (const auto& c : ropes.contacts()) {
            EXPECT_GT(c.normal_force, 0.0);
            EXPECT_NEAR(c.normal.length(), 1.0, 1e-5);
            EXPECT_GE(c.s, 0.0);
            EXPECT_LE(c.s, 1.0);
            EXPECT_NEAR(static_cast<double>(c.impulse.y()), static_cast<double>(c.force.y()) * h, 1e-6 * std::abs(static_cast<double>(c.force.y())) * h);  // float
            // On the box's underside.
            EXPECT_NEAR(static_cast<double>(c.position.y()), static_cast<double>(box.getCenterOfMassPosition().y()) - 0.05, 0.01);
            impulse += tearables::toCore(c.impulse);
        }
    }
    ASSERT_GT(reported, 0u);
    const double T = steps * h;
    const Vec3 expected = m * (tearables::toCore(box.getLinearVelocity()) - tearables::toCore(v0)) + Vec3(0, m * g * T, 0);
    EXPECT_NEAR(impulse.y(), expected.y(), 1e-3 * m * g * T);
    EXPECT_NEAR(impulse.x(), expected.x(), 1e-3 * m * g * T);
    EXPECT_NEAR(impulse.z(), expected.z(), 1e-3 * m * g * T);
}

// A rope hanging a crate heavier than its rupture load tears once: the event carries the
// load it tore at (at or above the rupture load), the torn segment's middle and the crate
// (the piece it was part of hung it); the callback sees the same event.
TEST(Events, ATearCarriesItsForcePositionAndBody) {
    Physics p;
    BulletWorld ropes(*p.world);
    StringDesc d = StringDesc::straight({0, 2, 0}, {0, 1, 0}, 10);
    d.material.variation = 0.0;
    const double rupture_load = d.material.tensile.rupture * 3.14159265358979323846 * d.radius * d.radius;  // 1005 N
    const StringId rope = ropes.addString(d);
    ropes.attach(rope, 0, btVector3(0, 2, 0));
    btRigidBody& crate = p.box(btVector3(0.1f, 0.1f, 0.1f), 150.0, btVector3(0, 0.9f, 0));  // 1471 N
    ropes.attach(rope, -1, crate, btVector3(0, 0.1f, 0));
    std::vector<tearables::BulletEvent> seen;
    ropes.setTearCallback([&](const tearables::BulletEvent& e) { seen.push_back(e); });
    for (int i = 0; i < 120 && seen.empty(); ++i) p.step(1, 1.0 / 240.0);
    ASSERT_EQ(seen.size(), 1u);
    const tearables::BulletEvent& e = seen.front();
    EXPECT_EQ(e.type, tearables::EventType::Tear);
    EXPECT_EQ(e.cause, tearables::EventCause::Tension);
    EXPECT_EQ(e.string, rope);
    EXPECT_GE(e.force, rupture_load * (1.0 - 1e-12));
    EXPECT_EQ(e.body, &crate);
    const auto v = ropes.core().view(rope);
    ASSERT_EQ((*v.broken)[e.segment], 1);
    const Vec3 middle = 0.5 * ((*v.positions)[e.segment] + (*v.positions)[e.segment + 1]);
    EXPECT_LT((tearables::toCore(e.position) - middle).norm(), 1e-6);
    int tears = 0;
    for (const auto& o : ropes.events())
        if (o.type == tearables::EventType::Tear) {
            ++tears;
            EXPECT_EQ(o.force, e.force);
            EXPECT_EQ(o.body, e.body);
        }
    EXPECT_EQ(tears, 1);
}

// A rope loaded past its yield everywhere at once: one yield event per string and internal
// step, counting the core's per-segment events of that step, with the worst stress.
TEST(Events, YieldsAreOneEventPerStringAndStep) {
    Physics p;
    BulletWorld ropes(*p.world);
    StringDesc d = StringDesc::straight({0, 2, 0}, {0, 1, 0}, 20);
    d.material.tensile.rupture = 4e8;  // yields (at 503 N), never tears
    const StringId rope = ropes.addString(d);
    ropes.attach(rope, 0, btVector3(0, 2, 0));
    btRigidBody& crate = p.box(btVector3(0.1f, 0.1f, 0.1f), 60.0, btVector3(0, 0.9f, 0));  // 589 N
    ropes.attach(rope, -1, crate, btVector3(0, 0.1f, 0));
    int core_yields = 0, merged = 0;
    for (int i = 0; i < 120; ++i) {
        p.step(1, 1.0 / 240.0);  // one internal step: core().events() are that step's
        int here = 0;
        double worst = 0.0;
        for (const auto& e : ropes.core().events())
            if (e.type == tearables::EventType::Yield) {
                ++here;
                worst = std::max(worst, e.stress);
            }
        int events = 0;
        for (const auto& e : ropes.events())
            if (e.type == tearables::EventType::Yield) {
                ++events;
                EXPECT_EQ(e.count, here);
                EXPECT_EQ(e.stress, worst);
                EXPECT_NEAR(e.force, worst * 3.14159265358979323846 * d.radius * d.radius, 1e-9 * e.force);
            }
        EXPECT_EQ(events, here > 0 ? 1 : 0);
        core_yields += here;
        merged += events;
        ropes.clearEvents();
    }
    EXPECT_EQ(core_yields, 20);  // every segment yields once
    EXPECT_LT(merged, core_yields);
}

// --- controls -----------------------------------------------------------------------------

// The C++ preset is the scene's: the one lookup both use.
TEST(Controls, MaterialPresetsByName) {
    const tearables::Material m = tearables::materialPreset("rubber_cord");
    const tearables::MaterialPreset* p = tearables::findMaterialPreset("rubber_cord");
    ASSERT_NE(p, nullptr);
    EXPECT_EQ(m.tensile.young, p->material.tensile.young);
    EXPECT_EQ(m.tensile.rupture, p->material.tensile.rupture);
    EXPECT_EQ(m.torsion.modulus, p->material.torsion.modulus);
    EXPECT_EQ(m.variation, p->material.variation);
    std::string problem;
    EXPECT_EQ(refusal([] { tearables::materialPreset("kevlar"); }, &problem), "preset");
    EXPECT_NE(problem.find("unknown material preset \"kevlar\""), std::string::npos) << problem;
    EXPECT_NE(problem.find("nylon_rope"), std::string::npos) << problem;
}

// The shape is the catenary of that length through both points (closed form, Irvine ch. 1),
// and it is where the rope settles: after 2 s pinned at both ends its lowest point is within
// 1% of the catenary's sag, and the first step moves no particle by more than 1% of it.
TEST(Controls, BetweenBuildsTheHangingShape) {
    const Vec3 a(0, 1, 0), b(1, 1.2, 0);
    const double L = 1.3;
    StringDesc d = StringDesc::between(a, b, L, 40);
    ASSERT_EQ(d.points.size(), 41u);
    EXPECT_EQ(d.points.front(), a);
    EXPECT_EQ(d.points.back(), b);
    double chords = 0.0, lowest = 1e9;
    for (std::size_t i = 1; i < d.points.size(); ++i) chords += (d.points[i] - d.points[i - 1]).norm();
    for (const Vec3& p : d.points) lowest = std::min(lowest, p.y());
    EXPECT_LT(chords, L);
    EXPECT_GT(chords, L * (1.0 - 1e-3));
    // The catenary's own lowest point: c from sqrt(L^2 - V^2) = 2 c sinh(H / 2c), by bisection.
    const double H = 1.0, V = 0.2, r = std::sqrt(L * L - V * V);
    double lo = 1e-3, hi = 10.0;
    for (int k = 0; k < 200; ++k) {
        const double c = 0.5 * (lo + hi);
        (2.0 * c * std::sinh(H / (2.0 * c)) > r ? lo : hi) = c;
    }
    const double c = 0.5 * (lo + hi);
    const double xm = 0.5 * H - c * std::atanh(V / L);
    ASSERT_GT(xm, 0.0);
    const double bottom = a.y() + c * (1.0 - std::cosh(xm / c));
    const double sag = a.y() - bottom;
    EXPECT_NEAR(lowest, bottom, 0.005 * sag);  // the particles near the bottom, 1/40 apart

    Physics p;
    BulletWorld ropes(*p.world);
    d.material.variation = 0.0;
    d.tearable = false;
    const StringId rope = ropes.addString(d);
    ropes.attach(rope, 0, tearables::toBullet(a));
    ropes.attach(rope, -1, tearables::toBullet(b));
    const std::vector<Vec3> start = *ropes.core().view(rope).positions;
    p.step(1, 1.0 / 240.0);
    double jump = 0.0;
    for (std::size_t i = 0; i < start.size(); ++i) jump = std::max(jump, ((*ropes.core().view(rope).positions)[i] - start[i]).norm());
    EXPECT_LT(jump, 0.01 * sag);
    p.step(479, 1.0 / 240.0);
    double settled = 1e9;
    for (const Vec3& x : *ropes.core().view(rope).positions) settled = std::min(settled, x.y());
    EXPECT_NEAR(settled, bottom, 0.01 * sag);
    std::string problem;
    EXPECT_EQ(refusal([&] { StringDesc::between(a, b, 0.9, 10); }, &problem), "length");
    EXPECT_EQ(refusal([&] { StringDesc::between(a, a, 1.0, 10); }), "b");
    EXPECT_EQ(refusal([&] { StringDesc::between(a, a + Vec3(0, 1, 0), 2.0, 10); }), "b");
    EXPECT_EQ(refusal([&] { StringDesc::between(a, b, std::nan(""), 10); }), "length");
    EXPECT_EQ(refusal([&] { StringDesc::between(Vec3(std::nan(""), 0, 0), b, L, 10); }), "a");
    EXPECT_EQ(refusal([&] { StringDesc::between(a, b, L, 0); }), "segments");
    EXPECT_EQ(StringDesc::between(a, b, (b - a).norm(), 4).points[2], 0.5 * (a + b));
}

// A crate hung at s = 0.37 of a slack rope's length between two pins hangs there: the two
// pieces, pulled straight by its weight (the rope weighs 0.2% of it), are 0.37 L and 0.63 L
// long, to the rope's stretch under the load (T / EA: 0.22% and 0.12%), once the crate's
// swing has died out.
TEST(Controls, AMassHungAtAFractionOfTheLengthHangsThere) {
    const Vec3 a(0, 2, 0), b(1, 2, 0);
    const double L = 1.4;
    StringDesc d = StringDesc::between(a, b, L, 30);
    d.material.variation = 0.0;
    d.tearable = false;
    const int k = tearables::insertParticle(d, 0.37);
    ASSERT_EQ(d.points.size(), 32u);
    double along = 0.0;
    for (int i = 1; i <= k; ++i) along += (d.points[i] - d.points[i - 1]).norm();
    EXPECT_NEAR(along, 0.37 * L, 0.37 * L * 1e-3);  // chords of the catenary's arcs
    EXPECT_EQ(tearables::insertParticle(d, 0.37), k);  // already there
    Physics p;
    BulletWorld ropes(*p.world);
    const StringId rope = ropes.addString(d);
    ropes.attach(rope, 0, tearables::toBullet(a));
    ropes.attach(rope, -1, tearables::toBullet(b));
    btRigidBody& crate = p.box(btVector3(0.05f, 0.05f, 0.05f), 10.0, tearables::toBullet(d.points[k]));
    crate.setActivationState(DISABLE_DEACTIVATION);
    crate.setDamping(0.9f, 0.9f);  // its swing along the ellipse |x - a| + |x - b| = L dies out
    ropes.attach(rope, k, crate, btVector3(0, 0, 0));
    p.step(720, 1.0 / 240.0);
    ASSERT_TRUE(ropes.lastError().empty()) << ropes.lastError();
    const Vec3 at = (*ropes.core().view(rope).positions)[k];
    EXPECT_NEAR((at - a).norm(), 0.37 * L, 0.005 * 0.37 * L);
    EXPECT_NEAR((b - at).norm(), 0.63 * L, 0.005 * 0.63 * L);
    EXPECT_LT((tearables::toCore(crate.getCenterOfMassPosition()) - at).norm(), 1e-3);
    StringDesc bad = d;
    EXPECT_EQ(refusal([&] { tearables::insertParticle(bad, 1.5); }), "s");
    EXPECT_EQ(refusal([&] { tearables::insertParticle(bad, std::nan("")); }), "s");
    EXPECT_EQ(bad.points.size(), d.points.size());
}

// Initial velocities: a free rope in zero gravity given a velocity per particle carries
// their momentum sum m_i v_i, and keeps it (nothing acts on it from outside).
TEST(Controls, InitialVelocitiesGiveTheirMomentum) {
    Physics p(0.0);
    BulletWorld ropes(*p.world);
    StringDesc d = StringDesc::straight({0, 1, 0}, {1, 1, 0}, 20);
    const StringId rope = ropes.addString(d);
    std::vector<btVector3> v;
    const auto view = ropes.core().view(rope);
    Vec3 expected = Vec3::Zero();
    for (std::size_t i = 0; i < view.particleCount(); ++i) {
        // A drift and a spin about the middle: v = V + w x (x - c).
        const Vec3 vi = Vec3(0.3, -0.2, 0.1) + Vec3(0, 0, 2.0).cross((*view.positions)[i] - Vec3(0.5, 1, 0));
        v.push_back(tearables::toBullet(vi));
        expected += (*view.masses)[i] * tearables::toCore(v.back());
    }
    ropes.setVelocities(rope, v);
    Vec3 now = Vec3::Zero();
    for (std::size_t i = 0; i < view.particleCount(); ++i) now += (*view.masses)[i] * (*view.velocities)[i];
    EXPECT_LT((now - expected).norm(), 1e-12);
    p.step(60, 1.0 / 60.0);
    Vec3 later = Vec3::Zero();
    const auto after = ropes.core().view(rope);
    for (std::size_t i = 0; i < after.particleCount(); ++i) later += (*after.masses)[i] * (*after.velocities)[i];
    EXPECT_LT((later - expected).norm(), 1e-6 * expected.norm());
    EXPECT_EQ(refusal([&] { ropes.setVelocities(rope, std::vector<btVector3>(3)); }), "velocities");
    std::vector<btVector3> fast(view.particleCount(), btVector3(0, 0, 0));
    fast[4] = btVector3(1e4f, 0, 0);
    const std::vector<Vec3> before = *after.velocities;
    EXPECT_EQ(refusal([&] { ropes.setVelocities(rope, fast); }), "velocities[4]");
    EXPECT_EQ(*ropes.core().view(rope).velocities, before);
}

// A winch at a rope's pinned top hauls a hanging crate in at speed v: once the start's
// transient has passed the crate rises at v (to 2%: the segment being wound is stiffer
// as it shortens), and the rope holds it with m (g + a) = m g (to 2%). With
// RestMass::Add the rope taken in takes its mass, rho pi r^2 per metre, with it.
TEST(Controls, AWinchHaulsAHangingMassAtItsSpeed) {
    Physics p;
    BulletWorld ropes(*p.world);
    StringDesc d = tearables::testing::plainRope({0, 2, 0}, {0, 1, 0}, 20);
    const StringId rope = ropes.addString(d);
    ropes.attach(rope, 0, btVector3(0, 2, 0));
    const double m = 5.0, g = 9.81, h = 1.0 / 240.0, v = 0.1;
    btRigidBody& crate = p.box(btVector3(0.05f, 0.05f, 0.05f), m, btVector3(0, 0.95f, 0));
    crate.setActivationState(DISABLE_DEACTIVATION);
    ropes.attach(rope, -1, crate, btVector3(0, 0.05f, 0));
    p.step(240, h);
    ropes.reel(rope, 0, -v);
    p.step(240, h);  // 1 s: the transient
    const double y0 = static_cast<double>(crate.getCenterOfMassPosition().y());
    double tension = 0.0;
    const int steps = 240;
    for (int i = 0; i < steps; ++i) {
        p.step(1, h);
        tension += ropes.core().view(rope).tension->back() / steps;
    }
    ASSERT_TRUE(ropes.lastError().empty()) << ropes.lastError();
    const double rise = static_cast<double>(crate.getCenterOfMassPosition().y()) - y0;
    EXPECT_NEAR(rise / (steps * h), v, 0.02 * v);
    EXPECT_NEAR(tension, m * g, 0.02 * m * g);
    EXPECT_TRUE(ropes.core().isAttached(rope, 3));  // 0.2 m wound: the first segments on the drum

    const StringId other = ropes.addString(tearables::testing::plainRope({1, 2, 0}, {1, 1, 0}, 20));
    ropes.attach(other, 0, btVector3(1, 2, 0));
    auto mass = [&](StringId id) {
        double sum = 0.0;
        for (double x : *ropes.core().view(id).masses) sum += x;
        return sum;
    };
    const double before = mass(other);
    tearables::reel(ropes.core(), other, 0, -0.12, tearables::RestMass::Add);
    const double area = 3.14159265358979323846 * d.radius * d.radius;
    EXPECT_NEAR(before - mass(other), d.density * area * 0.12, 1e-12);
    EXPECT_TRUE(ropes.core().isAttached(other, 2));  // 0.12 m: two segments of 0.05 m wound
    EXPECT_FALSE(ropes.core().isAttached(other, 3));
    EXPECT_EQ(refusal([&] { ropes.reel(other, 1, -0.1); }), "end");
    EXPECT_EQ(refusal([&] { ropes.reel(other, -1, -0.1); }), "end");  // not pinned
    EXPECT_EQ(refusal([&] { ropes.reel(other, 0, std::nan("")); }), "speed");
    EXPECT_EQ(refusal([&] { tearables::setRestLength(ropes.core(), other, 40, 0.1); }), "segment");
    EXPECT_EQ(refusal([&] { tearables::setRestLength(ropes.core(), other, 4, 0.0); }), "length");
}

}  // namespace
