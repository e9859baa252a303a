// Paper sheets solved to a tolerance (PaperSolver::ConjugateGradient): the answer is the
// model's, not the iteration count's.
//
// What the model is, flat: every spring (structural and bending) joins two vertices of
// the flat sheet, and a spring at its rest length has the stiffness k d d^T along itself
// only (implicit.cpp: the transverse term k max(0, 1 - l0/l) is zero at l = l0). All of
// them lie in the sheet's plane, so a flat sheet has no linear stiffness against a
// deflection w out of it: a bending spring of length L across a fold of curvature kappa
// shortens by kappa^2 L^3 / 24, an energy of order kappa^4 L^6, which vanishes as the mesh
// is refined (L ~ h). Under a small load the sheet is a membrane (a net), not a plate of
// some bending stiffness D, and the closed forms that fit are a membrane's.
//
// The membrane's stiffness, from the springs of the grid (desc.cpp, restMesh: diagonals in
// a checkerboard; a bending spring across each inner edge). Per cell of side h: one
// structural spring along x and one along z (length h, stiffness k), one diagonal (sqrt 2 h,
// k), and bending springs (b k) of length 2 h along x and along z (across the grid edges)
// and one anti-diagonal (sqrt 2 h, across the diagonal). A spring of length L along d under
// a uniform strain e stores 1/2 k_s (L d.e.d)^2; summed per area h^2 and with the two
// diagonal directions alike (the checkerboard), the energy per area is
//   1/2 [A (e_xx^2 + e_zz^2) + B (e_xx + e_zz)^2],  A = k (1 + 4 b),  B = k (1 + b) / 2,
// so a strip stretched along x carries N = E e_xx per unit width with E = A + B when it
// cannot narrow (plane strain) and E = A + B - B^2 / (A + B) when it narrows freely
// (plane stress). Neither depends on h.
#include "paper_helpers.hpp"
#include "paper/sheet.hpp"
#include "tearables/world.hpp"
#include "world/world_access.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

namespace tearables {
namespace {

constexpr double kH = 1.0 / 60.0;
constexpr double kSide = 0.2;  // m
constexpr int kSteps = 600;    // 10 s: with damping 0.05 s the sheet is at rest (checked)

enum class Held { Corners, TwoEdges };

PaperDesc heldSheet(int resolution, Held held, double tolerance) {
    PaperDesc d;
    d.name = "sheet";
    d.center = Vec3(0, 1, 0);
    d.size[0] = kSide;
    d.size[1] = kSide;
    d.resolution[0] = resolution;
    d.resolution[1] = resolution;
    d.breakable = false;
    d.damping = 0.05;  // settles within the run; the static sag does not depend on it
    d.solver = PaperSolver::ConjugateGradient;
    d.tolerance = tolerance;
    for (int k = 0; k < resolution; ++k)
        for (int i : {0, resolution - 1}) {
            if (held == Held::Corners && k != 0 && k != resolution - 1) continue;
            PaperAttachment a;
            a.vertex = static_cast<std::uint32_t>(d.gridVertex(i, k));
            d.attachments.push_back(a);
        }
    return d;
}

struct Sag {
    double depth = 0.0;          ///< m, centre below the held vertices
    double speed = 0.0;          ///< m/s, fastest vertex at the end
    double worst_residual = 0.0; ///< largest relative residual a solve stopped at
};

Sag settledSag(int resolution, Held held, double tolerance) {
    World world;
    const PaperId id = world.addPaper(heldSheet(resolution, held, tolerance));
    const detail::PaperSheet& sheet = (*detail::WorldAccess::parts(world).papers)[id.index];
    Sag out;
    for (int s = 0; s < kSteps; ++s) {
        world.step(kH);
        out.worst_residual = std::max(out.worst_residual, sheet.cg_residual);
    }
    const PaperView v = world.viewPaper(id);
    const int c = resolution / 2;
    out.depth = 1.0 - (*v.positions)[static_cast<std::size_t>(world.paperDesc(id).gridVertex(c, c))].y();
    out.speed = testing::maxSpeed(v);
    return out;
}

/// A sheet held along two opposite edges (x = 0 and x = a) hangs as a taut elastic cable of
/// span a per unit width: a parabola of sag s carries the load q (N/m^2) with the
/// horizontal tension N = q a^2 / (8 s), and its length exceeds the span by 8 s^2 / (3 a),
/// which the strain N / E over the span supplies: s^3 = 3 q a^4 / (64 E) (the flat elastic
/// cable: H. M. Irvine, Cable Structures, MIT Press 1981, ch. 1, for sag/span << 1; here
/// 1%, so the tension varies along the span by 0.1%). The held edges keep the sheet from
/// narrowing, its free sides let it: E lies between the plane-stress and plane-strain
/// moduli above, and so does the sag. The answer does not depend on the mesh: refined
/// twice, it changes by far less than 5%.
TEST(PaperConverge, SheetHeldAtTwoEdgesSagsAsAnElasticCableAtEveryResolution) {
    const PaperDesc d;
    const double k = d.stiffness, b = d.bending;
    const double A = k * (1.0 + 4.0 * b), B = 0.5 * k * (1.0 + b);
    const double plane_strain = A + B, plane_stress = A + B - B * B / (A + B);
    const double q = d.areal_density * 9.81, a = kSide;
    const double stiff = std::cbrt(3.0 * q * std::pow(a, 4) / (64.0 * plane_strain));
    const double soft = std::cbrt(3.0 * q * std::pow(a, 4) / (64.0 * plane_stress));
    const Sag coarse = settledSag(11, Held::TwoEdges, 1e-6);
    const Sag fine = settledSag(21, Held::TwoEdges, 1e-6);
    std::printf("sag (mm): cable %.4f..%.4f; 11 vertices %.4f, 21 vertices %.4f\n", 1e3 * stiff, 1e3 * soft, 1e3 * coarse.depth,
                1e3 * fine.depth);
    for (const Sag& s : {coarse, fine}) {
        EXPECT_LT(s.speed, 1e-6);  // at rest
        EXPECT_LE(s.worst_residual, 1e-6);
        EXPECT_GE(s.depth, stiff);
        EXPECT_LE(s.depth, soft);
    }
    EXPECT_LT(std::abs(fine.depth - coarse.depth), 0.05 * fine.depth);
}

/// A tolerance ten times tighter changes a loaded sheet's sag by less than 1%: the solve
/// has converged, and what is left is the model's. (Held at its four corners: the
/// tolerance, not the mesh, is what varies here: held at single vertices, its sag grows
/// with the mesh as the log of the spacing, the point supports' singularity; docs/paper-solver.md.)
TEST(PaperConverge, TighterToleranceDoesNotMoveTheSag) {
    const Sag base = settledSag(11, Held::Corners, 1e-6);
    const Sag tight = settledSag(11, Held::Corners, 1e-7);
    std::printf("sag (mm) at the corners' held sheet: tolerance 1e-6 %.5f, 1e-7 %.5f\n", 1e3 * base.depth, 1e3 * tight.depth);
    EXPECT_LT(base.speed, 1e-6);
    EXPECT_LE(base.worst_residual, 1e-6);
    EXPECT_LE(tight.worst_residual, 1e-7);
    EXPECT_GT(base.depth, 0.0);
    EXPECT_LT(std::abs(tight.depth - base.depth), 0.01 * base.depth);
}

}  // namespace
}  // namespace tearables
