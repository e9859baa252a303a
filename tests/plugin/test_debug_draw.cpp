// Debug drawing through btIDebugDraw: a recording drawer checks what the plugin draws.
#include "tearables/bullet_core.hpp"
#include "tearables/colormap.hpp"

#include "bullet_fixture.hpp"

#include <btBulletDynamicsCommon.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <vector>

namespace {

using tearables::BulletWorld;
using tearables::StringDesc;
using tearables::StringId;
using tearables::testing::Physics;

/// Records lines and spheres; everything else Bullet may call is counted as "other".
class RecordingDraw : public btIDebugDraw {
public:
    struct Line {
        btVector3 from, to, color;
    };
    std::vector<Line> lines;
    std::vector<btVector3> spheres;      // centres
    std::vector<btVector3> sphere_colors;
    int other = 0;
    int mode = DBG_DrawWireframe;

    void drawLine(const btVector3& from, const btVector3& to, const btVector3& color) override {
        lines.push_back({from, to, color});
    }
    void drawSphere(const btVector3& p, btScalar, const btVector3& color) override {
        spheres.push_back(p);
        sphere_colors.push_back(color);
    }
    void drawContactPoint(const btVector3&, const btVector3&, btScalar, int, const btVector3&) override { ++other; }
    void reportErrorWarning(const char*) override { ++other; }
    void draw3dText(const btVector3&, const char*) override { ++other; }
    void setDebugMode(int m) override { mode = m; }
    int getDebugMode() const override { return mode; }
};

double lum(const btVector3& c) { return tearables::luminance({float(c.x()), float(c.y()), float(c.z())}); }

/// A 1 m rope pinned at its top whose material tears at a low stress, so that its own weight
/// loads the top segment to about half the rupture tension: tension (and colour) then grows
/// from the free end to the pin.
StringDesc softRope() {
    StringDesc d = StringDesc::straight({0, 2, 0}, {0, 1, 0}, 20);
    d.material.variation = 0.0;
    d.material.tensile.young = 1e6;             // Pa
    d.material.tensile.yield = 2.0e4;           // Pa
    d.material.tensile.plastic_modulus = 1e5;   // Pa
    d.material.tensile.rupture = 2.26e4;        // Pa: weight 0.142 N ~ half of 2.26e4 * pi r^2
    d.tearable = false;
    d.damping = 2.0;
    return d;
}

}  // namespace

// One line per intact segment, between its particles, in the colour of its load fraction;
// sorted by tension, the colours' luminance never falls (the map's order survives).
TEST(DebugDraw, LinesFollowTensionOrder) {
    Physics phys;
    BulletWorld ropes(*phys.world);
    const StringDesc desc = softRope();
    const StringId id = ropes.addString(desc);
    ropes.attach(id, 0, btVector3(0, 2, 0));
    phys.step(200);
    RecordingDraw rec;
    ropes.debugDraw(rec);
    const auto v = ropes.core().view(id);
    ASSERT_EQ(rec.lines.size(), v.segmentCount());
    EXPECT_TRUE(rec.spheres.empty());
    std::vector<std::size_t> order(v.segmentCount());
    for (std::size_t j = 0; j < order.size(); ++j) {
        order[j] = j;
        EXPECT_NEAR(rec.lines[j].from.y(), (*v.positions)[j].y(), 1e-5);
        EXPECT_NEAR(rec.lines[j].to.y(), (*v.positions)[j + 1].y(), 1e-5);
        const tearables::Rgb want = tearables::tensionColor(
            tearables::loadFraction((*v.tension)[j], desc.material.tensile.rupture, v.radius));
        EXPECT_NEAR(rec.lines[j].color.x(), want.r, 1e-6);
        EXPECT_NEAR(rec.lines[j].color.y(), want.g, 1e-6);
        EXPECT_NEAR(rec.lines[j].color.z(), want.b, 1e-6);
    }
    std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return (*v.tension)[a] < (*v.tension)[b]; });
    for (std::size_t k = 1; k < order.size(); ++k)
        EXPECT_LE(lum(rec.lines[order[k - 1]].color), lum(rec.lines[order[k]].color) + 1e-9) << "segments " << order[k - 1] << ", " << order[k];
    // The loads span a good part of the map: top segment well above the bottom one.
    const double top = tearables::loadFraction(v.tension->front(), desc.material.tensile.rupture, v.radius);
    const double bottom = tearables::loadFraction(v.tension->back(), desc.material.tensile.rupture, v.radius);
    EXPECT_GT(top, 0.3);
    EXPECT_LT(bottom, 0.1);
    EXPECT_GT(lum(rec.lines.front().color), lum(rec.lines.back().color) + 0.1);
}

// After a tear: lines only for the intact segments, a magenta marker per broken one.
TEST(DebugDraw, BrokenSegmentsAreMarkedNotDrawn) {
    Physics phys;
    BulletWorld ropes(*phys.world);
    StringDesc desc = StringDesc::straight({0, 2, 0}, {0, 1, 0}, 10);
    desc.material.variation = 0.0;
    desc.particle_masses = {{-1, 200.0}};  // 1962 N on a rope that tears at ~1005 N
    const StringId id = ropes.addString(desc);
    ropes.attach(id, 0, btVector3(0, 2, 0));
    int steps = 0;
    auto broken = [&] { return std::count(ropes.core().view(id).broken->begin(), ropes.core().view(id).broken->end(), 1); };
    while (broken() == 0 && steps < 200) {
        phys.step(1);
        ++steps;
    }
    ASSERT_LT(steps, 200) << "the rope never tore";
    RecordingDraw rec;
    ropes.debugDraw(rec);
    const auto n_broken = static_cast<std::size_t>(broken());
    EXPECT_EQ(rec.lines.size(), desc.points.size() - 1 - n_broken);
    ASSERT_EQ(rec.spheres.size(), n_broken);
    for (const btVector3& c : rec.sphere_colors) EXPECT_EQ(c, BulletWorld::brokenMarkerColor());
}

// Bullet's own debugDrawWorld() reaches the strings through the plugin's action.
TEST(DebugDraw, DebugDrawWorldDrawsStrings) {
    Physics phys;
    BulletWorld ropes(*phys.world);
    const StringId id = ropes.addString(StringDesc::straight({0, 2, 0}, {1, 2, 0}, 12));
    ropes.attach(id, 0, btVector3(0, 2, 0));
    RecordingDraw rec;
    phys.world->setDebugDrawer(&rec);
    phys.world->debugDrawWorld();
    phys.world->setDebugDrawer(nullptr);
    EXPECT_EQ(rec.lines.size(), 12u);
}

namespace {

std::size_t countColor(const RecordingDraw& rec, const btVector3& color) {
    return static_cast<std::size_t>(
        std::count_if(rec.lines.begin(), rec.lines.end(), [&](const RecordingDraw::Line& l) { return l.color == color; }));
}

}  // namespace

// A flat sheet: each triangle edge once, in the paper's colour, and no crease lines. Pushed
// together from two sides it creases: then the crease lines are drawn too, one per line
// paperCreaseLines gives, and the edges are still each drawn once.
TEST(DebugDraw, PaperEdgesOnceAndCreasesInTheirColour) {
    using namespace tearables;
    Physics phys(0.0);
    BulletWorld paper(*phys.world);
    PaperDesc d;
    d.center = Vec3(0, 1, 0);
    d.size[0] = 0.1;
    d.size[1] = 0.1;
    d.resolution[0] = 11;
    d.resolution[1] = 11;
    d.seed = 3;
    for (int k = 0; k < 11; ++k)
        for (int i : {0, 10}) d.attachments.push_back(PaperAttachment{static_cast<int>(d.gridVertex(i, k)), {}, Vec3::Zero(), {}});
    const PaperId id = paper.addPaper(d);
    auto uniqueEdges = [&] {
        std::vector<std::array<std::uint32_t, 2>> e;
        for (const auto& t : *paper.core().viewPaper(id).triangles)
            for (int c = 0; c < 3; ++c) e.push_back({std::min(t[c], t[(c + 1) % 3]), std::max(t[c], t[(c + 1) % 3])});
        std::sort(e.begin(), e.end());
        return static_cast<std::size_t>(std::unique(e.begin(), e.end()) - e.begin());
    };
    RecordingDraw flat;
    paper.debugDraw(flat);
    EXPECT_EQ(flat.lines.size(), 10u * 11u * 2u + 10u * 10u);  // rows, columns, diagonals
    EXPECT_EQ(countColor(flat, BulletWorld::paperColor()), flat.lines.size());
    // Push the x+ edge 2 cm toward the other in 0.5 s, with a slight lift to start the buckle.
    for (int step = 0; step < 50; ++step) {
        for (int k = 0; k < 11; ++k) {
            const auto v = static_cast<std::uint32_t>(d.gridVertex(10, k));
            paper.core().movePaperPin(id, v, Vec3(0.1 - 0.0004 * (step + 1), 1.0, k * 0.01));
        }
        paper.core().applyPaperForce(id, static_cast<std::uint32_t>(d.gridVertex(5, 5)), Vec3(0, 1e-4, 0));
        phys.step(1, 0.01);
    }
    const PaperView v = paper.core().viewPaper(id);
    ASSERT_GT(v.counters.creases, 0u) << "the pushed sheet did not crease";
    RecordingDraw creased;
    paper.debugDraw(creased);
    EXPECT_EQ(countColor(creased, BulletWorld::paperColor()), uniqueEdges());
    EXPECT_EQ(countColor(creased, BulletWorld::creaseColor()), paperCreaseLines(v).size());
    EXPECT_GT(paperCreaseLines(v).size(), 0u);
    EXPECT_EQ(creased.lines.size(), uniqueEdges() + paperCreaseLines(v).size());
}

// A cloth: one line per yarn edge, coloured by its load like a string's.
TEST(DebugDraw, ClothYarnsColouredByLoad) {
    using namespace tearables;
    Physics phys;
    BulletWorld ropes(*phys.world);
    ClothDesc d;
    d.corner = Vec3(0, 2, 0);
    d.size = {0.2, 0.2};
    d.resolution = {5, 4};
    const ClothId id = ropes.addCloth(d);
    ropes.attachCloth(id, d.vertex(0, 0), btVector3(0, 2, 0));
    ropes.attachCloth(id, d.vertex(4, 0), btVector3(0.2f, 2, 0));
    phys.step(20);
    const ClothView v = ropes.core().viewCloth(id);
    RecordingDraw rec;
    ropes.debugDraw(rec);
    ASSERT_EQ(rec.lines.size(), v.edgeCount());  // 4 x 4 warp + 5 x 3 weft, none torn
    EXPECT_EQ(rec.lines.size(), 31u);
    for (std::size_t e = 0; e < v.edgeCount(); ++e) {
        const Rgb c = tensionColor(loadFraction((*v.tension)[e], d.material.tensile.rupture, v.yarn_radius));
        EXPECT_EQ(rec.lines[e].color, btVector3(c.r, c.g, c.b)) << "edge " << e;
    }
}
