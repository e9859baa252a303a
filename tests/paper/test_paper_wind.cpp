// Wind and forces on sheets: the face drag of addFaceDrag against its closed form, and a
// vertex force moving a sheet's centre of mass as Newton's second law says.
#include "paper_helpers.hpp"
#include "tearables/cloth.hpp"
#include "tearables/world.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace tearables {
namespace {

constexpr double kRho = 1.2, kCd = 1.2;  // the scene format's air and plate

PaperDesc freeSheet(int resolution) {
    PaperDesc d;
    d.name = "sheet";
    d.center = Vec3(0, 1, 0);
    d.size[0] = 0.2;
    d.size[1] = 0.3;
    d.resolution[0] = resolution;
    d.resolution[1] = resolution;
    d.breakable = false;
    d.solver = PaperSolver::ConjugateGradient;  // converged: the springs' pairwise forces cancel in the sum
    d.tolerance = 1e-12;
    return d;
}

Vec3 centreOfMass(const PaperView& v) {
    Vec3 sum = Vec3::Zero();
    double m = 0.0;
    for (std::size_t i = 0; i < v.vertexCount(); ++i) {
        sum += (*v.masses)[i] * (*v.positions)[i];
        m += (*v.masses)[i];
    }
    return sum / m;
}

Vec3 momentum(const PaperView& v) {
    Vec3 sum = Vec3::Zero();
    for (std::size_t i = 0; i < v.vertexCount(); ++i) sum += (*v.masses)[i] * (*v.velocities)[i];
    return sum;
}

/// A flat sheet at rest, wind along its normal: the total drag is 1/2 rho C_d A w^2 along
/// the wind, and, the drag being uniform, the sheet accelerates as a whole at F / m over
/// the first step (no spring is stretched by a uniform load: dv = h F / m exactly).
TEST(PaperWind, NormalWindAcceleratesFreeSheetAtPlateDrag) {
    WorldSettings settings;
    settings.gravity = Vec3::Zero();
    World world(settings);
    const PaperId id = world.addPaper(freeSheet(9));
    const PaperView v = world.viewPaper(id);
    const double w = 5.0;  // m/s, along +y, the sheet's normal
    std::vector<Vec3> force;
    addFaceDrag(*v.positions, *v.velocities, *v.triangles, Vec3(0, w, 0), kRho, kCd, force);
    Vec3 total = Vec3::Zero();
    for (const Vec3& f : force) total += f;
    const double area = 0.2 * 0.3;
    const double expected = 0.5 * kRho * kCd * area * w * w;  // 1.08 N
    EXPECT_NEAR(total.y(), expected, 1e-12 * expected);
    EXPECT_NEAR(total.x(), 0.0, 1e-12 * expected);
    EXPECT_NEAR(total.z(), 0.0, 1e-12 * expected);
    for (std::size_t i = 0; i < force.size(); ++i) world.applyPaperForce(id, static_cast<std::uint32_t>(i), force[i]);
    const double h = 1.0 / 600.0;
    world.step(h);
    const PaperView after = world.viewPaper(id);
    const double mass = testing::totalMass(after);
    const double accel = expected / mass;  // 225 m/s^2 on 4.8 g
    const Vec3 a = momentum(after) / (mass * h);
    EXPECT_NEAR(a.y(), accel, 1e-6 * accel);
    EXPECT_NEAR(a.x(), 0.0, 1e-6 * accel);
    EXPECT_NEAR(a.z(), 0.0, 1e-6 * accel);
}

/// Wind in the sheet's plane (edge-on) meets no face: w . n = 0 on every triangle.
TEST(PaperWind, EdgeOnWindExertsNothing) {
    World world;
    const PaperId id = world.addPaper(freeSheet(9));
    const PaperView v = world.viewPaper(id);
    std::vector<Vec3> force;
    addFaceDrag(*v.positions, *v.velocities, *v.triangles, Vec3(5.0, 0, 3.0), kRho, kCd, force);
    const double normal_drag = 0.5 * kRho * kCd * 0.06 * 34.0;  // the same speed along the normal
    for (const Vec3& f : force) EXPECT_LT(f.norm(), 1e-15 * normal_drag);
    // Tilted by 30 degrees out of the wind: the drag goes as sin^2.
    const double tilt = M_PI / 6.0;
    addFaceDrag(*v.positions, *v.velocities, *v.triangles, 5.0 * Vec3(std::cos(tilt), std::sin(tilt), 0), kRho, kCd, force);
    Vec3 total = Vec3::Zero();
    for (const Vec3& f : force) total += f;
    const double expected = 0.5 * kRho * kCd * 0.06 * 25.0 * std::sin(tilt) * std::sin(tilt);
    EXPECT_NEAR(total.y(), expected, 1e-12 * expected);
    EXPECT_NEAR(total.x(), 0.0, 1e-12 * expected);
}

/// The sheet moves with the wind: no drag once it moves at the wind's speed (w is relative).
TEST(PaperWind, DragIsOfTheRelativeWind) {
    World world;
    const PaperId id = world.addPaper(freeSheet(5));
    const PaperView v = world.viewPaper(id);
    const std::vector<Vec3> moving(v.vertexCount(), Vec3(0, 2.0, 0));
    std::vector<Vec3> force;
    addFaceDrag(*v.positions, moving, *v.triangles, Vec3(0, 2.0, 0), kRho, kCd, force);
    for (const Vec3& f : force) EXPECT_EQ(f, Vec3::Zero());
    // Against the motion: the drag opposes it.
    addFaceDrag(*v.positions, moving, *v.triangles, Vec3::Zero(), kRho, kCd, force);
    Vec3 total = Vec3::Zero();
    for (const Vec3& f : force) total += f;
    EXPECT_NEAR(total.y(), -0.5 * kRho * kCd * 0.06 * 4.0, 1e-15);
}

TEST(PaperWind, BadArgumentsNamed) {
    const std::vector<Vec3> x = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 0, 1)};
    const std::vector<std::array<std::uint32_t, 3>> tri = {{0, 2, 1}};
    std::vector<Vec3> f;
    auto refused = [&](const char* field, auto call) {
        try {
            call();
            ADD_FAILURE() << field << " accepted";
        } catch (const InvalidInput& e) {
            EXPECT_NE(std::string(e.what()).find(field), std::string::npos) << e.what();
        }
    };
    refused("wind", [&] { addFaceDrag(x, x, tri, Vec3(NAN, 0, 0), kRho, kCd, f); });
    refused("air_density", [&] { addFaceDrag(x, x, tri, Vec3::Zero(), -1.0, kCd, f); });
    refused("drag_coefficient", [&] { addFaceDrag(x, x, tri, Vec3::Zero(), kRho, INFINITY, f); });
    refused("velocities", [&] { addFaceDrag(x, {}, tri, Vec3::Zero(), kRho, kCd, f); });
    refused("triangles[0]", [&] { addFaceDrag(x, x, {{0, 1, 3}}, Vec3::Zero(), kRho, kCd, f); });
}

/// A force on one vertex of a falling sheet (no holds): its centre of mass follows
/// g + F / m exactly as backward Euler steps it, x_n = x_0 + h^2 a n (n + 1) / 2
/// (v_n = n h a), whatever the springs do inside (they are pairwise; the conjugate
/// gradient is converged to 1e-12, and the Jacobi sweeps' momentum error is removed by a
/// uniform velocity, implicit.cpp keepMomentum).
class PaperDriversSolver : public ::testing::TestWithParam<PaperSolver> {};

TEST_P(PaperDriversSolver, VertexForceMovesCentreOfMassAsFOverM) {
    World world;
    PaperDesc d = freeSheet(9);
    d.solver = GetParam();
    const PaperId id = world.addPaper(d);
    const Vec3 x0 = centreOfMass(world.viewPaper(id));
    const double mass = testing::totalMass(world.viewPaper(id));
    const Vec3 push(0.02, 0.01, -0.015);  // N, on a corner: the sheet also turns and bends
    const double h = 1.0 / 240.0;
    const int steps = 60;
    for (int s = 0; s < steps; ++s) {
        world.applyPaperForce(id, 0, push);
        world.step(h);
    }
    const Vec3 a = Vec3(0, -9.81, 0) + push / mass;
    const Vec3 expected = x0 + h * h * a * (steps * (steps + 1) / 2.0);
    const Vec3 got = centreOfMass(world.viewPaper(id));
    const double travel = (expected - x0).norm();
    EXPECT_LT((got - expected).norm(), 1e-6 * travel) << got.transpose() << " vs " << expected.transpose();
}
INSTANTIATE_TEST_SUITE_P(BothSolvers, PaperDriversSolver, ::testing::Values(PaperSolver::Paper, PaperSolver::ConjugateGradient, PaperSolver::Multigrid));

/// Cloth faces: every intact cell is two triangles with +y normals on a flat cloth.
TEST(ClothWind, FacesOfAFlatClothAndTheirDrag) {
    WorldSettings settings;
    World world(settings);
    ClothDesc d;
    d.resolution = {5, 4};
    d.size = {0.4, 0.3};
    const ClothId id = world.addCloth(d);
    const ClothView v = world.viewCloth(id);
    const auto faces = clothFaces(v);
    ASSERT_EQ(faces.size(), 2u * 4u * 3u);
    std::vector<Vec3> force;
    addFaceDrag(*v.positions, *v.velocities, faces, Vec3(0, 3.0, 0), kRho, kCd, force);
    Vec3 total = Vec3::Zero();
    for (const Vec3& f : force) total += f;
    const double expected = 0.5 * kRho * kCd * 0.4 * 0.3 * 9.0;
    EXPECT_NEAR(total.y(), expected, 1e-12 * expected);
}

}  // namespace
}  // namespace tearables
