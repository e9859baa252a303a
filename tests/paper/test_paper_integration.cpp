// Paper Sec. III.A: stiff sheets stay stable at game time steps with the approximate
// implicit Euler (Jacobi iterations), where explicit Euler diverges.
#include "paper_helpers.hpp"
#include "tearables/world.hpp"

#include <gtest/gtest.h>

#include <cstdio>

namespace tearables {
namespace {

using testing::maxEdgeStrain;
using testing::maxSpeed;

/// Cloth-like edge stiffness, N/m (a cotton sheet at this resolution); paper is 100x.
constexpr double kClothStiffness = 50.0;
constexpr double kH = 1.0 / 60.0;

PaperDesc hangingSheet(PaperIntegrator integrator) {
    PaperDesc d;
    d.name = "sheet";
    d.center = Vec3(0, 1, 0);
    d.size[0] = 0.2;
    d.size[1] = 0.2;
    d.resolution[0] = 11;
    d.resolution[1] = 11;
    d.stiffness = 100.0 * kClothStiffness;
    d.breakable = false;
    d.integrator = integrator;
    // The edge z = -0.1 is held; the sheet starts horizontal and falls about it.
    for (int i = 0; i < d.resolution[0]; ++i) {
        PaperAttachment a;
        a.vertex = d.gridVertex(i, 0);
        d.attachments.push_back(a);
    }
    return d;
}

TEST(PaperIntegration, ImplicitSettlesStiffSheetWhereExplicitDiverges) {
    // Implicit: falls from horizontal, swings, settles hanging. At rest the edges carry
    // the sheet's weight: the strain must stay far below 1% (the weight of the whole
    // sheet is 0.03 N against 5000 N/m springs).
    {
        World world;
        const PaperId id = world.addPaper(hangingSheet(PaperIntegrator::Implicit));
        double peak = 0.0;
        for (int step = 0; step < 1200; ++step) {
            world.step(kH);
            const PaperView v = world.viewPaper(id);
            ASSERT_TRUE(testing::allFinite(v)) << "step " << step;
            peak = std::max(peak, maxEdgeStrain(v));
        }
        const PaperView v = world.viewPaper(id);
        const double strain = maxEdgeStrain(v);
        std::printf("implicit: strain at rest %.3g, peak %.3g, max speed %.3g m/s\n", strain, peak, maxSpeed(v));
        EXPECT_LT(strain, 0.01);
        EXPECT_LT(maxSpeed(v), 0.05);  // settled
        // It fell: the free edge hangs below the held one.
        const PaperDesc& d = world.paperDesc(id);
        const Vec3 free_edge = (*v.positions)[static_cast<std::size_t>(d.gridVertex(5, d.resolution[1] - 1))];
        EXPECT_LT(free_edge.y(), 1.0 - 0.15);
    }
    // Explicit Euler, same sheet, same step: diverges within a few steps (omega h is in
    // the hundreds): strain past 100%, or non-finite and frozen.
    {
        World world;
        const PaperId id = world.addPaper(hangingSheet(PaperIntegrator::Explicit));
        bool diverged = false;
        int step = 0;
        for (; step < 120 && !diverged; ++step) {
            world.step(kH);
            const PaperView v = world.viewPaper(id);
            diverged = v.frozen || !testing::allFinite(v) || maxEdgeStrain(v) > 1.0;
        }
        std::printf("explicit: diverged after %d steps\n", step);
        EXPECT_TRUE(diverged);
    }
}

}  // namespace
}  // namespace tearables
