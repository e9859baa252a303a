// Issue 8, snapshots of cloths and paper sheets: a run saved half-way and restored into a
// fresh world continues bit-identically to the uninterrupted run (a cloth pulled apart
// until it tears, lying on a sphere and holding a glued weight; a sheet pressed by a
// sphere until it creases, then pulled until it tears, holding a glued weight; both in a
// Bullet world, with Bullet bodies, through BulletWorld::saveSnapshot); a world
// whose cloths or sheets are not the snapshot's refuses it, naming the difference, and
// is left as it was.
#include "world/world_access.hpp"
#include "tearables/bullet_core.hpp"
#include "tearables/snapshot.hpp"
#include "tearables/world.hpp"

#include "../plugin/bullet_fixture.hpp"

#include <btBulletDynamicsCommon.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <sstream>
#include <string>
#include <vector>

namespace {

using tearables::ClothDesc;
using tearables::ClothId;
using tearables::EventType;
using tearables::PaperAttachment;
using tearables::PaperDesc;
using tearables::PaperId;
using tearables::PointContact;
using tearables::PointQuery;
using tearables::RigidId;
using tearables::RigidState;
using tearables::SnapshotError;
using tearables::Vec3;
using tearables::World;

/// Mesh vertices against spheres (the host interface the Bullet plugin implements):
/// speculative contacts from the start positions, within the radius plus the travel. The
/// spheres' centres are their rigid proxies' positions (a test moves a kinematic one).
class SphereContacts : public tearables::ContactProvider {
public:
    struct Sphere {
        RigidId body;
        double radius;
    };
    explicit SphereContacts(const World& world) : world_(world) {}
    std::vector<Sphere> spheres;
    long long reported = 0;  ///< contacts handed to the world, over the run

    void findContacts(const tearables::CollisionQuery&, std::vector<tearables::RigidContact>&) override {}
    void findPointContacts(const PointQuery& q, std::vector<PointContact>& out) override {
        for (std::size_t o = 0; o < q.start.size(); ++o)
            for (std::size_t v = 0; v < q.start[o]->size(); ++v)
                for (const Sphere& s : spheres) {
                    const Vec3 centre = world_.rigid(s.body).position;
                    const Vec3 d = (*q.start[o])[v] - centre;
                    const double travel = ((*q.predicted[o])[v] - (*q.start[o])[v]).norm();
                    if (d.norm() > s.radius + q.radius[o] + travel + 0.002 || d.norm() < 1e-9) continue;
                    PointContact c;
                    c.object = static_cast<std::uint32_t>(o);
                    c.vertex = static_cast<std::uint32_t>(v);
                    c.normal = d.normalized();
                    c.point = centre + s.radius * c.normal;
                    c.body = s.body;
                    c.friction = 0.4;
                    out.push_back(c);
                    ++reported;
                }
    }

private:
    const World& world_;
};

void addBits(std::string& out, const void* p, std::size_t n) { out.append(static_cast<const char*>(p), n); }
template <class T>
void addVector(std::string& out, const std::vector<T>& v) {
    addBits(out, v.data(), v.size() * sizeof(T));
}

/// Everything observable about a world's cloths, sheets, bodies and events, bit for bit.
std::string fingerprint(const World& world) {
    std::string out;
    for (ClothId id : world.cloths()) {
        const auto v = world.viewCloth(id);
        addVector(out, *v.positions);
        addVector(out, *v.velocities);
        addVector(out, *v.masses);
        addVector(out, *v.tension);
        addVector(out, *v.rest_length);
        addVector(out, *v.max_length);
        addVector(out, *v.broken);
        addBits(out, &v.tension_residual, sizeof v.tension_residual);
        out.push_back(v.frozen ? 'F' : 'L');
    }
    for (PaperId id : world.papers()) {
        const auto v = world.viewPaper(id);
        addVector(out, *v.positions);
        addVector(out, *v.velocities);
        addVector(out, *v.masses);
        addVector(out, *v.triangles);
        for (const auto& sp : *v.springs) {
            addBits(out, &sp.a, sizeof sp.a);
            addBits(out, &sp.b, sizeof sp.b);
            addBits(out, &sp.rest, sizeof sp.rest);
            addBits(out, &sp.stiffness, sizeof sp.stiffness);
            out.push_back(static_cast<char>(sp.kind));
            out.push_back(sp.broken ? 'B' : 'W');
            addBits(out, sp.hinge, sizeof sp.hinge);
        }
        addVector(out, *v.tension);
        addBits(out, &v.counters, sizeof v.counters);
        out.push_back(v.frozen ? 'F' : 'L');
    }
    for (std::uint32_t i = 0; i < 4; ++i) {
        try {
            const RigidState& b = world.rigid(RigidId{i});
            addBits(out, b.position.data(), sizeof(double) * 3);
            addBits(out, b.orientation.coeffs().data(), sizeof(double) * 4);
            addBits(out, b.linear_velocity.data(), sizeof(double) * 3);
            addBits(out, b.angular_velocity.data(), sizeof(double) * 3);
        } catch (const tearables::InvalidInput&) {
        }
    }
    for (const auto& e : world.events()) {
        out += tearables::toString(e.type);
        out += e.object;
        addBits(out, &e.segment, sizeof e.segment);
        addBits(out, &e.particle, sizeof e.particle);
        addBits(out, &e.stress, sizeof e.stress);
    }
    const double t = world.time();
    addBits(out, &t, sizeof t);
    return out;
}

int countEvents(const World& world, EventType type) {
    return static_cast<int>(std::count_if(world.events().begin(), world.events().end(), [&](const auto& e) { return e.type == type; }));
}

// --- a cloth pulled apart over a sphere, holding a weight -----------------------------------

/// A 9 x 7 cloth (8 x 6 cm) lying flat at y = 1: its left column pinned, its right column
/// pinned and pulled along +x at 5 cm/s until the cloth tears across; a static sphere
/// under its middle that it sags onto; a 2 g weight glued under vertex (6, 1); random
/// material variation and viscoplastic yarns.
struct ClothScene {
    World world;
    SphereContacts contacts{world};
    ClothId cloth;
    ClothDesc desc;

    explicit ClothScene(bool build = true) {
        world.setContactProvider(&contacts);
        contacts.spheres.push_back({RigidId{0}, 0.025});
        desc.name = "weave";
        desc.corner = {0.0, 1.0, 0.0};
        desc.resolution = {9, 7};
        desc.size = {0.08, 0.06};
        desc.damping = 1.0;
        desc.plastic_time = 0.05;
        desc.material.variation = 0.05;
        desc.seed = 5;
        pinSides();
        if (build) create();
    }
    /// The first and last columns pinned where they start (flat indices: again after a
    /// change of resolution).
    void pinSides() {
        desc.attachments.clear();
        for (int j = 0; j < desc.resolution[1]; ++j) {
            desc.attachments.push_back({desc.vertex(0, j)});
            desc.attachments.push_back({desc.vertex(-1, j)});
        }
    }
    /// The bodies and the cloth (what a user builds again before loading a snapshot).
    void create() {
        pinSides();
        RigidState sphere;  // slot 0: static, under the middle of the cloth
        sphere.position = {0.04, 0.974, 0.03};
        world.addRigid(sphere);
        cloth = world.addCloth(desc);
        const int glued = desc.vertex(6, 1);
        const Vec3 at = (*world.viewCloth(cloth).positions)[static_cast<std::size_t>(glued)];
        RigidState weight;  // slot 1: dynamic, glued under a vertex
        weight.position = at - Vec3(0, 0.005, 0);
        weight.inverse_mass = 1.0 / 0.002;
        weight.inverse_inertia_local = tearables::Mat3::Identity() * 1e4;
        const RigidId w = world.addRigid(weight);
        world.attachClothToRigid(cloth, glued, w, {0, 0.005, 0});
    }
    /// One step with the scripted drivers (functions of the step number only).
    void step() {
        const auto k = static_cast<double>(world.stepCount());
        for (int j = 0; j < desc.resolution[1]; ++j) {
            const int p = desc.vertex(-1, j);
            const Vec3 x = (*world.viewCloth(cloth).positions)[static_cast<std::size_t>(p)];
            world.moveClothPin(cloth, p, x + Vec3(0.05 * 0.01, 0, 0));
        }
        world.applyClothForce(cloth, desc.vertex(3, 3), Vec3(0, 0, 1e-4 * std::sin(0.1 * k)));
        world.step(0.01);
    }
};

TEST(SnapshotMeshes, TearingClothContinuesBitIdenticallyAfterRestore) {
    constexpr int kBefore = 12, kAfter = 188;  // the first yarn tears at step 18
    ClothScene a;
    int tears = 0;
    for (int i = 0; i < kBefore; ++i) {
        a.step();
        tears += countEvents(a.world, EventType::Tear);
    }
    EXPECT_EQ(tears, 0);  // the interesting part is still to come
    std::stringstream file;
    tearables::saveSnapshot(a.world, file);
    const long long touched_before = a.contacts.reported;
    std::vector<std::string> expected;
    int yields = 0;
    for (int i = 0; i < kAfter; ++i) {
        a.step();
        tears += countEvents(a.world, EventType::Tear);
        yields += countEvents(a.world, EventType::Yield);
        expected.push_back(fingerprint(a.world));
    }
    // What the continuation covers: tears, plastic yield, the sphere, the glued weight moving.
    EXPECT_GE(tears, 3);
    EXPECT_GT(yields, 0);
    EXPECT_GT(a.contacts.reported, touched_before);
    EXPECT_FALSE(a.world.viewCloth(a.cloth).frozen);
    std::printf("cloth: %d tears, %d yields, %lld sphere contacts after the snapshot\n", tears, yields,
                a.contacts.reported - touched_before);

    ClothScene b(false);  // a fresh world: only the contact provider
    tearables::loadSnapshot(b.world, file);
    ASSERT_EQ(b.world.cloths(), a.world.cloths());
    b.cloth = a.cloth;
    EXPECT_EQ(b.world.stepCount(), kBefore);
    for (int i = 0; i < kAfter; ++i) {
        b.step();
        ASSERT_TRUE(fingerprint(b.world) == expected[static_cast<std::size_t>(i)]) << "diverged at step " << kBefore + i + 1;
    }
    // Saving the restored world gives the bytes of saving the uninterrupted one.
    std::stringstream one, two;
    tearables::saveSnapshot(a.world, one);
    tearables::saveSnapshot(b.world, two);
    EXPECT_TRUE(one.str() == two.str());
}

// --- a sheet pressed into creases, then torn, holding a weight --------------------------------

/// A 20 x 10 cm sheet (21 x 11 vertices) at y = 1 held at its four corners; a kinematic
/// sphere (4 cm) presses its middle down 6 cm and leaves (creases), then the two near
/// corners are pulled apart at 4 cm/s (it tears between them); a 5 g weight hangs glued
/// under a far-side vertex.
struct PaperScene {
    World world;
    SphereContacts contacts{world};
    PaperId sheet;
    PaperDesc desc;
    std::uint32_t left = 0, right = 0;
    Vec3 left0, right0;

    explicit PaperScene(bool build = true) {
        world.setContactProvider(&contacts);
        contacts.spheres.push_back({RigidId{0}, 0.04});
        desc.name = "sheet";
        desc.center = {0.0, 1.0, 0.0};
        desc.size[0] = 0.2;
        desc.size[1] = 0.1;
        desc.resolution[0] = 21;
        desc.resolution[1] = 11;
        desc.tearable = true;
        desc.rupture_stretch = 0.02;
        desc.seed = 9;
        left = static_cast<std::uint32_t>(desc.gridVertex(0, 0));
        right = static_cast<std::uint32_t>(desc.gridVertex(desc.resolution[0] - 1, 0));
        for (int k : {0, desc.resolution[1] - 1})
            for (int i : {0, desc.resolution[0] - 1})
                desc.attachments.push_back(PaperAttachment{static_cast<int>(desc.gridVertex(i, k)), {}, Vec3::Zero(), {}});
        if (build) create();
    }
    void create() {
        RigidState ball;  // slot 0: kinematic, moved by the script
        ball.position = {0.0, 1.05, 0.0};
        world.addRigid(ball);
        sheet = world.addPaper(desc);
        const auto& x = *world.viewPaper(sheet).positions;
        left0 = x[left];
        right0 = x[right];
        const auto glued = static_cast<std::uint32_t>(desc.gridVertex(14, 8));
        RigidState weight;  // slot 1: dynamic, glued under a vertex
        weight.position = x[glued] - Vec3(0, 0.01, 0);
        weight.inverse_mass = 1.0 / 0.005;
        weight.inverse_inertia_local = tearables::Mat3::Identity() * 1e4;
        const RigidId w = world.addRigid(weight);
        world.attachPaperToRigid(sheet, glued, w, {0, 0.01, 0});
    }
    void step() {
        const long long k = world.stepCount();
        const double h = 1.0 / 60.0;
        // The sphere: down at 0.3 m/s for 0.5 s, up for 0.5 s, then away.
        Vec3& ball = world.rigid(RigidId{0}).position;
        ball.y() += (k < 30 ? -0.3 : k < 60 ? 0.3 : 0.0) * h;
        if (k == 60) ball = {0.0, 2.0, 0.0};
        // From step 60 the near corners move apart.
        if (k >= 60) {
            const double pull = 0.04 * static_cast<double>(k - 59) * h;
            world.movePaperPin(sheet, left, left0 - Vec3(pull, 0, 0));
            world.movePaperPin(sheet, right, right0 + Vec3(pull, 0, 0));
        }
        world.step(h);
    }
};

TEST(SnapshotMeshes, CreasedTearingPaperContinuesBitIdenticallyAfterRestore) {
    constexpr int kBefore = 20, kAfter = 160;
    PaperScene a;
    int creases = 0, tears = 0, hinges = 0;
    for (int i = 0; i < kBefore; ++i) {
        a.step();
        creases += countEvents(a.world, EventType::Crease);
    }
    std::stringstream file;
    tearables::saveSnapshot(a.world, file);
    const long long touched_before = a.contacts.reported;
    const auto counters_before = a.world.viewPaper(a.sheet).counters;
    std::vector<std::string> expected;
    for (int i = 0; i < kAfter; ++i) {
        a.step();
        creases += countEvents(a.world, EventType::Crease);
        tears += countEvents(a.world, EventType::Tear);
        hinges += countEvents(a.world, EventType::Hinge);
        expected.push_back(fingerprint(a.world));
    }
    const auto counters = a.world.viewPaper(a.sheet).counters;
    // What the continuation covers: creases and tears after the snapshot, the sphere.
    EXPECT_GT(counters.creases, counters_before.creases);
    EXPECT_GT(counters.tears, counters_before.tears);
    EXPECT_GT(a.contacts.reported, touched_before);
    EXPECT_FALSE(a.world.viewPaper(a.sheet).frozen);
    std::printf("paper: %d creases (%llu before the snapshot), %d hinges, %d tears, %zu vertices, %lld sphere contacts after\n",
                creases, static_cast<unsigned long long>(counters_before.creases), hinges, tears,
                a.world.viewPaper(a.sheet).vertexCount(), a.contacts.reported - touched_before);

    PaperScene b(false);  // a fresh world: only the contact provider
    tearables::loadSnapshot(b.world, file);
    ASSERT_EQ(b.world.papers(), a.world.papers());
    b.sheet = a.sheet;
    b.left0 = a.left0;
    b.right0 = a.right0;
    for (int i = 0; i < kAfter; ++i) {
        b.step();
        ASSERT_TRUE(fingerprint(b.world) == expected[static_cast<std::size_t>(i)]) << "diverged at step " << kBefore + i + 1;
    }
    std::stringstream one, two;
    tearables::saveSnapshot(a.world, one);
    tearables::saveSnapshot(b.world, two);
    EXPECT_TRUE(one.str() == two.str());
}

// --- a world with other cloths or sheets refuses the snapshot ----------------------------------

/// A snapshot of a world with the cloth scene's cloth and the paper scene's sheet (both
/// stepped a while).
struct BothScene {
    ClothScene cloth;
    PaperScene paper{false};
    BothScene() { paper.sheet = cloth.world.addPaper(paper.desc); }  // held at its corners only
};

/// Loads `bytes` into `world` (which has run); it must be refused naming `field` with
/// `message` in the problem, and the world must be exactly as it was, and step on.
template <class Step>
void expectRefused(World& world, Step step, const std::string& bytes, const std::string& field, const std::string& message,
                   const std::string& label) {
    const std::string before = fingerprint(world);
    const auto steps = world.stepCount();
    std::stringstream in(bytes);
    try {
        tearables::loadSnapshot(world, in);
        ADD_FAILURE() << label << ": accepted";
    } catch (const SnapshotError& e) {
        EXPECT_EQ(e.field(), field) << label << ": " << e.what();
        EXPECT_NE(e.problem().find(message), std::string::npos) << label << ": " << e.what();
    }
    EXPECT_EQ(world.stepCount(), steps) << label;
    EXPECT_TRUE(fingerprint(world) == before) << label;
    step();
    EXPECT_EQ(world.stepCount(), steps + 1) << label;
}

TEST(SnapshotMeshes, WorldWithOtherClothsOrSheetsRefusesAndChangesNothing) {
    BothScene saved;
    for (int i = 0; i < 10; ++i) saved.cloth.step();
    std::stringstream out;
    tearables::saveSnapshot(saved.cloth.world, out);
    const std::string bytes = out.str();

    {  // The same objects, built again and stepped differently: accepted, and replaced bit for bit.
        BothScene same;
        same.cloth.world.step(0.01);
        std::stringstream in(bytes);
        tearables::loadSnapshot(same.cloth.world, in);
        same.cloth.step();  // (the last step's events are not state: compare after a step)
        BothScene again;
        for (int i = 0; i < 11; ++i) again.cloth.step();
        EXPECT_TRUE(fingerprint(same.cloth.world) == fingerprint(again.cloth.world));
    }
    {  // A cloth of another resolution.
        ClothScene other(false);
        other.desc.resolution = {10, 7};
        other.create();
        for (int i = 0; i < 3; ++i) other.step();
        expectRefused(other.world, [&] { other.step(); }, bytes, "snapshot.CLTH", "resolution 10 x 7 in the world and 9 x 7 in the snapshot",
                      "other resolution");
    }
    {  // The same cloth from another seed (its material differs).
        ClothScene other(false);
        other.desc.seed = 6;
        other.create();
        expectRefused(other.world, [&] { other.step(); }, bytes, "snapshot.CLTH", "cloth 0 (\"weave\") was created from another descriptor",
                      "other seed");
    }
    {  // The same cloth with one weak yarn (its material differs at that yarn alone).
        ClothScene other(false);
        other.desc.weak_yarns = {{4, 3, tearables::YarnKind::Warp, 0.9}};
        other.create();
        expectRefused(other.world, [&] { other.step(); }, bytes, "snapshot.CLTH", "cloth 0 (\"weave\") was created from another descriptor",
                      "a weak yarn");
    }
    {  // Another name.
        ClothScene other(false);
        other.desc.name = "flag";
        other.create();
        expectRefused(other.world, [&] { other.step(); }, bytes, "snapshot.CLTH", "cloth 0 is \"flag\" in the world and \"weave\" in the snapshot",
                      "other name");
    }
    {  // One cloth more.
        ClothScene other;
        ClothDesc extra = other.desc;
        extra.name = "extra";
        extra.corner = {1, 1, 0};
        other.world.addCloth(extra);
        expectRefused(other.world, [&] { other.step(); }, bytes, "snapshot.CLTH", "the world has cloth 1 (\"extra\"), which the snapshot does not have",
                      "a cloth more");
    }
    {  // The cloth, but no sheet where the snapshot has one: the sheet is missing.
        BothScene other;
        other.cloth.world.removePaper(other.paper.sheet);
        PaperDesc moved = other.paper.desc;
        moved.name = "note";
        other.cloth.world.addPaper(moved);  // takes slot 0 again, under another name
        expectRefused(other.cloth.world, [&] { other.cloth.step(); }, bytes, "snapshot.PAPR",
                      "paper sheet 0 is \"note\" in the world and \"sheet\" in the snapshot", "other sheet");
    }
    {  // A sheet of another stiffness.
        BothScene other;
        other.cloth.world.removePaper(other.paper.sheet);
        PaperDesc stiffer = other.paper.desc;
        stiffer.stiffness *= 2.0;
        other.cloth.world.addPaper(stiffer);
        expectRefused(other.cloth.world, [&] { other.cloth.step(); }, bytes, "snapshot.PAPR",
                      "paper sheet 0 (\"sheet\") was created from another descriptor", "stiffer sheet");
    }
    {  // A world with only a sheet, where the snapshot has one more slot of sheets.
        World only;
        only.addPaper(saved.paper.desc);
        only.addPaper(saved.paper.desc);
        expectRefused(only, [&] { only.step(0.01); }, bytes, "snapshot.PAPR", "the world has paper sheet 1 (\"sheet\"), which the snapshot does not have",
                      "a sheet more");
    }

    // Inconsistent slot counts behind a valid checksum: WRLD's cloth and paper slot counts.
    auto resealed = [](std::string file) {
        std::uint64_t h = 1469598103934665603ull;
        for (std::size_t i = 0; i + 8 < file.size(); ++i) {
            h ^= static_cast<unsigned char>(file[i]);
            h *= 1099511628211ull;
        }
        for (int i = 0; i < 8; ++i) file[file.size() - 8 + static_cast<std::size_t>(i)] = static_cast<char>((h >> (8 * i)) & 0xff);
        return file;
    };
    const std::size_t at = bytes.find("WRLD");
    ASSERT_NE(at, std::string::npos);
    // WRLD payload: settings (3 + 2 + 2 + 3 words), time, steps, string, body, cloth, paper slots.
    const std::size_t cloth_slots = at + 4 + 8 + 8 * (3 + 2 + 2 + 3 + 2 + 2);
    std::string more = bytes;
    more[cloth_slots] = static_cast<char>(more[cloth_slots] + 1);
    World fresh;
    expectRefused(fresh, [&] { fresh.step(0.01); }, resealed(more), "snapshot", "has 1 cloth sections for 2 cloth slots", "cloth slots");
    std::string fewer = bytes;
    fewer[cloth_slots + 8] = 0;
    expectRefused(fresh, [&] { fresh.step(0.01); }, resealed(fewer), "snapshot.PAPR", "more paper sections than the world has paper slots",
                  "paper slots");
    EXPECT_TRUE(fresh.papers().empty());
    EXPECT_TRUE(fresh.cloths().empty());
}

// A damaged cloth or sheet behind a valid checksum (written from a world whose state was
// broken on purpose: the writer does not check) is refused naming the section and what is
// wrong, and the world it was loaded into stays as it was.
TEST(SnapshotMeshes, DamagedClothsAndSheetsAreRefusedAndChangeNothing) {
    auto damaged = [](auto&& spoil) {
        BothScene scene;
        for (int i = 0; i < 3; ++i) scene.cloth.step();
        spoil(tearables::detail::WorldAccess::parts(scene.cloth.world));
        std::stringstream out;
        tearables::saveSnapshot(scene.cloth.world, out);
        return out.str();
    };
    struct Case {
        std::string bytes, field, message;
    };
    const Case cases[] = {
        {damaged([](const tearables::detail::WorldParts& w) { w.papers->at(0).triangles[3][1] = 100000; }), "snapshot.PAPR[0]",
         "triangle 3 names vertex 100000"},
        {damaged([](const tearables::detail::WorldParts& w) { w.papers->at(0).vertex_springs[5].push_back(0); }), "snapshot.PAPR[0]",
         "vertex 5 lists spring 0, which does not name it"},
        {damaged([](const tearables::detail::WorldParts& w) { w.papers->at(0).survived.pop_back(); }), "snapshot.PAPR[0]", "survived has"},
        {damaged([](const tearables::detail::WorldParts& w) { w.papers->at(0).mass[7] *= 2.0; }), "snapshot.PAPR[0]",
         "do not sum to the sheet's mass"},
        {damaged([](const tearables::detail::WorldParts& w) {
             auto& hold = w.papers->at(0).hold[9];
             hold.kind = tearables::detail::ParticleHold::Kind::Glue;
             hold.body = RigidId{7};
         }),
         "snapshot.PAPR[0]", "vertex 9 is glued to rigid slot 7"},
        {damaged([](const tearables::detail::WorldParts& w) { w.cloths->at(0).edges[4][0] = 500; }), "snapshot.CLTH[0]",
         "lists edge 4, which does not end at it"},
        {damaged([](const tearables::detail::WorldParts& w) { w.cloths->at(0).edge_springs[2].push_back(99999); }), "snapshot.CLTH[0]",
         "edge 2 names soft spring 99999"},
        {damaged([](const tearables::detail::WorldParts& w) { w.cloths->at(0).nu = 8; }), "snapshot.CLTH[0]",
         "does not match the descriptor's resolution"},
        {damaged([](const tearables::detail::WorldParts& w) { w.cloths->at(0).tension.pop_back(); }), "snapshot.CLTH[0]", "a per-edge array"},
    };
    for (const Case& c : cases) {
        ClothScene target;
        for (int i = 0; i < 2; ++i) target.step();
        expectRefused(target.world, [&] { target.step(); }, c.bytes, c.field, c.message, c.message);
    }
}

// --- both in a Bullet world -----------------------------------------------------------------

/// The cloth scene and the paper scene side by side in a Bullet world: a 2 g box hangs
/// glued under the cloth, which is pulled apart; a 2 kg ball driven down at 0.3 m/s for
/// 0.25 s and back up presses the sheet (held at its corners, a 5 g box glued under it),
/// whose near corners are then pulled apart. No body touches another.
struct BulletMeshScene {
    tearables::testing::Physics phys;
    btRigidBody* weight;
    btRigidBody* ball;
    btRigidBody* paperweight;
    std::unique_ptr<tearables::BulletWorld> meshes;
    ClothScene cloth_spec{false};
    PaperScene paper_spec{false};
    ClothId cloth;
    PaperId sheet;
    Vec3 left0, right0;

    BulletMeshScene() {
        meshes = std::make_unique<tearables::BulletWorld>(*phys.world);
        cloth = meshes->addCloth(cloth_spec.desc);
        const ClothDesc& cd = cloth_spec.desc;
        const Vec3 c = (*meshes->core().viewCloth(cloth).positions)[static_cast<std::size_t>(cd.vertex(6, 1))];
        weight = &phys.box(btVector3(0.005f, 0.005f, 0.005f), 0.002,
                           btVector3(static_cast<btScalar>(c.x()), static_cast<btScalar>(c.y() - 0.005), static_cast<btScalar>(c.z())));
        meshes->attachCloth(cloth, cd.vertex(6, 1), *weight, btVector3(0, 0.005f, 0));
        PaperDesc pd = paper_spec.desc;
        pd.center = {1.0, 1.0, 0.0};
        sheet = meshes->addPaper(pd);
        const auto& x = *meshes->core().viewPaper(sheet).positions;
        left0 = x[paper_spec.left];
        right0 = x[paper_spec.right];
        const Vec3 g = x[static_cast<std::size_t>(pd.gridVertex(14, 8))];
        paperweight = &phys.box(btVector3(0.01f, 0.01f, 0.01f), 0.005,
                                btVector3(static_cast<btScalar>(g.x()), static_cast<btScalar>(g.y() - 0.01), static_cast<btScalar>(g.z())));
        meshes->attachPaper(sheet, static_cast<std::uint32_t>(pd.gridVertex(14, 8)), *paperweight, btVector3(0, 0.01f, 0));
        ball = &phys.sphere(0.04, 2.0, btVector3(1.0f, 1.05f, 0));
    }
    std::vector<const btRigidBody*> constBodies() const { return {weight, ball, paperweight}; }
    std::vector<btRigidBody*> bodies() { return {weight, ball, paperweight}; }
    void step() {
        World& core = meshes->core();
        const long long k = core.stepCount();
        for (int j = 0; j < cloth_spec.desc.resolution[1]; ++j) {
            const int p = cloth_spec.desc.vertex(-1, j);
            const Vec3 x = (*core.viewCloth(cloth).positions)[static_cast<std::size_t>(p)];
            core.moveClothPin(cloth, p, x + Vec3(0.05 * 0.01, 0, 0));
        }
        const double vy = k < 25 ? -0.3 : k < 50 ? 0.3 : 0.0;
        ball->setLinearVelocity(btVector3(0, static_cast<btScalar>(vy), 0));
        ball->setAngularVelocity(btVector3(0, 0, 0));
        ball->activate();
        if (k >= 60) {
            const double pull = 0.04 * static_cast<double>(k - 59) * 0.01;
            core.movePaperPin(sheet, paper_spec.left, left0 - Vec3(pull, 0, 0));
            core.movePaperPin(sheet, paper_spec.right, right0 + Vec3(pull, 0, 0));
        }
        phys.step(1);
    }
    std::string state() const {
        std::string out = fingerprint(meshes->core());
        for (const btRigidBody* b : {weight, ball, paperweight}) {
            tearables::testing::appendBodyBits(out, *b);
        }
        return out;
    }
};

using tearables::testing::BodyState;

TEST(SnapshotMeshes, BulletClothAndPaperContinueBitIdenticallyAfterRestore) {
    constexpr int kBefore = 12, kAfter = 148;
    BulletMeshScene a;
    for (int i = 0; i < kBefore; ++i) a.step();
    std::stringstream file;
    a.meshes->saveSnapshot(file, a.constBodies());
    std::vector<BodyState> saved;
    for (const btRigidBody* b : a.constBodies()) saved.emplace_back(*b);
    const auto counters_before = a.meshes->core().viewPaper(a.sheet).counters;
    int cloth_tears = 0;
    std::vector<std::string> expected;
    for (int i = 0; i < kAfter; ++i) {
        a.step();
        for (const auto& e : a.meshes->core().events()) cloth_tears += e.type == EventType::Tear && e.object == "weave";
        expected.push_back(a.state());
    }
    EXPECT_TRUE(a.meshes->lastError().empty()) << a.meshes->lastError();
    const auto counters = a.meshes->core().viewPaper(a.sheet).counters;
    EXPECT_GT(cloth_tears, 0);
    EXPECT_GT(counters.creases, counters_before.creases);
    EXPECT_GT(counters.tears, counters_before.tears);
    std::printf("bullet: %d cloth tears, %llu creases and %llu paper tears after the snapshot\n", cloth_tears,
                static_cast<unsigned long long>(counters.creases - counters_before.creases),
                static_cast<unsigned long long>(counters.tears - counters_before.tears));

    BulletMeshScene b;  // the same bodies, cloth and sheet, fresh; then the saved state
    for (std::size_t i = 0; i < saved.size(); ++i) saved[i].applyTo(*b.bodies()[i]);
    b.meshes->loadSnapshot(file, b.bodies());
    for (int i = 0; i < kAfter; ++i) {
        b.step();
        ASSERT_TRUE(b.state() == expected[static_cast<std::size_t>(i)]) << "diverged at step " << kBefore + i + 1;
    }
}

}  // namespace
