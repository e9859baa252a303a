// The everyday calls of BulletWorld with Bullet's vectors (tearables/bullet.hpp): reading a
// string's state, building a rope between two points from a preset, cutting, turning an end.
// Each read is checked against the core's view it converts, and each call's refusals name
// the argument and change nothing.
#include "tearables/bullet_core.hpp"

#include "bullet_fixture.hpp"

#include <btBulletDynamicsCommon.h>
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <string>

namespace {

using tearables::BulletWorld;
using tearables::InvalidInput;
using tearables::StringDesc;
using tearables::StringId;
using tearables::Vec3;
using tearables::testing::Physics;

constexpr double kPi = 3.14159265358979323846;

/// The field an InvalidInput names, or "" when nothing was thrown.
std::string refusal(const std::function<void()>& call) {
    try {
        call();
    } catch (const InvalidInput& e) {
        return e.field();
    }
    return "";
}

// Every read is the core's state converted to btVector3 (bit for bit in double precision,
// rounded once in single), after a few steps of a rope swinging with a crate.
TEST(Facade, ReadsAreTheCoresState) {
    Physics p;
    BulletWorld ropes(*p.world);
    const StringId rope = ropes.addString(tearables::testing::plainRope({0, 2, 0}, {1, 2, 0}, 12));
    ropes.attach(rope, 0, btVector3(0, 2, 0));
    btRigidBody& crate = p.box(btVector3(0.05f, 0.05f, 0.05f), 2.0, btVector3(1, 2, 0));
    ropes.attach(rope, -1, crate, btVector3(0, 0, 0));
    p.step(30, 1.0 / 240.0);
    ASSERT_TRUE(ropes.lastError().empty()) << ropes.lastError();

    const auto v = ropes.core().view(rope);
    ASSERT_EQ(ropes.particleCount(rope), 13u);
    ASSERT_EQ(ropes.segmentCount(rope), 12u);
    const std::vector<btVector3> x = ropes.positions(rope), u = ropes.velocities(rope);
    ASSERT_EQ(x.size(), 13u);
    ASSERT_EQ(u.size(), 13u);
    for (std::size_t i = 0; i < x.size(); ++i) {
        EXPECT_EQ(x[i], tearables::toBullet((*v.positions)[i])) << i;
        EXPECT_EQ(u[i], tearables::toBullet((*v.velocities)[i])) << i;
    }
    EXPECT_EQ(ropes.position(rope, -1), x.back());
    EXPECT_EQ(ropes.position(rope, 3), x[3]);
    EXPECT_EQ(ropes.tensions(rope), *v.tension);
    EXPECT_GT(ropes.tensions(rope).front(), 0.0);  // it holds the crate
    double length = 0.0, rest = 0.0, mass = 0.0;
    for (std::size_t j = 0; j < 12; ++j) {
        length += ((*v.positions)[j + 1] - (*v.positions)[j]).norm();
        rest += (*v.rest_length)[j];
    }
    for (const double m : *v.masses) mass += m;
    EXPECT_EQ(ropes.length(rope), length);
    EXPECT_EQ(ropes.restLength(rope), rest);
    EXPECT_EQ(ropes.mass(rope), mass);
    EXPECT_TRUE(ropes.isAttached(rope, 0));
    EXPECT_TRUE(ropes.isAttached(rope, -1));
    EXPECT_FALSE(ropes.isAttached(rope, 5));
    EXPECT_EQ(ropes.brokenSegments(rope), std::vector<bool>(12, false));
    const auto whole = ropes.pieces(rope);
    ASSERT_EQ(whole.size(), 1u);
    EXPECT_EQ(whole[0].first, 0);
    EXPECT_EQ(whole[0].last, 12);
}

// A cut breaks one segment (a second cut of it changes nothing) and makes two pieces; two
// neighbouring cuts leave a lone particle as a piece of its own. Length and rest length
// leave the broken segments out, the mass keeps every particle.
TEST(Facade, CutsMakePieces) {
    Physics p;
    BulletWorld ropes(*p.world);
    const StringId rope = ropes.addString(tearables::testing::plainRope({0, 2, 0}, {1, 2, 0}, 10));
    const double mass = ropes.mass(rope), rest = ropes.restLength(rope);
    EXPECT_TRUE(ropes.cut(rope, 3));
    EXPECT_FALSE(ropes.cut(rope, 3));
    auto pieces = ropes.pieces(rope);
    ASSERT_EQ(pieces.size(), 2u);
    EXPECT_EQ(pieces[0].first, 0);
    EXPECT_EQ(pieces[0].last, 3);
    EXPECT_EQ(pieces[1].first, 4);
    EXPECT_EQ(pieces[1].last, 10);
    EXPECT_TRUE(ropes.cut(rope, -1));  // segment 9
    EXPECT_TRUE(ropes.cut(rope, 8));
    pieces = ropes.pieces(rope);
    ASSERT_EQ(pieces.size(), 4u);
    EXPECT_EQ(pieces[2].first, 9);
    EXPECT_EQ(pieces[2].last, 9);  // between segments 8 and 9
    EXPECT_EQ(pieces[3].first, 10);
    EXPECT_EQ(pieces[3].last, 10);
    std::vector<bool> broken(10, false);
    broken[3] = broken[8] = broken[9] = true;
    EXPECT_EQ(ropes.brokenSegments(rope), broken);
    EXPECT_NEAR(ropes.restLength(rope), rest * 0.7, 1e-12);
    EXPECT_NEAR(ropes.length(rope), 0.7, 1e-12);  // not stepped: still straight, 0.1 m segments
    EXPECT_EQ(ropes.mass(rope), mass);
    p.step(1, 1.0 / 240.0);
    int tears = 0;
    for (const auto& e : ropes.events()) tears += e.type == tearables::EventType::Tear && e.cause == tearables::EventCause::Request;
    EXPECT_EQ(tears, 3);
    EXPECT_EQ(refusal([&] { ropes.cut(rope, 10); }), "segment");
    EXPECT_EQ(refusal([&] { ropes.cut(rope, -11); }), "segment");
}

// Every read and the new calls refuse a stale id naming "string", and a particle out of
// range naming "particle"; nothing changes.
TEST(Facade, BadIdsAndIndicesAreRefused) {
    Physics p;
    BulletWorld ropes(*p.world);
    const StringId old = ropes.addString(tearables::testing::plainRope({0, 2, 0}, {1, 2, 0}, 4));
    ropes.removeString(old);
    const StringId rope = ropes.addString(tearables::testing::plainRope({0, 2, 0}, {1, 2, 0}, 4));
    ASSERT_EQ(rope.index, old.index);
    const std::vector<std::function<void()>> calls = {
        [&] { ropes.particleCount(old); }, [&] { ropes.segmentCount(old); },  [&] { ropes.positions(old); },
        [&] { ropes.position(old, 0); },   [&] { ropes.velocities(old); },    [&] { ropes.tensions(old); },
        [&] { ropes.brokenSegments(old); }, [&] { ropes.pieces(old); },       [&] { ropes.length(old); },
        [&] { ropes.restLength(old); },    [&] { ropes.mass(old); },          [&] { ropes.isAttached(old, 0); },
        [&] { ropes.cut(old, 0); },        [&] { ropes.turnEnd(old, 0, 1.0); }, [&] { ropes.endTwist(old, 0); },
        [&] { ropes.positions(StringId{}); },
    };
    for (std::size_t k = 0; k < calls.size(); ++k) EXPECT_EQ(refusal(calls[k]), "string") << "call " << k;
    EXPECT_EQ(refusal([&] { ropes.position(rope, 5); }), "particle");
    EXPECT_EQ(refusal([&] { ropes.position(rope, -6); }), "particle");
    EXPECT_EQ(refusal([&] { ropes.isAttached(rope, 5); }), "particle");
    EXPECT_EQ(ropes.brokenSegments(rope), std::vector<bool>(4, false));
}

// addRope is StringDesc::between made of a preset at its radius and density: its mass is
// density pi r^2 times the sum of its segments' rest lengths, its particles are where
// ropeBetween puts them. An unknown preset or a bad shape is refused naming the argument and
// creates nothing.
TEST(Facade, AddRopeIsBetweenMadeOfAPreset) {
    Physics p;
    BulletWorld ropes(*p.world);
    const btVector3 a(0, 2, 0), b(1, 1.8f, 0);
    const StringId rope = ropes.addRope(a, b, 1.3, 30, "steel_wire");
    const tearables::MaterialPreset* steel = tearables::findMaterialPreset("steel_wire");
    ASSERT_NE(steel, nullptr);
    const StringDesc& d = ropes.core().desc(rope);
    EXPECT_EQ(d.radius, steel->radius);
    EXPECT_EQ(d.density, steel->density);
    EXPECT_EQ(d.material.tensile.rupture, steel->material.tensile.rupture);
    EXPECT_EQ(d.material.torsion.modulus, steel->material.torsion.modulus);
    const StringDesc shape = BulletWorld::ropeBetween(a, b, 1.3, 30);
    EXPECT_EQ(d.points, shape.points);
    EXPECT_EQ(d.points, StringDesc::between(tearables::toCore(a), tearables::toCore(b), 1.3, 30).points);
    const double area = kPi * steel->radius * steel->radius;
    EXPECT_NEAR(ropes.mass(rope), steel->density * area * ropes.restLength(rope), 1e-12 * ropes.mass(rope));
    EXPECT_NEAR(ropes.restLength(rope), 1.3, 1.3 * 1e-3);  // chords of the catenary's arcs
    EXPECT_EQ(ropes.core().desc(ropes.addRope(a, b, 1.3, 30)).density,
              tearables::findMaterialPreset("nylon_rope")->density);  // the default preset

    const std::size_t count = ropes.core().strings().size();
    EXPECT_EQ(refusal([&] { ropes.addRope(a, b, 1.3, 30, "kevlar"); }), "preset");
    EXPECT_EQ(refusal([&] { ropes.addRope(a, b, 0.5, 30); }), "length");
    EXPECT_EQ(refusal([&] { ropes.addRope(a, b, std::nan(""), 30); }), "length");
    EXPECT_EQ(refusal([&] { ropes.addRope(a, a, 1.0, 30); }), "b");
    EXPECT_EQ(refusal([&] { ropes.addRope(btVector3(0, 0, 0) / btScalar(0), b, 1.3, 30); }), "a");
    EXPECT_EQ(refusal([&] { ropes.addRope(a, b, 1.3, 0); }), "segments");
    EXPECT_EQ(refusal([&] { BulletWorld::ropeBetween(a, b, 1.3, -2); }), "segments");
    EXPECT_EQ(ropes.core().strings().size(), count);
}

// A turn given for the next stepSimulation is spread evenly over its internal steps: the
// rope goes exactly as a twin whose end is turned by the core, k/4 of the angle reached by
// internal step k of 4 (from Bullet's pre-tick callback, before the step's actions), bit for
// bit; after the frame nothing more is turned (both stay equal a frame later). The end's
// angle is the turn plus what the core's own transport of the clamped frame adds as the
// end segment swings (a small part: under 1e-5 of it here).
TEST(Facade, TurnEndIsSpreadOverTheSubsteps) {
    Physics p, q;
    BulletWorld ropes(*p.world), twin(*q.world);
    StringId ids[2];
    for (int w = 0; w < 2; ++w) {
        BulletWorld& r = w == 0 ? ropes : twin;
        ids[w] = r.addString(tearables::testing::plainRope({0, 2, 0}, {1, 2, 0}, 10));
        r.attach(ids[w], 0, btVector3(0, 2, 0));
        r.attach(ids[w], -1, btVector3(1, 2, 0));
    }
    const double angle = 1.2;
    struct Driver {
        BulletWorld* twin;
        StringId rope;
        double angle, done = 0.0;
        int tick = 0;
    } driver{&twin, ids[1], angle};
    q.world->setInternalTickCallback(
        [](btDynamicsWorld* w, btScalar) {
            auto* d = static_cast<Driver*>(w->getWorldUserInfo());
            if (d->tick >= 4) return;
            ++d->tick;
            const double reached = d->tick == 4 ? d->angle : d->angle * d->tick / 4;
            d->twin->core().turnEnd(d->rope, -1, reached - d->done);
            d->done = reached;
        },
        &driver, true);
    ropes.turnEnd(ids[0], -1, angle);
    EXPECT_EQ(ropes.endTwist(ids[0], -1), 0.0);  // not yet
    for (int frame = 0; frame < 2; ++frame) {
        p.world->stepSimulation(btScalar(1.0 / 60.0), 4, btScalar(1.0 / 240.0));
        q.world->stepSimulation(btScalar(1.0 / 60.0), 4, btScalar(1.0 / 240.0));
        ASSERT_TRUE(ropes.lastError().empty()) << ropes.lastError();
        ASSERT_EQ(driver.tick, 4);
        EXPECT_EQ(ropes.endTwist(ids[0], -1), twin.endTwist(ids[1], -1)) << frame;
        EXPECT_EQ(ropes.endTwist(ids[0], 0), twin.endTwist(ids[1], 0)) << frame;
        EXPECT_EQ(ropes.positions(ids[0]), twin.positions(ids[1])) << frame;
        EXPECT_EQ(ropes.core().view(ids[0]).twist->back(), twin.core().view(ids[1]).twist->back()) << frame;
        EXPECT_NEAR(ropes.endTwist(ids[0], -1), angle, 1e-5 * angle) << frame;
    }
    q.world->setInternalTickCallback(nullptr);
}

// turnEnd refuses a bad end, a free end, a non-finite angle; nothing is turned then.
TEST(Facade, TurnEndRefusals) {
    Physics p;
    BulletWorld ropes(*p.world);
    const StringId rope = ropes.addString(tearables::testing::plainRope({0, 2, 0}, {1, 2, 0}, 10));
    ropes.attach(rope, 0, btVector3(0, 2, 0));
    btRigidBody& crate = p.box(btVector3(0.05f, 0.05f, 0.05f), 1.0, btVector3(1, 2, 0));
    ropes.attach(rope, -1, crate, btVector3(0, 0, 0));
    EXPECT_EQ(refusal([&] { ropes.turnEnd(rope, 1, 0.5); }), "end");
    EXPECT_EQ(refusal([&] { ropes.turnEnd(rope, 5, 0.5); }), "end");
    EXPECT_EQ(refusal([&] { ropes.turnEnd(rope, -1, 0.5); }), "end");  // glued, not pinned to a point
    EXPECT_EQ(refusal([&] { ropes.turnEnd(rope, 0, std::nan("")); }), "angle");
    EXPECT_EQ(refusal([&] { ropes.turnEnd(rope, 0, INFINITY); }), "angle");
    EXPECT_EQ(refusal([&] { ropes.endTwist(rope, 2); }), "end");
    p.step(4, 1.0 / 240.0);
    EXPECT_EQ(ropes.endTwist(rope, 0), 0.0);
    EXPECT_EQ(ropes.endTwist(rope, -1), 0.0);
}

// A cloth's and a sheet's reads are the core's views converted (btVector3 from the
// positions and velocities, the intact yarns with their tensions, the faces, the torn
// counts), read after each has torn: a cloth under a heavy ball, a sheet pulled apart at two
// corners (tests/plugin/test_cloth_bullet.cpp, tests/paper/test_paper_tear.cpp).
TEST(Facade, ClothAndSheetReadsAreTheCoresState) {
    Physics p;
    BulletWorld world(*p.world);
    tearables::ClothDesc c;
    c.resolution = {9, 9};
    c.size = {0.6, 0.6};
    c.corner = Vec3(-0.3, 1.0, -0.3);
    c.areal_density = 0.2;
    c.yarn_radius = 5e-4;
    c.material.variation = 0.0;
    for (int i : {0, -1})
        for (int j : {0, -1}) c.attachments.push_back({c.vertex(i, j)});
    const tearables::ClothId cloth = world.addCloth(c);
    p.sphere(0.1, 40.0, btVector3(0, 1.3f, 0));
    tearables::PaperDesc s;
    s.center = Vec3(3, 1, 0);
    s.size[0] = 0.2;
    s.size[1] = 0.1;
    s.resolution[0] = 21;
    s.resolution[1] = 11;
    s.tearable = true;
    s.breakable = false;
    s.attachments = {{0}, {20}};  // the corners of the first row
    const tearables::PaperId sheet = world.addPaper(s);
    const Vec3 l0 = (*world.core().viewPaper(sheet).positions)[0], r0 = (*world.core().viewPaper(sheet).positions)[20];
    for (int step = 1; step <= 150; ++step) {
        const double pull = 0.02 * step / 60.0;  // each corner moves out along the edge at 2 cm/s
        world.core().movePaperPin(sheet, 0, l0 - Vec3(pull, 0, 0));
        world.core().movePaperPin(sheet, 20, r0 + Vec3(pull, 0, 0));
        p.step(1, 1.0 / 60.0);
    }
    ASSERT_TRUE(world.lastError().empty()) << world.lastError();

    const tearables::ClothView cv = world.core().viewCloth(cloth);
    ASSERT_EQ(world.vertexCount(cloth), 81u);
    const std::vector<btVector3> cx = world.positions(cloth), cu = world.velocities(cloth);
    ASSERT_EQ(cx.size(), 81u);
    ASSERT_EQ(cu.size(), 81u);
    for (std::size_t i = 0; i < cx.size(); ++i) {
        EXPECT_EQ(cx[i], tearables::toBullet((*cv.positions)[i])) << i;
        EXPECT_EQ(cu[i], tearables::toBullet((*cv.velocities)[i])) << i;
    }
    std::size_t torn = 0;
    std::vector<tearables::BulletYarn> intact;
    for (std::size_t e = 0; e < cv.edgeCount(); ++e) {
        if ((*cv.broken)[e]) {
            ++torn;
            continue;
        }
        intact.push_back({static_cast<int>((*cv.edges)[e][0]), static_cast<int>((*cv.edges)[e][1]), static_cast<int>(e), (*cv.tension)[e]});
    }
    EXPECT_GT(torn, 0u);  // the ball went through
    EXPECT_EQ(world.tornCount(cloth), torn);
    const std::vector<tearables::BulletYarn> yarns = world.yarns(cloth);
    ASSERT_EQ(yarns.size(), intact.size());
    for (std::size_t k = 0; k < yarns.size(); ++k) {
        EXPECT_EQ(yarns[k].a, intact[k].a);
        EXPECT_EQ(yarns[k].b, intact[k].b);
        EXPECT_EQ(yarns[k].edge, intact[k].edge);
        EXPECT_EQ(yarns[k].tension, intact[k].tension);
    }
    const auto faces = tearables::clothFaces(cv);
    const std::vector<std::array<int, 3>> ct = world.triangles(cloth);
    ASSERT_EQ(ct.size(), faces.size());
    EXPECT_LT(ct.size(), 2u * 8u * 8u);  // torn cells show no face
    for (std::size_t k = 0; k < ct.size(); ++k)
        for (int m = 0; m < 3; ++m) EXPECT_EQ(ct[k][m], static_cast<int>(faces[k][m]));

    const tearables::PaperView sv = world.core().viewPaper(sheet);
    EXPECT_GT(sv.counters.tears, 0u);  // pulled apart
    ASSERT_EQ(world.vertexCount(sheet), sv.vertexCount());
    EXPECT_GT(sv.vertexCount(), 231u);  // a tear adds vertices
    const std::vector<btVector3> sx = world.positions(sheet), su = world.velocities(sheet);
    ASSERT_EQ(sx.size(), sv.vertexCount());
    ASSERT_EQ(su.size(), sv.vertexCount());
    for (std::size_t i = 0; i < sx.size(); ++i) {
        EXPECT_EQ(sx[i], tearables::toBullet((*sv.positions)[i])) << i;
        EXPECT_EQ(su[i], tearables::toBullet((*sv.velocities)[i])) << i;
    }
    const std::vector<std::array<int, 3>> st = world.triangles(sheet);
    ASSERT_EQ(st.size(), sv.triangles->size());
    for (std::size_t k = 0; k < st.size(); ++k)
        for (int m = 0; m < 3; ++m) EXPECT_EQ(st[k][m], static_cast<int>((*sv.triangles)[k][m]));
    EXPECT_EQ(world.tornCount(sheet), sv.counters.tears);

    // A removed object's id is stale: every read refuses it naming the object, and the
    // slot's next object does not answer to it.
    world.removeCloth(cloth);
    world.removePaper(sheet);
    const tearables::ClothId next_cloth = world.addCloth(c);
    const tearables::PaperId next_sheet = world.addPaper(s);
    ASSERT_EQ(next_cloth.index, cloth.index);
    ASSERT_EQ(next_sheet.index, sheet.index);
    const std::vector<std::pair<std::string, std::function<void()>>> reads = {
        {"cloth", [&] { (void)world.vertexCount(cloth); }},     {"cloth", [&] { (void)world.positions(cloth); }},
        {"cloth", [&] { (void)world.velocities(cloth); }},      {"cloth", [&] { (void)world.yarns(cloth); }},
        {"cloth", [&] { (void)world.triangles(cloth); }},       {"cloth", [&] { (void)world.tornCount(cloth); }},
        {"cloth", [&] { (void)world.positions(tearables::ClothId{7, 0}); }},
        {"paper", [&] { (void)world.vertexCount(sheet); }},     {"paper", [&] { (void)world.positions(sheet); }},
        {"paper", [&] { (void)world.velocities(sheet); }},      {"paper", [&] { (void)world.triangles(sheet); }},
        {"paper", [&] { (void)world.tornCount(sheet); }},
        {"paper", [&] { (void)world.positions(tearables::PaperId{7, 0}); }},
    };
    for (const auto& [field, read] : reads) EXPECT_EQ(refusal(read), field);
    EXPECT_EQ(world.vertexCount(next_cloth), 81u);
    EXPECT_EQ(world.tornCount(next_sheet), 0u);
}

}  // namespace
