// Paper sheets in a Bullet world: a sphere presses a sheet and leaves creases (Paper
// Fig. 10); a sheet holds a light box resting on it; vertices glued to a body hold it.
#include "bullet_fixture.hpp"
#include "paper/sheet.hpp"
#include "../paper/paper_helpers.hpp"
#include "tearables/bullet_core.hpp"

#include <gtest/gtest.h>

#include <cstdio>

namespace tearables {
namespace {

using testing::Physics;

constexpr double kH = 1.0 / 60.0;

/// A 20 cm sheet at y = 1, held at its four corners.
PaperDesc cornerSheet(bool breakable) {
    PaperDesc d;
    d.center = Vec3(0, 1, 0);
    d.size[0] = 0.2;
    d.size[1] = 0.2;
    d.resolution[0] = 21;
    d.resolution[1] = 21;
    d.breakable = breakable;
    d.seed = 5;
    for (int k : {0, d.resolution[1] - 1})
        for (int i : {0, d.resolution[0] - 1}) d.attachments.push_back(PaperAttachment{static_cast<int>(d.gridVertex(i, k)), {}, Vec3::Zero(), {}});
    return d;
}

/// Largest distance of a vertex from the plane y = 1 the sheet started in, m.
double deviation(const PaperView& v) {
    double worst = 0.0;
    for (const Vec3& x : *v.positions) worst = std::max(worst, std::abs(x.y() - 1.0));
    return worst;
}

/// Presses the sheet with a heavy sphere driven down (its bottom 14 cm past the sheet) and back up,
/// without gravity, then waits two seconds. Returns the deviation at the deepest point
/// and at the end.
std::pair<double, double> pressAndRelease(bool breakable, std::uint64_t* creases) {
    Physics p(0.0);
    BulletWorld paper(*p.world);
    const PaperId id = paper.addPaper(cornerSheet(breakable));
    btRigidBody& ball = p.sphere(0.04, 20.0, btVector3(0, 1.05, 0));
    double deepest = 0.0;
    for (int step = 0; step < 300; ++step) {
        // Down at 0.3 m/s for 0.5 s, back up at 0.3 m/s for 1 s, then still (far away).
        const double vy = step < 30 ? -0.3 : step < 90 ? 0.3 : 0.0;
        ball.setLinearVelocity(btVector3(0, static_cast<btScalar>(vy), 0));
        ball.setAngularVelocity(btVector3(0, 0, 0));
        ball.activate();
        p.step(1, kH);
        deepest = std::max(deepest, deviation(paper.core().viewPaper(id)));
        EXPECT_TRUE(testing::allFinite(paper.core().viewPaper(id)));
    }
    const PaperView v = paper.core().viewPaper(id);
    EXPECT_GT(ball.getCenterOfMassPosition().y(), 1.15);  // it has left
    EXPECT_EQ(detail::checkMesh(v, 0.08 * 0.2 * 0.2), "");
    EXPECT_EQ(paper.lastError(), "");
    if (creases) *creases = v.counters.creases + v.counters.hinges;
    return {deepest, deviation(v)};
}

TEST(PaperBullet, SpherePressKeepsCreasesAfterItLeaves) {
    std::uint64_t damage = 0, none = 0;
    const auto [deep_paper, kept_paper] = pressAndRelease(true, &damage);
    const auto [deep_elastic, kept_elastic] = pressAndRelease(false, &none);
    std::printf("pressed: %.4f m (breakable) %.4f m (elastic); after: %.5f m vs %.5f m, ratio %.1f; damage %llu vs %llu\n",
                deep_paper, deep_elastic, kept_paper, kept_elastic, kept_paper / std::max(kept_elastic, 1e-12),
                static_cast<unsigned long long>(damage), static_cast<unsigned long long>(none));
    // Both were pressed deep.
    EXPECT_GT(deep_paper, 0.03);
    EXPECT_GT(deep_elastic, 0.03);
    EXPECT_EQ(none, 0u);
    EXPECT_GT(damage, 0u);
    // The breakable sheet keeps its creases; the elastic one returns flat.
    EXPECT_GT(kept_paper, 5.0 * kept_elastic);
    EXPECT_GT(kept_paper, 0.002);
}

// Bodies touch a sheet between its vertices (the triangles' btDbvt and Bullet's GJK on
// each candidate triangle): a marble far smaller than the sheet's triangles, dropped onto
// the middle of one, is caught by the sheet instead of falling between the vertices, and
// its weight is carried by the sheet (its vertices sag). Vertices alone cannot see it: the
// nearest corner is 6 cm from a 1 cm marble (with them alone it falls through).
TEST(PaperBullet, SmallBallIsCaughtBetweenTheVertices) {
    Physics p;
    BulletWorld paper(*p.world);
    PaperDesc d;
    d.center = Vec3(0, 1, 0);
    d.size[0] = 0.3;
    d.size[1] = 0.3;
    d.resolution[0] = 4;  // 10 cm cells
    d.resolution[1] = 4;
    d.breakable = false;
    for (int k = 0; k < 4; ++k)
        for (int i = 0; i < 4; ++i)
            if (i == 0 || k == 0 || i == 3 || k == 3)
                d.attachments.push_back(PaperAttachment{static_cast<int>(d.gridVertex(i, k)), {}, Vec3::Zero(), {}});
    const PaperId id = paper.addPaper(d);
    // The centre of the middle cell, which is split into two triangles: a third of the way
    // along its diagonal lies inside one of them, well away from every corner.
    const double radius = 0.01;
    btRigidBody& marble = p.sphere(radius, 0.002, btVector3(0.012f, 1.06f, -0.011f));
    marble.getCollisionShape()->setMargin(0.001f);
    double low = 1e9, high = -1e9;
    for (int step = 0; step < 180; ++step) {
        p.step(1, kH);
        ASSERT_TRUE(testing::allFinite(paper.core().viewPaper(id)));
        if (step >= 120) {  // the last second
            low = std::min(low, static_cast<double>(marble.getCenterOfMassPosition().y()));
            high = std::max(high, static_cast<double>(marble.getCenterOfMassPosition().y()));
        }
    }
    const PaperView v = paper.core().viewPaper(id);
    double lowest = 1e9;
    for (const Vec3& x : *v.positions) lowest = std::min(lowest, x.y());
    const double y = marble.getCenterOfMassPosition().y();
    std::printf("marble centre %.4f m (%.4f to %.4f in the last second), sheet lowest vertex %.4f m\n", y, low, high, lowest);
    EXPECT_GT(y, lowest);            // above the sheet, not through it
    EXPECT_GT(y, 0.9);               // and not fallen away (free fall: 3.4 m below)
    EXPECT_LT(lowest, 1.0 - 1e-5);   // the sheet carries its weight: the inner vertices sag
    EXPECT_LT(high - low, 0.01);     // resting on it, not falling
    EXPECT_EQ(paper.lastError(), "");
}

TEST(PaperBullet, SheetHoldsALightBoxRestingOnIt) {
    Physics p;
    BulletWorld paper(*p.world);
    // A breakable sheet held at its four corners (it sags and creases under the box).
    const PaperDesc d = cornerSheet(true);
    const PaperId id = paper.addPaper(d);
    const double half = 0.015, mass = 0.005;  // a 3 cm, 5 g box on a 3.2 g sheet
    btRigidBody& box = p.box(btVector3(half, half, half), mass, btVector3(0, static_cast<btScalar>(1.0 + half + 0.002), 0));
    // Bullet's default margin (4 cm) is larger than this box: its corners would be
    // rounded to a blob. Small bodies need a small margin.
    box.getCollisionShape()->setMargin(0.001f);
    double low = 1e9, high = -1e9;
    for (int step = 0; step < 360; ++step) {
        p.step(1, kH);
        ASSERT_TRUE(testing::allFinite(paper.core().viewPaper(id)));
        if (step >= 300) {  // the last second
            low = std::min(low, static_cast<double>(box.getCenterOfMassPosition().y()));
            high = std::max(high, static_cast<double>(box.getCenterOfMassPosition().y()));
        }
    }
    const PaperView v = paper.core().viewPaper(id);
    double lowest = 1e9;
    for (const Vec3& x : *v.positions) lowest = std::min(lowest, x.y());
    const double bottom = box.getCenterOfMassPosition().y() - half;
    std::printf("box bottom %.4f m, sheet lowest %.4f m, box moved %.4f m in the last second, x %.4f z %.4f\n", bottom, lowest,
                high - low, box.getCenterOfMassPosition().x(), box.getCenterOfMassPosition().z());
    // It is held on the sheet: not through it (its bottom is not below the sheet's lowest
    // point), still in the middle, and no longer falling (it stays within 3 cm in the
    // last second, sinking slowly as the sheet keeps creasing under it; free fall would
    // take it 10 m).
    EXPECT_GT(bottom, lowest - 0.5 * v.thickness - 0.002);
    EXPECT_LT(std::hypot(box.getCenterOfMassPosition().x(), box.getCenterOfMassPosition().z()), 0.05);
    EXPECT_LT(high - low, 0.03);
    EXPECT_GT(bottom, 0.8);
    EXPECT_EQ(paper.lastError(), "");
}

TEST(PaperBullet, GluedVerticesHoldABody) {
    Physics p;
    BulletWorld paper(*p.world);
    PaperDesc d;
    d.center = Vec3(0, 1, 0);
    d.orientation = Quat(Eigen::AngleAxisd(0.5 * M_PI, Vec3::UnitX()));  // hanging: row 0 on top
    d.size[0] = 0.1;
    d.size[1] = 0.1;
    d.resolution[0] = 6;
    d.resolution[1] = 6;
    d.breakable = false;
    for (int i = 0; i < 6; ++i) d.attachments.push_back(PaperAttachment{static_cast<int>(i), {}, Vec3::Zero(), {}});
    const PaperId id = paper.addPaper(d);
    // A 2 g weight glued at the bottom corners.
    btRigidBody& weight = p.box(btVector3(0.05f, 0.005f, 0.005f), 0.002, btVector3(0, 0.945f, 0));
    paper.attachPaper(id, static_cast<std::uint32_t>(d.gridVertex(0, 5)), weight, btVector3(-0.05f, 0.005f, 0));
    paper.attachPaper(id, static_cast<std::uint32_t>(d.gridVertex(5, 5)), weight, btVector3(0.05f, 0.005f, 0));
    double low = 1e9, high = -1e9;
    for (int step = 0; step < 120; ++step) {
        p.step(1, kH);
        if (step >= 90) {
            low = std::min(low, static_cast<double>(weight.getCenterOfMassPosition().y()));
            high = std::max(high, static_cast<double>(weight.getCenterOfMassPosition().y()));
        }
    }
    std::printf("glued weight: between %.4f and %.4f m in the last half second\n", low, high);
    // It hangs where it was glued (within a millimetre over the last half second), and
    // the sheet carries its 2 g at paper-like strain (its weight is 0.02 N against
    // 5000 N/m edges).
    EXPECT_GT(low, 0.944);
    EXPECT_LT(high, 0.946);
    EXPECT_LT(testing::maxEdgeStrain(paper.core().viewPaper(id)), 0.01);
    EXPECT_EQ(paper.lastError(), "");
}

}  // namespace
}  // namespace tearables
