// Strings against Bullet rigid bodies, two ways (issue 4): Bullet's narrow phase finds
// capsule contacts, the string's Newton solve resolves them together with its tension,
// and the bodies feel the reaction.
#include "tearables/bullet_core.hpp"

#include "bullet_fixture.hpp"
#include "collision/capsule.hpp"

#include <btBulletDynamicsCommon.h>
#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <sstream>
#include <vector>

namespace {

using tearables::BulletWorld;
using tearables::StringDesc;
using tearables::StringId;
using tearables::Vec3;

using tearables::testing::Physics;

/// Rigid contacts are on by default; the tests say so explicitly.
tearables::WorldSettings withContacts() {
    tearables::WorldSettings s;
    s.rigid_contacts = true;
    return s;
}

StringDesc rope(const Vec3& from, const Vec3& to, int segments, double radius) {
    StringDesc d = StringDesc::straight(from, to, segments);
    d.material.variation = 0.0;
    d.radius = radius;
    d.bending = 0.0;
    return d;
}

/// The lowest point of a string.
double lowest(const BulletWorld& ropes, StringId id) {
    double y = 1e9;
    for (const Vec3& p : *ropes.core().view(id).positions) y = std::min(y, p.y());
    return y;
}

}  // namespace

// A 5 kg crate dropped from 2 m onto a horizontal rope clamped at both ends is caught: the
// rope stops it (its velocity turns upward) before it passes below the rope, and the
// rope's tension peaks at the impact. (A crate on a single rope is balanced on a knife
// edge, so afterwards it may tip off the side: the test watches the catch.)
TEST(RigidCollision, CrateDroppedOnARopeIsCaught) {
    Physics phys;
    btRigidBody& crate = phys.add(std::make_unique<btBoxShape>(btVector3(0.15f, 0.15f, 0.15f)), 5.0, btVector3(0, 3.0f, 0));
    BulletWorld ropes(*phys.world, withContacts());
    StringDesc d = rope({-1, 1, 0}, {1, 1, 0}, 40, 0.005);
    d.tearable = false;
    const StringId id = ropes.addString(d);
    ropes.attach(id, 0, btVector3(-1, 1, 0));
    ropes.attach(id, -1, btVector3(1, 1, 0));
    double peak = 0.0, peak_time = 0.0, first_contact = -1.0, impact_speed = 0.0;
    bool stopped = false;
    for (int i = 0; i < 300 && (first_contact < 0 || i * 0.01 < first_contact + 0.5); ++i) {
        const double speed = -crate.getLinearVelocity().y();
        phys.step(1);
        const double t = ropes.core().view(id).tension->front();
        if (t > peak) {
            peak = t;
            peak_time = i * 0.01;
        }
        if (first_contact < 0 && !ropes.core().lastContacts().empty()) {
            first_contact = i * 0.01;
            impact_speed = speed;
        }
        if (first_contact >= 0 && !stopped) {
            // Until it stops, the crate stays above the rope's lowest point.
            EXPECT_GT(crate.getCenterOfMassPosition().y() - 0.15, lowest(ropes, id) - 0.01) << i;
            stopped = crate.getLinearVelocity().y() >= 0.0f;
        }
    }
    ASSERT_GT(first_contact, 0.0);
    EXPECT_GT(impact_speed, 5.0);  // about sqrt(2 g 1.85 m)
    EXPECT_TRUE(stopped);
    EXPECT_NEAR(peak_time, first_contact, 0.15);  // the peak comes with the impact
    EXPECT_GT(peak, 10.0 * 5.0 * 9.81);            // an impact, far above the crate's weight
}

// With a rupture stress set low enough, the rope tears at the impact instead.
TEST(RigidCollision, WeakRopeTearsAtTheImpact) {
    Physics phys;
    btRigidBody& crate = phys.add(std::make_unique<btBoxShape>(btVector3(0.15f, 0.15f, 0.15f)), 5.0, btVector3(0, 3.0f, 0));
    BulletWorld ropes(*phys.world, withContacts());
    StringDesc d = rope({-1, 1, 0}, {1, 1, 0}, 40, 0.005);
    d.material.tensile.yield = 1e6;
    d.material.tensile.rupture = 3e6;  // 235 N on 5 mm radius: more than the crate's weight at rest
    const StringId id = ropes.addString(d);
    ropes.attach(id, 0, btVector3(-1, 1, 0));
    ropes.attach(id, -1, btVector3(1, 1, 0));
    int tears = 0;
    for (int i = 0; i < 300; ++i) {
        phys.step(1);
        for (const auto& e : ropes.events()) tears += e.type == tearables::EventType::Tear;
        ropes.clearEvents();
    }
    EXPECT_GE(tears, 1);
    EXPECT_LT(crate.getCenterOfMassPosition().y(), 0.5f);  // fell through
}

// A rope lying across the top of a static box, straight along it or at an angle to its
// edges, comes to rest on it. Where a segment lies on the face, the face carries it at
// the ends of the part of it over the face: each such contact has the face's normal to
// rounding, and a segment over the face's inside is carried at its two particles (Bullet's
// GJK answers with one closest point anywhere along it, which changes from step to step,
// and a segment carried there rocks about it and chatters: docs/island-baseline.md).
// At rest means below 1 mm/s, the speed of a 10 um settling a step.
TEST(RigidCollision, RopeAcrossABoxLiesStillOnItsFace) {
    for (const double turn : {0.0, 0.3}) {
        Physics phys;
        btRigidBody& box = phys.add(std::make_unique<btBoxShape>(btVector3(0.2f, 0.2f, 0.2f)), 0.0, btVector3(0, 1.0f, 0));
        btTransform pose = box.getWorldTransform();
        pose.setRotation(btQuaternion(btVector3(0, 1, 0), static_cast<btScalar>(turn)));
        box.setWorldTransform(pose);
        BulletWorld ropes(*phys.world, withContacts());
        const double radius = 0.005;
        const StringId id = ropes.addString(rope({-0.3, 1.2 + 2 * radius, 0.05}, {0.3, 1.2 + 2 * radius, 0.05}, 24, radius));
        phys.step(300);
        const auto view = ropes.core().view(id);
        double fastest = 0.0;
        for (const Vec3& v : *view.velocities) fastest = std::max(fastest, v.norm());
        // Straight along the box the rope is at rest; across its edges at an angle, its
        // hanging ends still swing a little (measured 0.3-4 mm/s after 3 s).
        EXPECT_LT(fastest, turn == 0.0 ? 1e-3 : 1e-2) << "turn " << turn;
        // Over the face's inside: both particles within the top face, a radius from its edges.
        auto over = [&](std::size_t p) {
            const btVector3 local = pose.inverse() * tearables::toBullet((*view.positions)[p]);
            return std::abs(local.x()) < 0.2 - radius && std::abs(local.z()) < 0.2 - radius;
        };
        int on_face = 0;
        for (const tearables::BulletContact& c : ropes.contacts()) {
            const auto j = static_cast<std::size_t>(c.segment);
            if (over(j) && over(j + 1)) {
                EXPECT_NEAR(c.normal.y(), 1.0, 1e-6) << "turn " << turn << ", segment " << c.segment;
                EXPECT_TRUE(c.s == 0.0 || c.s == 1.0) << "turn " << turn << ", segment " << c.segment << " at s " << c.s;
                ++on_face;
            }
        }
        EXPECT_GE(on_face, 10) << "turn " << turn;  // 0.4 m of face under 25 mm segments
    }
}

// A rope draped over a static box rests on it and does not slide through its edges.
TEST(RigidCollision, RopeDrapedOverABoxRestsOnIt) {
    Physics phys;
    phys.add(std::make_unique<btBoxShape>(btVector3(0.2f, 0.2f, 0.2f)), 0.0, btVector3(0, 1.0f, 0));
    BulletWorld ropes(*phys.world, withContacts());
    StringDesc d = rope({-0.6, 1.25, 0}, {0.6, 1.25, 0}, 48, 0.005);
    d.damping = 0.5;
    const StringId id = ropes.addString(d);
    for (int i = 0; i < 400; ++i) phys.step(1);
    const auto& x = *ropes.core().view(id).positions;
    // The middle rests on top of the box (y = 1.2 + radius); nothing inside the box.
    EXPECT_NEAR(x[24].y(), 1.205, 0.01);
    for (const Vec3& p : x) {
        const bool inside = std::abs(p.x()) < 0.2 - 1e-3 && std::abs(p.y() - 1.0) < 0.2 - 1e-3 && std::abs(p.z()) < 0.2 - 1e-3;
        EXPECT_FALSE(inside) << p.transpose();
    }
    // Both ends hang down the sides.
    EXPECT_LT(x.front().y(), 1.0);
    EXPECT_LT(x.back().y(), 1.0);
}

// A rope laid straight on the ground comes to rest on it and stays, every particle held
// up: the ground carries its weight (the normal forces sum to m g within 1%), no particle
// sinks into the ground by more than the contacts' give (m g / k_c per particle, microns;
// 20 um asked), and none moves faster than 1 mm/s (a particle the step left without a
// contact would fall g h = 4 cm/s in an internal step and be pushed back at the next: such
// a rope chattered at 6 cm/s with particles 0.25 mm deep). Stepped as games step.
TEST(RigidCollision, RopeLyingOnTheGroundComesToRest) {
    Physics phys;
    phys.add(std::make_unique<btStaticPlaneShape>(btVector3(0, 1, 0), 0.0f), 0.0, btVector3(0, 0, 0));
    BulletWorld ropes(*phys.world, withContacts());
    const double r = 0.006;
    const StringId id = ropes.addString(rope({-0.5, r + 0.001, 0}, {0.5, r + 0.001, 0}, 64, r));
    double mass = 0.0;
    for (double m : *ropes.core().view(id).masses) mass += m;
    for (int frame = 0; frame < 60; ++frame) phys.world->stepSimulation(1.0f / 60.0f, 10, 1.0f / 240.0f);
    for (int frame = 0; frame < 15; ++frame) {
        phys.world->stepSimulation(1.0f / 60.0f, 10, 1.0f / 240.0f);
        const tearables::StringView v = ropes.core().view(id);
        for (std::size_t p = 0; p < v.particleCount(); ++p) {
            EXPECT_GT((*v.positions)[p].y(), r - 20e-6) << "particle " << p << ", frame " << frame;
            EXPECT_LT((*v.velocities)[p].norm(), 1e-3) << "particle " << p << ", frame " << frame;
        }
        double carried = 0.0;
        for (const tearables::BulletContact& c : ropes.contacts()) carried += c.normal_force * c.normal.y();
        EXPECT_NEAR(carried, mass * 9.81, 0.01 * mass * 9.81) << "frame " << frame;
    }
}

// In zero gravity a free rope hit by a free box conserves linear momentum within 2% and
// never gains kinetic energy.
TEST(RigidCollision, FreeRopeHitByABoxConservesMomentum) {
    Physics phys(0.0);
    btRigidBody& box = phys.add(std::make_unique<btBoxShape>(btVector3(0.1f, 0.1f, 0.1f)), 1.0, btVector3(0, 0.5f, 0));
    box.setLinearVelocity(btVector3(0, -2.0f, 0));
    box.setActivationState(DISABLE_DEACTIVATION);
    BulletWorld ropes(*phys.world, withContacts());
    StringDesc d = rope({-0.5, 0, 0}, {0.5, 0, 0}, 40, 0.005);
    d.tearable = false;
    const StringId id = ropes.addString(d);
    auto momentum = [&] {
        Vec3 p = tearables::toCore(box.getLinearVelocity()) * 1.0;
        const auto v = ropes.core().view(id);
        for (std::size_t i = 0; i < v.particleCount(); ++i) p += (*v.masses)[i] * (*v.velocities)[i];
        return p;
    };
    auto energy = [&] {  // kinetic: the box's translation and rotation, the rope's particles
        double e = tearables::testing::kineticEnergy(box);
        const auto v = ropes.core().view(id);
        for (std::size_t i = 0; i < v.particleCount(); ++i) e += 0.5 * (*v.masses)[i] * (*v.velocities)[i].squaredNorm();
        return e;
    };
    const Vec3 before = momentum();
    const double energy_before = energy();
    bool touched = false;
    for (int i = 0; i < 60; ++i) {
        phys.step(1);
        touched = touched || !ropes.core().lastContacts().empty();
        // No energy from nowhere: the rope wrapping the box (and touching itself) only
        // takes energy (within 1% of the step's discretisation).
        ASSERT_LT(energy(), 1.01 * energy_before) << "step " << i;
    }
    ASSERT_TRUE(touched);
    const Vec3 after = momentum();
    EXPECT_NEAR(after.y(), before.y(), 0.02 * std::abs(before.y()));
    EXPECT_LT(std::abs(after.x()), 0.02 * std::abs(before.y()));
    // The box was slowed by the rope (two-way).
    EXPECT_GT(box.getLinearVelocity().y(), -1.99f);
}

// Fast motion: a crate at 10 m/s does not pass through a rope of 5 mm radius at
// dt = 0.01 s (it moves 20 rope diameters per step). Contacts are speculative: found
// between the start-of-step poses within the distance both can travel, so the solve
// keeps the rope on its side (plugin/bullet_world.cpp). The rope stops the crate within
// two steps; then the crate, balanced on one rope like a knife edge, rolls off it. At no
// step does the rope's axis get deeper into the crate than one radius (the closest of 11
// points per segment to the box; measured: 2.4 mm at the worst step, when the crate
// starts to roll at 0.7 m/s, then clear by 0.9 r), and a crate below the rope at the end
// went around it (beside it by more than its half width), not through.
TEST(RigidCollision, FastCrateDoesNotTunnelThroughARope) {
    Physics phys(0.0);
    const double half = 0.05, radius = 0.005;
    btRigidBody& crate = phys.add(std::make_unique<btBoxShape>(btVector3(0.05f, 0.05f, 0.05f)), 2.0, btVector3(0, 0.5f, 0));
    crate.setLinearVelocity(btVector3(0, -10.0f, 0));
    crate.setActivationState(DISABLE_DEACTIVATION);
    BulletWorld ropes(*phys.world, withContacts());
    StringDesc d = rope({-0.5, 0, 0}, {0.5, 0, 0}, 40, radius);
    d.tearable = false;
    // Elastic to the end: stopping 100 J within a few centimetres takes tens of kN, far past
    // nylon's yield (a real rope yields and lets the crate farther); this is about contact.
    d.material.tensile.yield = 1e12;
    d.material.tensile.rupture = 2e12;
    const StringId id = ropes.addString(d);
    ropes.attach(id, 0, btVector3(-0.5f, 0, 0));
    ropes.attach(id, -1, btVector3(0.5f, 0, 0));
    // Signed distance of a world point to the crate's box (negative inside).
    auto boxDistance = [&](const Vec3& p) {
        const btVector3 local = crate.getWorldTransform().inverse() * tearables::toBullet(p);
        const Vec3 q = tearables::toCore(local).cwiseAbs() - Vec3::Constant(half);
        return q.cwiseMax(0.0).norm() + std::min(q.maxCoeff(), 0.0);
    };
    int first_contact = -1;
    double slowest = -10.0;
    for (int i = 0; i < 100; ++i) {
        phys.step(1);
        if (first_contact < 0 && !ropes.core().lastContacts().empty()) first_contact = i;
        if (first_contact >= 0 && i <= first_contact + 2) slowest = std::max(slowest, static_cast<double>(crate.getLinearVelocity().y()));
        const auto& x = *ropes.core().view(id).positions;
        double closest = 1e9;
        for (std::size_t j = 0; j + 1 < x.size(); ++j)
            for (int k = 0; k <= 10; ++k) closest = std::min(closest, boxDistance(x[j] + (x[j + 1] - x[j]) * (k / 10.0)));
        ASSERT_GT(closest, -radius) << "step " << i;
    }
    ASSERT_GE(first_contact, 0);
    EXPECT_GT(slowest, -1.0);  // stopped by the rope within two steps of the impact
    const btVector3 c = crate.getCenterOfMassPosition();
    if (c.y() < (*ropes.core().view(id).positions)[20].y()) EXPECT_GT(std::abs(c.z()), half);
}

// Friction with a body (in the contact solve): a rope over a fixed sphere (its great
// circle, the same as a cylinder's), the ends hanging 0.2 m and 0.4 m down its sides.
// - Frictionless, the long end runs down as the equation of motion of a rope over a
//   smooth pulley says: x'' = g (dL + 2x) / L, so x(t) = dL/2 (cosh(sqrt(2g/L) t) - 1)
//   (dL = 0.2 m the difference of the hanging lengths, L the rope's length).
// - With friction it holds while the long side's weight is within what friction can hold.
//   The arc's own weight presses it too (a rope of weight w per length on a drum of radius
//   a, theta from the short side's tangent point over the top: N = T / a + w sin(theta),
//   and at the verge of slipping dT/dtheta = w a cos(theta) + mu (T + w a sin(theta))),
//   so the largest pull at the far end is T(pi) = (T0 - A) e^(mu pi) - A with
//   A = -2 mu w a / (1 + mu^2), T0 = 0.2 w (Euler-Eytelwein plus the arc's weight). For
//   a = 0.105 m: mu = 0.3 holds up to 0.72 w (held: the long side weighs 0.4 w); mu = 0.15
//   holds 0.40 w, the verge itself (so not a case to test); mu = 0.1 holds 0.32 w
//   (slides).
// (A cylinder: Bullet's GJK gives capsule-cylinder normals a few milliradians off the
// radial direction, along the axis too; a rope laid on a cylinder then creeps along it.)
TEST(RigidCollision, RopeOverASphereSlidesAsAPulleyAndHoldsByCapstanFriction) {
    const double r = 0.1 + 0.005;
    std::vector<Vec3> points;
    for (int i = 0; i <= 20; ++i) points.push_back({-r, 1.0 - 0.2 + 0.01 * i, 0});
    for (int i = 1; i < 32; ++i) {
        const double a = 3.14159265358979 * (1.0 - i / 32.0);
        points.push_back({r * std::cos(a), 1.0 + r * std::sin(a), 0});
    }
    for (int i = 0; i <= 40; ++i) points.push_back({r, 1.0 - 0.01 * i, 0});
    double length = 0.0;
    for (std::size_t i = 1; i < points.size(); ++i) length += (points[i] - points[i - 1]).norm();
    // How far the long end ran down in `steps` steps.
    auto run = [&](double mu, int steps) {
        Physics phys;
        btRigidBody& ball = phys.add(std::make_unique<btSphereShape>(0.1f), 0.0, btVector3(0, 1.0f, 0));
        ball.setFriction(static_cast<btScalar>(mu));
        BulletWorld ropes(*phys.world, withContacts());
        StringDesc d;
        d.points = points;
        d.material.variation = 0.0;
        d.radius = 0.005;
        d.bending = 0.0;
        d.tearable = false;
        const StringId id = ropes.addString(d);
        const double start = ropes.core().view(id).positions->back().y();
        for (int i = 0; i < steps; ++i) phys.step(1);
        return start - ropes.core().view(id).positions->back().y();
    };
    const double t = 0.3;
    const double expected = 0.1 * (std::cosh(std::sqrt(2.0 * 9.81 / length) * t) - 1.0);
    // The implicit step's numerical damping keeps the frictionless run under the closed
    // form (docs/island-plan.md, item 4, has the figures). Held is measured against
    // sliding: friction sticks below a slip of kRigidSlip of the rope's radius a step
    // (contact_rows.cpp), so a held rope may creep by micrometres a step. Held means 30x
    // less than where friction cannot hold.
    EXPECT_NEAR(run(0.0, 30), expected, 0.15 * expected);
    const double held = run(0.3, 100), slid = run(0.1, 100);
    EXPECT_GT(slid, 0.3);
    EXPECT_LT(std::abs(held), slid / 30.0);
}

// Strings pressed by a movable body still collide with each other: a crate dropped on
// two clamped ropes crossing 2 cm apart (one above the other) presses the upper onto the
// lower; their axes never come closer than the sum of their radii, less 5%, and the
// crate is caught (stopped above both; afterwards it may tip off the crossing).
TEST(RigidCollision, CrateOnCrossingRopesKeepsThemApart) {
    Physics phys;
    btRigidBody& crate = phys.add(std::make_unique<btBoxShape>(btVector3(0.1f, 0.1f, 0.1f)), 2.0, btVector3(0, 1.5f, 0));
    BulletWorld ropes(*phys.world, withContacts());
    const double radius = 0.005;
    StringDesc upper = rope({-0.6, 1.02, 0}, {0.6, 1.02, 0}, 40, radius);
    StringDesc lower = rope({0, 1.0, -0.6}, {0, 1.0, 0.6}, 40, radius);
    upper.tearable = lower.tearable = false;
    const StringId a = ropes.addString(upper);
    const StringId b = ropes.addString(lower);
    ropes.attach(a, 0, btVector3(-0.6f, 1.02f, 0));
    ropes.attach(a, -1, btVector3(0.6f, 1.02f, 0));
    ropes.attach(b, 0, btVector3(0, 1.0f, -0.6f));
    ropes.attach(b, -1, btVector3(0, 1.0f, 0.6f));
    double closest = 1e9;
    bool pressed = false, stopped = false;
    for (int i = 0; i < 150; ++i) {
        phys.step(1);
        if (pressed && !stopped) {
            stopped = crate.getLinearVelocity().y() >= 0.0f;
            EXPECT_GT(crate.getCenterOfMassPosition().y() - 0.1, lowest(ropes, b) - radius) << i;
        }
        const auto& xa = *ropes.core().view(a).positions;
        const auto& xb = *ropes.core().view(b).positions;
        for (std::size_t j = 0; j + 1 < xa.size(); ++j)
            for (std::size_t k = 0; k + 1 < xb.size(); ++k)
                closest = std::min(closest, tearables::detail::closestPointsOfSegments(xa[j], xa[j + 1], xb[k], xb[k + 1]).distance);
        for (const auto& c : ropes.core().lastContacts()) pressed = pressed || c.string == a;
    }
    EXPECT_TRUE(pressed);
    EXPECT_TRUE(stopped);
    EXPECT_GT(closest, 2.0 * radius * 0.95);
}

// Every family of Bullet shape stops a rope (Bullet's own narrow phase on a capsule per
// segment): a static plane, a triangle mesh, a compound of two boxes, a convex hull, a
// sphere, a capsule and a cylinder lying across the rope's fall. A rope dropped from
// 10 cm onto each comes to rest on its top: the middle particle one radius above it
// (within 3 mm), and the particles over the top (within 12 mm of the middle, where a
// round top of 0.1 m radius falls by 0.7 mm) never more than 1.5 mm below it. A convex
// hull's surface is its margin (Bullet's default 0.04 m) outside its points, as for
// Bullet's own bodies.
TEST(RigidCollision, EveryShapeFamilyStopsAFallingRope) {
    const double radius = 0.005, top = 0.5;
    auto restOn = [&](const char* name, std::unique_ptr<btCollisionShape> shape, const btVector3& at, double margin = 0.0) {
        const double surface = top + margin;
        Physics phys;
        phys.add(std::move(shape), 0.0, at);
        BulletWorld ropes(*phys.world, withContacts());
        StringDesc d = rope({-0.15, surface + 0.1, 0}, {0.15, surface + 0.1, 0}, 30, radius);
        d.damping = 1.0;
        const StringId id = ropes.addString(d);
        double deepest = 1e9;
        for (int i = 0; i < 150; ++i) {
            phys.step(1);
            for (const Vec3& p : *ropes.core().view(id).positions)
                if (std::abs(p.x()) < 0.012) deepest = std::min(deepest, p.y() - surface);
        }
        const auto& x = *ropes.core().view(id).positions;
        EXPECT_NEAR(x[15].y(), surface + radius, 0.003) << name;
        EXPECT_GT(deepest, -0.0015) << name;
    };
    restOn("plane", std::make_unique<btStaticPlaneShape>(btVector3(0, 1, 0), static_cast<btScalar>(top)), btVector3(0, 0, 0));
    auto mesh = std::make_unique<btTriangleMesh>();
    mesh->addTriangle(btVector3(-1, 0, -1), btVector3(1, 0, -1), btVector3(1, 0, 1));
    mesh->addTriangle(btVector3(-1, 0, -1), btVector3(1, 0, 1), btVector3(-1, 0, 1));
    restOn("mesh", std::make_unique<btBvhTriangleMeshShape>(mesh.get(), true), btVector3(0, static_cast<btScalar>(top), 0));
    auto compound = std::make_unique<btCompoundShape>();
    btBoxShape half_table(btVector3(0.1f, 0.05f, 0.2f));
    compound->addChildShape(btTransform(btQuaternion::getIdentity(), btVector3(-0.1f, 0, 0)), &half_table);
    compound->addChildShape(btTransform(btQuaternion::getIdentity(), btVector3(0.1f, 0, 0)), &half_table);
    restOn("compound", std::move(compound), btVector3(0, static_cast<btScalar>(top - 0.05), 0));
    auto hull = std::make_unique<btConvexHullShape>();
    for (int i = 0; i < 8; ++i)
        hull->addPoint(btVector3(i & 1 ? 0.2f : -0.2f, i & 2 ? 0.0f : -0.2f, i & 4 ? 0.2f : -0.2f));
    const double hull_margin = hull->getMargin();
    restOn("hull", std::move(hull), btVector3(0, static_cast<btScalar>(top), 0), hull_margin);
    restOn("sphere", std::make_unique<btSphereShape>(0.2f), btVector3(0, static_cast<btScalar>(top - 0.2), 0));
    restOn("capsule", std::make_unique<btCapsuleShapeZ>(0.1f, 0.4f), btVector3(0, static_cast<btScalar>(top - 0.1), 0));
    restOn("cylinder", std::make_unique<btCylinderShapeZ>(btVector3(0.1f, 0.1f, 0.2f)), btVector3(0, static_cast<btScalar>(top - 0.1), 0));
}

// A winch: a rope glued to a kinematic drum (a Bullet cylinder the test turns at 2 rad/s)
// winds onto it: the weight at its end rises by what the drum's turn wound on,
// (R + r) * angle, within 10%, and the rope's axis never enters the drum. Known weakness
// (issue 4): where the hanging part leaves the turning drum the rope overlaps the drum by
// up to 4.2 mm of its 5 mm radius for a few steps (its axis stays 0.8 mm outside; before
// the contact solve was made convex, 2026-12-01, the axis dipped 4.5 mm inside).
TEST(RigidCollision, RopeWindsOntoARotatingKinematicDrum) {
    Physics phys;
    const double drum = 0.05, radius = 0.005, omega = 2.0, h = 0.01;
    btRigidBody& cylinder = phys.add(std::make_unique<btCylinderShapeZ>(btVector3(0.05f, 0.05f, 0.1f)), 0.0, btVector3(0, 0, 0));
    cylinder.setCollisionFlags(cylinder.getCollisionFlags() | btCollisionObject::CF_KINEMATIC_OBJECT);
    cylinder.setActivationState(DISABLE_DEACTIVATION);
    cylinder.setAngularVelocity(btVector3(0, 0, static_cast<btScalar>(omega)));
    BulletWorld ropes(*phys.world, withContacts());
    const double x = drum + radius;
    StringDesc d = rope({x, 0, 0}, {x, -0.6, 0}, 60, radius);
    d.tearable = false;
    d.particle_masses = {{-1, 0.05}};
    const StringId id = ropes.addString(d);
    ropes.attach(id, 0, cylinder, btVector3(static_cast<btScalar>(x), 0, 0));
    for (int i = 0; i < 50; ++i) phys.step(1, h);  // settle
    const double tip_before = (*ropes.core().view(id).positions).back().y();
    const int turning = 150;
    double angle = 0.0, worst = 1.0;
    for (int i = 0; i < turning; ++i) {
        angle += omega * h;
        cylinder.setWorldTransform(btTransform(btQuaternion(btVector3(0, 0, 1), static_cast<btScalar>(angle)), btVector3(0, 0, 0)));
        phys.step(1, h);
        const auto& p = *ropes.core().view(id).positions;
        for (std::size_t j = 0; j + 1 < p.size(); ++j)
            for (int k = 0; k <= 4; ++k) {
                const Vec3 q = p[j] + (p[j + 1] - p[j]) * (k / 4.0);
                worst = std::min(worst, std::hypot(q.x(), q.y()));
            }
    }
    const double rise = (*ropes.core().view(id).positions).back().y() - tip_before;
    EXPECT_NEAR(rise, x * angle, 0.1 * x * angle);  // measured: 0.179 m for 0.165 m
    EXPECT_GT(worst, drum);                         // measured: 0.8 mm outside the drum's surface
}

// Starts that are not catastrophes. A static block set down across a free rope (no
// gravity), its bottom face 5 mm below the rope's axis along the rope's whole length: the
// rope is pushed out a fraction of its overlap d0 a step, 20% (as Bullet's contact ERP),
// not all at once: no tear, and it leaves at about d0 / (5 h), the first step's push
// (measured: 0.23 d0 / h at the fastest particle, near the ends), where all at once it
// would leave at d0 / h; asserted below d0 / (4 h). The overlap left after n steps is 0.8^n d0: after 1 s (100 steps)
// every segment's axis is clear of the block by its radius to within 1e-3 of d0.
// The same with the block set down on a rope that has been lying there for ten steps (a
// body placed on an existing rope): its overlap is a start as well, pushed out as gently
// and reported once, at the first step the block is there.
TEST(RigidCollision, RopeUnderABlockSetDownOnItIsPushedOutGently) {
    for (const bool placed_later : {false, true}) {
        SCOPED_TRACE(placed_later ? "block placed on the rope" : "rope made under the block");
        Physics phys(0.0);
        const double h = 0.01, radius = 0.002, below = 0.005;
        const Vec3 half(0.5, 0.1, 0.1);
        const btVector3 at(0, static_cast<btScalar>(half.y() - below), 0);
        btRigidBody* placed = placed_later ? nullptr : &phys.box(tearables::toBullet(half), 0.0, at);
        BulletWorld ropes(*phys.world, withContacts());
        const StringDesc d = rope({-0.3, 0, 0}, {0.3, 0, 0}, 30, radius);
        const StringId id = ropes.addString(d);
        long long first_step = 1;
        if (placed_later) {
            phys.step(10, h);
            placed = &phys.box(tearables::toBullet(half), 0.0, at);
            first_step = 11;
        }
        btRigidBody& block = *placed;
        auto boxDistance = [&](const Vec3& p) {
            const btVector3 local = block.getWorldTransform().inverse() * tearables::toBullet(p);
            const Vec3 q = tearables::toCore(local).cwiseAbs() - half;
            return q.cwiseMax(0.0).norm() + std::min(q.maxCoeff(), 0.0);
        };
        const double d0 = below + radius;
        double fastest = 0.0;
        for (int i = 0; i < 100; ++i) {
            phys.step(1, h);
            for (const Vec3& v : *ropes.core().view(id).velocities) fastest = std::max(fastest, v.norm());
        }
        // One overlap event, at the block's first step, naming the block, with the start
        // overlap of the deepest segment: its axis d0 inside the block's face.
        int overlaps = 0;
        for (const auto& e : ropes.events()) {
            EXPECT_NE(e.type, tearables::EventType::Tear);
            if (e.type != tearables::EventType::Overlap) continue;
            ++overlaps;
            EXPECT_EQ(e.step, first_step);
            EXPECT_EQ(e.body, &block);
            EXPECT_EQ(e.string, id);
            EXPECT_TRUE(e.segment >= 0 && e.segment < 30);
            EXPECT_NEAR(e.depth, d0, 1e-6);
        }
        EXPECT_EQ(overlaps, 1);
        EXPECT_LT(fastest, 0.25 * d0 / h);
        const auto& x = *ropes.core().view(id).positions;
        double closest = 1e9;
        for (std::size_t j = 0; j + 1 < x.size(); ++j)
            for (int k = 0; k <= 10; ++k) closest = std::min(closest, boxDistance(x[j] + (x[j + 1] - x[j]) * (k / 10.0)));
        EXPECT_GT(closest, radius - 1e-3 * d0);
    }
}

// A rope hung from the centre of a static 0.2 m cube, its first five segments inside it,
// held there by a glue to the cube or by a pin: the buried run has no contact with the
// cube (as btSoftBody::appendAnchor may disable collision with its body), so nothing
// pushes it against its own hold, and it hangs without a tear (pushed out, the first
// segment took 60-300x its rupture stress in the first step). The segment that crosses
// the cube's face is pushed out gently and stretches the one above it by what it moves
// (measured: a yield of 3 mm, 0.4x the rupture stress at the first step): the rope's end
// hangs within 1% of its length of where the same rope pinned in empty space hangs.
TEST(RigidCollision, RopeHeldInsideABlockHangsWithoutTearing) {
    // hold: 0 pinned in empty space (the reference), 1 glued to the cube, 2 pinned in it.
    auto hang = [](int hold, bool& tore) {
        Physics phys;
        btRigidBody& cube = phys.box(btVector3(0.1f, 0.1f, 0.1f), 0.0, btVector3(0, hold == 0 ? 5.0f : 2.0f, 0));
        BulletWorld ropes(*phys.world, withContacts());
        const StringDesc d = rope({0, 2, 0}, {0, 1, 0}, 50, 0.002);
        const StringId id = ropes.addString(d);
        if (hold == 1)
            ropes.attach(id, 0, cube, btVector3(0, 0, 0));
        else
            ropes.attach(id, 0, btVector3(0, 2, 0));
        tore = false;
        for (int i = 0; i < 200; ++i) {
            phys.step(1);
            for (const auto& e : ropes.events()) tore = tore || e.type == tearables::EventType::Tear;
        }
        return ropes.core().view(id).positions->back().y();
    };
    bool tore = false;
    const double reference = hang(0, tore);
    EXPECT_FALSE(tore) << "in empty space";
    for (const int hold : {1, 2}) {
        EXPECT_NEAR(hang(hold, tore), reference, 0.01) << (hold == 1 ? "glued" : "pinned");
        EXPECT_FALSE(tore) << (hold == 1 ? "glued" : "pinned");
    }
}

// A snapshot taken while a start overlap is being pushed out carries the push: the restored
// rope goes on leaving the block exactly as the original does (one that forgot where it was
// made would be pushed out of the rest of its overlap at once, at 0.8 d0 / h), and the
// overlap is not reported a second time.
TEST(RigidCollision, ASnapshotTakenDuringAStartPushOutContinuesIt) {
    const double h = 0.01, radius = 0.002, below = 0.005;
    const Vec3 half(0.5, 0.1, 0.1);
    Physics a(0.0), b(0.0);
    btRigidBody& block_a = a.box(tearables::toBullet(half), 0.0, btVector3(0, static_cast<btScalar>(half.y() - below), 0));
    btRigidBody& block_b = b.box(tearables::toBullet(half), 0.0, btVector3(0, static_cast<btScalar>(half.y() - below), 0));
    BulletWorld ropes_a(*a.world, withContacts()), ropes_b(*b.world, withContacts());
    const StringId id = ropes_a.addString(rope({-0.3, 0, 0}, {0.3, 0, 0}, 30, radius));
    a.step(1, h);
    // Saved mid-push: after one step the rope has left a fifth of its overlap d0.
    const double d0 = below + radius;
    ASSERT_LT(-ropes_a.core().view(id).positions->at(15).y(), 0.5 * d0);
    std::stringstream saved;
    ropes_a.saveSnapshot(saved, {&block_a});
    ropes_b.loadSnapshot(saved, {&block_b});
    ropes_a.clearEvents();
    for (int i = 0; i < 5; ++i) {
        a.step(1, h);
        b.step(1, h);
    }
    const auto& xa = *ropes_a.core().view(id).positions;
    const auto& xb = *ropes_b.core().view(id).positions;
    ASSERT_EQ(xa.size(), xb.size());
    for (std::size_t p = 0; p < xa.size(); ++p) EXPECT_EQ(xa[p], xb[p]) << "particle " << p;
    for (const auto* events : {&ropes_a.events(), &ropes_b.events()})
        for (const auto& e : *events) EXPECT_NE(e.type, tearables::EventType::Overlap);
}
