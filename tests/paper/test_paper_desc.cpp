// Paper sheets: descriptors are checked field by field, nothing is created on refusal,
// and the rest mesh is what the descriptor says.
#include "paper/sheet.hpp"
#include "paper_helpers.hpp"
#include "tearables/world.hpp"

#include <gtest/gtest.h>

#include <functional>

namespace tearables {
namespace {

PaperDesc small() {
    PaperDesc d;
    d.size[0] = 0.1;
    d.size[1] = 0.1;
    d.resolution[0] = 4;
    d.resolution[1] = 3;
    return d;
}

/// Every bad value of every field is refused naming that field, and leaves no sheet.
TEST(PaperDesc, BadInputRefusedWithTheFieldNamed) {
    const double nan = std::nan(""), inf = INFINITY;
    struct Case {
        const char* field;
        std::function<void(PaperDesc&)> spoil;
    };
    const std::vector<Case> cases = {
        {"center", [&](PaperDesc& d) { d.center = Vec3(nan, 0, 0); }},
        {"corner", [&](PaperDesc& d) { d.corner = Vec3(0, nan, 0); }},
        {"corner", [&](PaperDesc& d) { d.corner = Vec3(0, 1, 0); d.center = Vec3(0, 1, 0); }},
        {"orientation", [&](PaperDesc& d) { d.orientation = Quat(0, 0, 0, 0); }},
        {"orientation", [&](PaperDesc& d) { d.orientation.w() = inf; }},
        {"size", [&](PaperDesc& d) { d.size[0] = 0.0; }},
        {"size", [&](PaperDesc& d) { d.size[1] = nan; }},
        {"resolution", [&](PaperDesc& d) { d.resolution[0] = 1; }},
        {"resolution", [&](PaperDesc& d) { d.resolution[1] = 5000; }},
        {"areal_density", [&](PaperDesc& d) { d.areal_density = 0.0; }},
        {"areal_density", [&](PaperDesc& d) { d.areal_density = nan; }},
        {"stiffness", [&](PaperDesc& d) { d.stiffness = -1.0; }},
        {"stiffness", [&](PaperDesc& d) { d.stiffness = inf; }},
        {"bending", [&](PaperDesc& d) { d.bending = 2.0; }},
        {"damping", [&](PaperDesc& d) { d.damping = -0.1; }},
        {"solver", [&](PaperDesc& d) { d.solver = static_cast<PaperSolver>(7); }},
        {"tolerance", [&](PaperDesc& d) { d.tolerance = 0.0; }},
        {"tolerance", [&](PaperDesc& d) { d.tolerance = nan; }},
        {"tolerance", [&](PaperDesc& d) { d.tolerance = 0.5; }},
        {"jacobi_iterations", [&](PaperDesc& d) { d.jacobi_iterations = 0; }},
        {"jacobi_iterations", [&](PaperDesc& d) { d.jacobi_iterations = 1000; }},
        {"phi", [&](PaperDesc& d) { d.phi = 0.0; }},
        {"phi", [&](PaperDesc& d) { d.phi = nan; }},
        {"psi", [&](PaperDesc& d) { d.psi = -0.5; }},
        {"psi", [&](PaperDesc& d) { d.psi = inf; }},
        {"hinge_threshold", [&](PaperDesc& d) { d.hinge_threshold = 1.0; }},
        {"hinge_threshold", [&](PaperDesc& d) { d.hinge_threshold = -0.1; }},
        {"rupture_stretch", [&](PaperDesc& d) { d.rupture_stretch = 0.0; }},
        {"rupture_stretch", [&](PaperDesc& d) { d.rupture_stretch = nan; }},
        {"thickness", [&](PaperDesc& d) { d.thickness = 0.0; }},
        {"friction", [&](PaperDesc& d) { d.friction = -1.0; }},
        {"attachments[0].vertex", [&](PaperDesc& d) { d.attachments.push_back(PaperAttachment{12, {}, Vec3::Zero(), {}}); }},
        {"attachments[1].vertex", [&](PaperDesc& d) {
             d.attachments.push_back(PaperAttachment{3, {}, Vec3::Zero(), {}});
             d.attachments.push_back(PaperAttachment{3, {}, Vec3::Zero(), {}});
         }},
        {"attachments[0].world", [&](PaperDesc& d) { d.attachments.push_back(PaperAttachment{0, {}, Vec3::Zero(), Vec3(nan, 0, 0)}); }},
        {"attachments[0].body", [&](PaperDesc& d) { d.attachments.push_back(PaperAttachment{0, RigidId{7}, Vec3::Zero(), {}}); }},
        {"triangles", [&](PaperDesc& d) { d.triangles = {{0, 1, 2}}; }},
        {"triangles", [&](PaperDesc& d) { d.vertices = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 0, 1)}; }},
        {"triangles[0]", [&](PaperDesc& d) {
             d.vertices = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 0, 1)};
             d.triangles = {{0, 1, 3}};
         }},
        {"triangles[0]", [&](PaperDesc& d) {
             d.vertices = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(2, 0, 0)};  // collinear
             d.triangles = {{0, 1, 2}};
         }},
        {"triangles[1]", [&](PaperDesc& d) {
             d.vertices = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 0, 1), Vec3(1, 0, 1)};
             d.triangles = {{0, 2, 1}, {2, 1, 3}};  // the second is flipped
         }},
        {"vertices[3]", [&](PaperDesc& d) {
             d.vertices = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 0, 1), Vec3(5, 5, 5)};
             d.triangles = {{0, 2, 1}};
         }},
        {"vertices[1]", [&](PaperDesc& d) {
             d.vertices = {Vec3(0, 0, 0), Vec3(inf, 0, 0), Vec3(0, 0, 1)};
             d.triangles = {{0, 2, 1}};
         }},
    };
    for (const Case& c : cases) {
        World world;
        PaperDesc d = small();
        c.spoil(d);
        try {
            world.addPaper(d);
            ADD_FAILURE() << "accepted a bad " << c.field;
        } catch (const InvalidInput& e) {
            EXPECT_EQ(e.field(), c.field) << e.what();
        }
        EXPECT_TRUE(world.papers().empty()) << c.field;
        // The world goes on stepping, finite.
        world.step(0.01);
    }
}

TEST(PaperDesc, RectangleHasTheAreaMassAndSpringsItDescribes) {
    PaperDesc d = small();
    d.orientation = Quat(Eigen::AngleAxisd(0.7, Vec3(1, 2, 3).normalized()));
    d.center = Vec3(0.3, 2.0, -1.0);
    World world;
    const PaperId id = world.addPaper(d);
    const PaperView v = world.viewPaper(id);
    ASSERT_EQ(v.vertexCount(), 12u);
    EXPECT_EQ(v.triangles->size(), 2u * 3 * 2);
    EXPECT_NEAR(testing::totalMass(v), d.areal_density * d.size[0] * d.size[1], 1e-12);
    // Structural springs: one per edge (3x3 grid of cells: 3*3 + 4*2 + 6 diagonals).
    int structural = 0, bending = 0;
    for (const PaperSpring& sp : *v.springs) {
        structural += sp.kind == PaperSpringKind::Structural;
        bending += sp.kind == PaperSpringKind::Bending;
        EXPECT_NEAR(((*v.positions)[sp.a] - (*v.positions)[sp.b]).norm(), sp.rest, 1e-12);
    }
    EXPECT_EQ(structural, 3 * 3 + 4 * 2 + 6);
    const int inner_edges = structural - 2 * (3 + 2);
    EXPECT_EQ(bending, inner_edges);
    // Every triangle's normal is the sheet's (local +y turned by the orientation).
    const Vec3 up = d.orientation * Vec3::UnitY();
    for (const auto& t : *v.triangles) {
        const Vec3 n = ((*v.positions)[t[1]] - (*v.positions)[t[0]]).cross((*v.positions)[t[2]] - (*v.positions)[t[0]]).normalized();
        EXPECT_GT(n.dot(up), 0.999);
    }
    EXPECT_EQ(detail::checkMesh(detail::buildSheet(d)), "");
}

// A negative vertex index counts from the end, as a cloth's and the runtime calls': -1 is
// the last of the 12 vertices, -12 the first.
TEST(PaperDesc, AttachmentsCountNegativeIndicesFromTheEnd) {
    World world;
    PaperDesc d = small();
    d.attachments.push_back(PaperAttachment{-1, {}, Vec3::Zero(), Vec3(1, 2, 3)});
    d.attachments.push_back(PaperAttachment{-12, {}, Vec3::Zero(), {}});
    const PaperId id = world.addPaper(d);
    const Vec3 first = (*world.viewPaper(id).positions)[0];
    for (int i = 0; i < 10; ++i) world.step(0.01);
    EXPECT_NEAR(((*world.viewPaper(id).positions)[11] - Vec3(1, 2, 3)).norm(), 0.0, 1e-12);
    EXPECT_NEAR(((*world.viewPaper(id).positions)[0] - first).norm(), 0.0, 1e-12);
    d.attachments.push_back(PaperAttachment{11, {}, Vec3::Zero(), {}});  // -1 again
    try {
        world.addPaper(d);
        ADD_FAILURE() << "accepted";
    } catch (const InvalidInput& e) {
        EXPECT_EQ(e.field(), "attachments[2].vertex");
    }
    d.attachments.back().vertex = -13;
    EXPECT_THROW(world.addPaper(d), InvalidInput);
    EXPECT_EQ(world.papers().size(), 1u);
}

TEST(PaperDesc, AttachmentsHoldVerticesToPointsAndBodies) {
    World world;
    RigidState body;
    body.position = Vec3(0, 3, 0);
    const RigidId rb = world.addRigid(body);
    PaperDesc d = small();
    d.attachments.push_back(PaperAttachment{0, {}, Vec3::Zero(), Vec3(0, 1.5, 0)});
    d.attachments.push_back(PaperAttachment{3, rb, Vec3(0.1, 0, 0), {}});
    const PaperId id = world.addPaper(d);
    for (int i = 0; i < 30; ++i) world.step(0.01);
    const PaperView v = world.viewPaper(id);
    EXPECT_NEAR(((*v.positions)[0] - Vec3(0, 1.5, 0)).norm(), 0.0, 1e-12);
    EXPECT_NEAR(((*v.positions)[3] - Vec3(0.1, 3, 0)).norm(), 0.0, 1e-12);
    EXPECT_TRUE(world.rigidInUse(rb));
    world.removeRigid(rb);  // the glue goes with a Release event
    world.step(0.01);
    bool released = false;
    for (const Event& e : world.events()) released = released || (e.type == EventType::Release && e.particle == 3);
    EXPECT_TRUE(released);
    EXPECT_THROW(world.attachPaperToPoint(id, 99, Vec3::Zero()), InvalidInput);
    EXPECT_THROW(world.movePaperPin(id, 3, Vec3::Zero()), InvalidInput);  // 3 is free now
    world.movePaperPin(id, 0, Vec3(0, 1.4, 0));
    world.step(0.01);
    EXPECT_NEAR((*world.viewPaper(id).positions)[0].y(), 1.4, 1e-12);
    world.removePaper(id);
    EXPECT_FALSE(world.contains(id));
    EXPECT_THROW(world.viewPaper(id), InvalidInput);
}

// A sheet's vertex is numbered as a cloth's: a flat index, negative counting from the end
// (-1 the last vertex); out of range is refused naming "vertex", and nothing changes.
TEST(PaperDesc, NegativeVertexIndicesCountFromTheEnd) {
    World world;
    const PaperId id = world.addPaper(small());
    const int n = static_cast<int>(world.viewPaper(id).vertexCount());
    EXPECT_EQ(world.paperVertex(id, -1), static_cast<std::uint32_t>(n - 1));
    EXPECT_EQ(world.paperVertex(id, -n), 0u);
    world.attachPaperToPoint(id, -1, Vec3(0, 2, 0));
    world.step(0.01);
    EXPECT_EQ((*world.viewPaper(id).positions)[static_cast<std::size_t>(n - 1)], Vec3(0, 2, 0));
    for (const int bad : {n, -n - 1}) {
        try {
            world.attachPaperToPoint(id, bad, Vec3::Zero());
            ADD_FAILURE() << bad << " accepted";
        } catch (const InvalidInput& e) {
            EXPECT_EQ(e.field(), "vertex");
        }
    }
    world.movePaperPin(id, n - 1, Vec3(0, 2.5, 0));
    world.step(0.01);
    EXPECT_EQ((*world.viewPaper(id).positions)[static_cast<std::size_t>(n - 1)], Vec3(0, 2.5, 0));
}

}  // namespace
}  // namespace tearables

namespace tearables {
namespace {

/// Non-finite input is refused at every entry point; a sheet driven non-finite anyway (a
/// finite but absurd force) is frozen with a Freeze event and its neighbour goes on.
/// Either solver: the conjugate gradient's stop test is false on a non-finite residual,
/// and it must not hand back its finite start as if it had converged.
class PaperDescSolver : public ::testing::TestWithParam<PaperSolver> {};

TEST_P(PaperDescSolver, NonFiniteRefusedAndABlownUpSheetIsFrozen) {
    World world;
    PaperDesc d = PaperDesc{};
    d.solver = GetParam();
    d.resolution[0] = 4;
    d.resolution[1] = 4;
    const PaperId bad = world.addPaper(d);
    d.center = Vec3(1, 1, 0);
    const PaperId good = world.addPaper(d);
    EXPECT_THROW(world.applyPaperForce(bad, 0, Vec3(NAN, 0, 0)), InvalidInput);
    EXPECT_THROW(world.attachPaperToPoint(bad, 0, Vec3(INFINITY, 0, 0)), InvalidInput);
    EXPECT_THROW(world.attachPaperToRigid(bad, 0, RigidId{3}, Vec3::Zero()), InvalidInput);
    world.applyPaperForce(bad, 5, Vec3(1e308, 1e308, 0));
    world.step(1.0 / 60.0);
    bool frozen_event = false;
    for (const Event& e : world.events()) frozen_event = frozen_event || (e.type == EventType::Freeze && e.object == d.name);
    EXPECT_TRUE(frozen_event);
    EXPECT_TRUE(world.viewPaper(bad).frozen);
    for (int i = 0; i < 10; ++i) world.step(1.0 / 60.0);
    EXPECT_TRUE(testing::allFinite(world.viewPaper(bad)));
    EXPECT_TRUE(testing::allFinite(world.viewPaper(good)));
    EXPECT_FALSE(world.viewPaper(good).frozen);
    EXPECT_LT((*world.viewPaper(good).positions)[0].y(), 1.0);  // it falls on
}
INSTANTIATE_TEST_SUITE_P(BothSolvers, PaperDescSolver, ::testing::Values(PaperSolver::Paper, PaperSolver::ConjugateGradient, PaperSolver::Multigrid));

}  // namespace
}  // namespace tearables

namespace tearables {
namespace {

/// Any triangle mesh: a hexagonal fan (a vertex inside, six around), pinned at one rim
/// vertex, falls, swings and creases; its mass is the mesh's area times the density and
/// stays so, and the mesh stays valid.
TEST(PaperDesc, AnyTriangleMeshSimulates) {
    PaperDesc d;
    d.vertices.push_back(Vec3(0, 1, 0));
    for (int k = 0; k < 6; ++k) d.vertices.push_back(Vec3(0.05 * std::cos(k * M_PI / 3), 1, 0.05 * std::sin(k * M_PI / 3)));
    for (std::uint32_t k = 0; k < 6; ++k) d.triangles.push_back({0, 1 + (k + 1) % 6, 1 + k});  // normal +y
    d.phi = 0.3;  // fragile: it creases as it swings
    d.attachments.push_back(PaperAttachment{1, {}, Vec3::Zero(), {}});
    World world;
    const PaperId id = world.addPaper(d);
    const double area = 6.0 * 0.5 * 0.05 * 0.05 * std::sin(M_PI / 3);
    EXPECT_NEAR(testing::totalMass(world.viewPaper(id)), d.areal_density * area, 1e-12);
    for (int step = 0; step < 120; ++step) {
        world.step(1.0 / 60.0);
        ASSERT_EQ(detail::checkMesh(world.viewPaper(id), d.areal_density * area), "") << "step " << step;
    }
    const PaperView v = world.viewPaper(id);
    EXPECT_TRUE(testing::allFinite(v));
    EXPECT_LT((*v.positions)[4].y(), 0.95);  // the far rim vertex fell
    EXPECT_EQ(v.vertexCount(), 7u + v.counters.creases + v.counters.tears);
}

}  // namespace
}  // namespace tearables
