// Issue 8, snapshots: a run saved half-way and restored into a fresh world continues
// bit-identically to the uninterrupted run (tearing, twist, rigid collision, a glued
// body, random material variation); other versions, truncated and corrupt files are
// refused with a clear error and leave the world as it was.
#include "tearables/bullet_core.hpp"
#include "tearables/snapshot.hpp"
#include "sphere_contacts.hpp"
#include "tearables/world.hpp"

#include "../plugin/bullet_fixture.hpp"

#include <btBulletDynamicsCommon.h>
#include <gtest/gtest.h>

#include <cstring>
#include <sstream>
#include <string>
#include <vector>

namespace {

using tearables::CollisionQuery;
using tearables::ContactProvider;
using tearables::RigidContact;
using tearables::RigidId;
using tearables::RigidState;
using tearables::SnapshotError;
using tearables::StringDesc;
using tearables::StringId;
using tearables::Vec3;
using tearables::World;

// --- a core scene: no Bullet, a static sphere the strings hit ----------------------------------

using tearables::testing::SphereContacts;  // the core's host interface, as the Bullet plugin implements it

/// Tearing (a ramped pull on a weak rope with random variation), twist (a clamped end
/// turned every step until the rope tears by torsion), rigid collision (a rope falling
/// on a static sphere), a dynamic body glued to a rope, string-string collision on.
struct CoreScene {
    World world;
    SphereContacts contacts{RigidId{0}, Vec3(2.0, 0.5, 0.0), 0.2, 0.3};
    StringId weak, twisted, draped, net, holder;

    explicit CoreScene(bool build = true) {
        world.setContactProvider(&contacts);
        if (!build) return;
        RigidState sphere;  // slot 0: static
        sphere.position = {2.0, 0.5, 0.0};
        EXPECT_EQ(world.addRigid(sphere).index, 0u);
        RigidState crate;  // slot 1: dynamic, glued
        crate.position = {-1.0, 0.4, 0.0};
        crate.inverse_mass = 0.5;
        crate.inverse_inertia_local = tearables::Mat3::Identity() * 30.0;
        const RigidId crate_id = world.addRigid(crate);

        StringDesc w = StringDesc::straight({0, 1, 0}, {0, 0, 0}, 20);
        w.material.tensile.yield = 2e7;
        w.material.tensile.rupture = 4e7;
        w.material.variation = 1e-2;
        w.seed = 11;
        w.integrator = tearables::StringIntegrator::BDF2;  // its history (v_{n-1}) is kept too
        w.yield_in_solve = true;  // its flow solved with the strain limit (the flag is kept)
        weak = world.addString(w);
        world.attachToPoint(weak, 0, {0, 1, 0});

        StringDesc t = StringDesc::straight({0.5, 1, 0}, {1.4, 1, 0}, 30);
        t.radius = 0.01;
        t.damping = 1.0;
        t.material.torsion.yield = 0.1;
        t.material.torsion.rupture = 0.25;
        t.material.variation = 1e-2;
        t.seed = 12;
        twisted = world.addString(t);
        world.attachToPoint(twisted, 0, {0.5, 1, 0});
        world.attachToPoint(twisted, -1, {1.4, 1, 0});

        StringDesc d = StringDesc::straight({1.6, 0.9, 0.02}, {2.4, 0.9, -0.02}, 30);
        d.radius = 0.004;
        d.seed = 13;
        draped = world.addString(d);

        // A taut rope the draped rope falls across (string-string contact, whose warm start
        // the snapshot keeps: without it the restored run diverges at step 16).
        StringDesc n = StringDesc::straight({2.3, 0.8, -0.4}, {2.3, 0.8, 0.4}, 20);
        n.radius = 0.004;
        n.tearable = false;
        n.seed = 15;
        net = world.addString(n);
        world.attachToPoint(net, 0, {2.3, 0.8, -0.4});
        world.attachToPoint(net, -1, {2.3, 0.8, 0.4});

        StringDesc h = StringDesc::straight({-1.0, 1.5, 0}, {-1.0, 0.5, 0}, 20);
        h.radius = 0.003;
        h.seed = 14;
        holder = world.addString(h);
        world.attachToPoint(holder, 0, {-1.0, 1.5, 0});
        world.attachToRigid(holder, -1, crate_id, {0, 0.1, 0});
    }

    /// One step with the scripted drivers (a function of the step number only).
    void step() {
        const std::int64_t k = world.stepCount();
        world.applyForce(weak, -1, {0.0, -10.0 * static_cast<double>(k), 3.0});
        world.turnEnd(twisted, -1, 0.25);
        world.step(0.01);
    }
};

/// Everything observable about a world, bit for bit.
std::string fingerprint(const World& world) {
    std::string out;
    auto add = [&](const void* p, std::size_t n) { out.append(static_cast<const char*>(p), n); };
    for (StringId id : world.strings()) {
        const auto v = world.view(id);
        add(v.positions->data(), v.positions->size() * sizeof(Vec3));
        add(v.velocities->data(), v.velocities->size() * sizeof(Vec3));
        add(v.tension->data(), v.tension->size() * sizeof(double));
        add(v.twist->data(), v.twist->size() * sizeof(double));
        add(v.rest_length->data(), v.rest_length->size() * sizeof(double));
        add(v.broken->data(), v.broken->size());
        out.push_back(v.frozen ? 'F' : 'L');
    }
    for (const auto& e : world.events()) {
        out += tearables::toString(e.type);
        add(&e.segment, sizeof e.segment);
        add(&e.stress, sizeof e.stress);
    }
    const double t = world.time();
    add(&t, sizeof t);
    return out;
}

int tears(const World& world, StringId id) {
    int n = 0;
    for (auto b : *world.view(id).broken) n += b;
    return n;
}

TEST(Snapshot, CoreRunContinuesBitIdenticallyAfterRestore) {
    constexpr int kBefore = 15, kAfter = 85;
    CoreScene a;
    for (int i = 0; i < kBefore; ++i) a.step();
    EXPECT_EQ(tears(a.world, a.weak) + tears(a.world, a.twisted), 0);  // the interesting part is still to come
    std::stringstream file;
    tearables::saveSnapshot(a.world, file);
    std::vector<std::string> expected;
    bool touched = false;
    for (int i = 0; i < kAfter; ++i) {
        a.step();
        expected.push_back(fingerprint(a.world));
        for (const auto& c : a.world.lastContacts()) touched = touched || c.string == a.draped;
    }
    // What the continuation must cover: both tears, the draped rope on the sphere (it
    // lands on the taut rope first, lopsided, and slides off the sphere), the body.
    EXPECT_GT(tears(a.world, a.weak), 0);
    EXPECT_GT(tears(a.world, a.twisted), 0);
    EXPECT_TRUE(touched);

    CoreScene b(false);  // a fresh world: only the contact provider
    b.world.settings().max_speed = 10.0;  // restored from the snapshot
    tearables::loadSnapshot(b.world, file);
    EXPECT_EQ(b.world.stepCount(), kBefore);
    EXPECT_EQ(b.world.settings().max_speed, a.world.settings().max_speed);
    b.weak = a.weak;
    b.twisted = a.twisted;
    b.draped = a.draped;
    b.holder = a.holder;
    b.net = a.net;
    for (int i = 0; i < kAfter; ++i) {
        b.step();
        ASSERT_TRUE(fingerprint(b.world) == expected[static_cast<std::size_t>(i)]) << "diverged at step " << kBefore + i + 1;
    }
    EXPECT_EQ(b.world.rigid(RigidId{1}).position, a.world.rigid(RigidId{1}).position);
    EXPECT_EQ(b.world.rigid(RigidId{1}).orientation.coeffs(), a.world.rigid(RigidId{1}).orientation.coeffs());
}

TEST(Snapshot, SavingTwiceGivesTheSameBytesAndLoadingReplacesEverything) {
    CoreScene a;
    for (int i = 0; i < 10; ++i) a.step();
    std::stringstream one, two;
    tearables::saveSnapshot(a.world, one);
    tearables::saveSnapshot(a.world, two);
    EXPECT_EQ(one.str(), two.str());
    // A world with other strings is replaced, not merged.
    World other;
    other.addString(StringDesc::straight({5, 5, 5}, {6, 5, 5}, 3));
    other.addString(StringDesc::straight({5, 6, 5}, {6, 6, 5}, 3));
    other.addString(StringDesc::straight({5, 7, 5}, {6, 7, 5}, 3));
    other.addString(StringDesc::straight({5, 8, 5}, {6, 8, 5}, 3));
    other.addString(StringDesc::straight({5, 9, 5}, {6, 9, 5}, 3));
    std::stringstream in(one.str());
    tearables::loadSnapshot(other, in);
    EXPECT_EQ(other.strings(), a.world.strings());
    EXPECT_EQ(fingerprint(other), fingerprint(a.world));
    std::stringstream again;
    tearables::saveSnapshot(other, again);
    EXPECT_EQ(again.str(), one.str());
}

// --- refusals ---------------------------------------------------------------------------------

std::uint64_t fnv(const std::string& s, std::size_t n) {
    std::uint64_t h = 1469598103934665603ull;
    for (std::size_t i = 0; i < n; ++i) {
        h ^= static_cast<unsigned char>(s[i]);
        h *= 1099511628211ull;
    }
    return h;
}

/// Rewrites the trailing checksum so that a deliberately inconsistent file passes it.
std::string resealed(std::string file) {
    const std::uint64_t h = fnv(file, file.size() - 8);
    for (int i = 0; i < 8; ++i) file[file.size() - 8 + static_cast<std::size_t>(i)] = static_cast<char>((h >> (8 * i)) & 0xff);
    return file;
}

/// Loads `bytes` into a world that has run; it must be refused naming `field` with
/// `message` in the problem, and the world must be exactly as it was.
void expectRefused(const std::string& bytes, const std::string& field, const std::string& message, const std::string& label) {
    CoreScene scene;
    for (int i = 0; i < 5; ++i) scene.step();
    const std::string before = fingerprint(scene.world);
    const auto steps = scene.world.stepCount();
    std::stringstream in(bytes);
    try {
        tearables::loadSnapshot(scene.world, in);
        ADD_FAILURE() << label << ": accepted";
    } catch (const SnapshotError& e) {
        EXPECT_EQ(e.field(), field) << label << ": " << e.what();
        EXPECT_NE(e.problem().find(message), std::string::npos) << label << ": " << e.what();
    }
    EXPECT_EQ(scene.world.stepCount(), steps) << label;
    EXPECT_TRUE(fingerprint(scene.world) == before) << label;
    scene.step();  // and it steps on
    EXPECT_EQ(scene.world.stepCount(), steps + 1) << label;
}

TEST(Snapshot, OtherVersionsTruncatedAndCorruptFilesAreRefusedAndChangeNothing) {
    CoreScene a;
    for (int i = 0; i < 20; ++i) a.step();
    std::stringstream out;
    tearables::saveSnapshot(a.world, out);
    const std::string good = out.str();
    ASSERT_GT(good.size(), 1000u);
    ASSERT_EQ(good.compare(0, 8, "TEARSNAP"), 0);

    expectRefused("", "snapshot", "not a tearables snapshot", "empty");
    expectRefused("{\"format\": \"tearables-scene/1\"}", "snapshot", "not a tearables snapshot", "a scene file");
    // Every earlier format, and the next one, is refused by number.
    const std::uint32_t current = tearables::kSnapshotVersion;
    ASSERT_EQ(static_cast<unsigned char>(good[8]), current);
    // 10: before a string's twist-free frames; 8 and 9: development formats with some of
    // what 10 adds (a sheet's center or corner, a string's start overlaps and
    // yield_in_solve); 7: before all three; 6: before each slot's generation (stale ids);
    // 5: before a sheet's solver, tolerance and warm start; 4: before a string's integrator
    // and its BDF2 history; 3: two per-segment string arrays the solver never read; 2:
    // before a cloth's weak yarns; 1: before cloths and sheets.
    for (std::uint32_t v = 1; v <= current + 1; ++v) {
        if (v == current) continue;
        std::string version = good;
        version[8] = static_cast<char>(v);
        const std::string label = "version " + std::to_string(v);
        expectRefused(version, "snapshot.version", label + " (this build reads version " + std::to_string(current) + ")", label);
    }
    std::string version = good;
    version[8] = 0;
    expectRefused(version, "snapshot.version", "version 0", "version 0");
    for (std::size_t keep : {std::size_t{8}, std::size_t{20}, good.size() / 3, good.size() / 2, good.size() - 9, good.size() - 1})
        expectRefused(good.substr(0, keep), "snapshot", keep < 24 ? "truncated" : "checksum mismatch",
                      "truncated to " + std::to_string(keep));
    for (std::size_t at : {std::size_t{30}, good.size() / 4, good.size() / 2, good.size() - 20}) {
        std::string flipped = good;
        flipped[at] = static_cast<char>(flipped[at] ^ 0x10);
        expectRefused(flipped, "snapshot", "checksum mismatch", "byte " + std::to_string(at) + " flipped");
    }
    expectRefused(good + "x", "snapshot", "checksum mismatch", "a byte appended");

    // Inconsistent content behind a valid checksum: an unknown section tag, the number of
    // string slots, a setting.
    std::string tag = good;
    const std::size_t evnt = tag.find("EVNT");
    ASSERT_NE(evnt, std::string::npos);
    tag.replace(evnt, 4, "ZZZZ");
    expectRefused(resealed(tag), "snapshot.ZZZZ", "host's section", "an unknown section");
    std::string wrld = good;
    const std::size_t at = wrld.find("WRLD");
    ASSERT_NE(at, std::string::npos);
    // WRLD payload: settings (3 + 2 + 2 + 3 words), time, steps, then the slot count.
    const std::size_t slots = at + 4 + 8 + 8 * (3 + 2 + 2 + 3 + 2);
    wrld[slots] = static_cast<char>(wrld[slots] + 1);
    expectRefused(resealed(wrld), "snapshot", "string sections for " + std::to_string(a.world.strings().size() + 1) + " slots", "slot count");
    wrld[slots] = static_cast<char>(wrld[slots] - 2);
    expectRefused(resealed(wrld), "snapshot.STRG", "more string sections than the world has slots", "slot count low");
    std::string settings = good;
    const std::size_t iterations = at + 4 + 8 + 8 * 3;  // strain_iterations
    settings[iterations] = 0;
    expectRefused(resealed(settings), "snapshot.WRLD", "strain_iterations", "bad settings");
}

// --- the Bullet plugin ----------------------------------------------------------------------

using tearables::BulletWorld;
using tearables::testing::Physics;

/// A board hanging from two ropes (one weak, it tears), a rope draped over a static ball,
/// a rope twisted until it tears. No rigid body touches another (Bullet's own contact
/// caches are not ours to restore).
struct BulletScene {
    Physics phys;
    btRigidBody* ground;
    btRigidBody* ball;
    btRigidBody* board;
    std::unique_ptr<BulletWorld> ropes;
    StringId left, right, draped, twisted;

    BulletScene() {
        ground = &phys.add(std::make_unique<btStaticPlaneShape>(btVector3(0, 1, 0), 0), 0.0, btVector3(0, 0, 0));
        ball = &phys.sphere(0.15, 0.0, btVector3(2.0f, 0.6f, 0));
        board = &phys.box(btVector3(0.4f, 0.025f, 0.15f), 10.0, btVector3(0, 1.0f, 0));
        ropes = std::make_unique<BulletWorld>(*phys.world);
        StringDesc l = StringDesc::straight({-0.3, 2.0, 0}, {-0.3, 1.025, 0}, 30);
        l.material.tensile.yield = 8e6;
        l.material.tensile.rupture = 1.5e7;
        l.material.variation = 1e-2;
        l.seed = 3;
        left = ropes->addString(l);
        ropes->attach(left, 0, btVector3(-0.3f, 2.0f, 0));
        ropes->attach(left, -1, *board, btVector3(-0.3f, 0.025f, 0));
        StringDesc r = StringDesc::straight({0.3, 2.0, 0}, {0.3, 1.025, 0}, 30);
        r.radius = 0.004;
        r.tearable = false;
        right = ropes->addString(r);
        ropes->attach(right, 0, btVector3(0.3f, 2.0f, 0));
        ropes->attach(right, -1, *board, btVector3(0.3f, 0.025f, 0));
        StringDesc d = StringDesc::straight({1.6, 0.9, 0.02}, {2.4, 0.9, -0.02}, 30);
        d.radius = 0.004;
        draped = ropes->addString(d);
        StringDesc t = StringDesc::straight({-1.5, 1.5, 0}, {-0.6, 1.5, 0}, 30);
        t.radius = 0.01;
        t.damping = 1.0;
        t.material.torsion.yield = 0.1;
        t.material.torsion.rupture = 0.25;
        t.material.variation = 1e-2;
        twisted = ropes->addString(t);
        ropes->attach(twisted, 0, btVector3(-1.5f, 1.5f, 0));
        ropes->attach(twisted, -1, btVector3(-0.6f, 1.5f, 0));
    }
    std::vector<const btRigidBody*> constBodies() const { return {ground, ball, board}; }
    std::vector<btRigidBody*> bodies() { return {ground, ball, board}; }
    void step() {
        ropes->core().turnEnd(twisted, -1, 0.4);
        // A pull on the board that grows until the weak rope tears.
        board->applyCentralForce(btVector3(0, -3.0f * static_cast<float>(ropes->core().stepCount()), 0));
        phys.step(1);
    }
    std::string state() const {
        std::string out = fingerprint(ropes->core());
        tearables::testing::appendBodyBits(out, *board);
        return out;
    }
};

using tearables::testing::BodyState;

TEST(Snapshot, BulletRunContinuesBitIdenticallyAfterRestore) {
    constexpr int kBefore = 30, kAfter = 90;
    BulletScene a;
    for (int i = 0; i < kBefore; ++i) a.step();
    EXPECT_EQ(tears(a.ropes->core(), a.left) + tears(a.ropes->core(), a.twisted), 0);
    std::stringstream file;
    a.ropes->saveSnapshot(file, a.constBodies());
    const BodyState board(*a.board);
    std::vector<std::string> expected;
    for (int i = 0; i < kAfter; ++i) {
        a.step();
        expected.push_back(a.state());
    }
    EXPECT_TRUE(a.ropes->lastError().empty()) << a.ropes->lastError();
    EXPECT_GT(tears(a.ropes->core(), a.left), 0);
    EXPECT_GT(tears(a.ropes->core(), a.twisted), 0);
    bool touched = false;
    for (const auto& c : a.ropes->core().lastContacts()) touched = touched || c.string == a.draped;
    EXPECT_TRUE(touched);

    BulletScene b;  // the same bodies and strings, fresh; then the saved state
    board.applyTo(*b.board);
    b.ropes->loadSnapshot(file, b.bodies());
    for (int i = 0; i < kAfter; ++i) {
        b.step();
        ASSERT_TRUE(b.state() == expected[static_cast<std::size_t>(i)]) << "diverged at step " << kBefore + i + 1;
    }
}

TEST(Snapshot, BulletLoadRefusesAMissingBodyOrACoreFileAndChangesNothing) {
    BulletScene a;
    for (int i = 0; i < 10; ++i) a.step();
    std::stringstream file;
    EXPECT_THROW(a.ropes->saveSnapshot(file, {a.ground}), tearables::InvalidInput);  // the board is held
    a.ropes->saveSnapshot(file, a.constBodies());
    const std::string bytes = file.str();

    BulletScene b;
    for (int i = 0; i < 3; ++i) b.step();
    const std::string before = b.state();
    std::stringstream in(bytes);
    try {
        b.ropes->loadSnapshot(in, {b.ground, b.ball});  // the board is missing
        ADD_FAILURE() << "accepted";
    } catch (const tearables::InvalidInput& e) {
        EXPECT_EQ(e.field(), "bodies") << e.what();
    }
    std::stringstream core;
    tearables::saveSnapshot(a.ropes->core(), core);
    EXPECT_THROW(b.ropes->loadSnapshot(core, b.bodies()), SnapshotError);
    // A Bullet snapshot into a bare core world: refused, it needs its host's body mapping.
    World bare;
    std::stringstream again(bytes);
    try {
        tearables::loadSnapshot(bare, again);
        ADD_FAILURE() << "accepted";
    } catch (const SnapshotError& e) {
        EXPECT_EQ(e.field(), "snapshot.BULT") << e.what();
    }
    EXPECT_TRUE(bare.strings().empty());
    EXPECT_TRUE(b.state() == before);
    b.step();
    EXPECT_TRUE(b.ropes->lastError().empty()) << b.ropes->lastError();
}

}  // namespace
