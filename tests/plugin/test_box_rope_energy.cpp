// A known bug, kept as a disabled test until it is fixed (issue 4): a free box thrown at
// a free rope in zero gravity must not gain energy, at any speed or offset. Today it does:
// max kinetic energy over 100 steps relative to the start, measured 2026-11-22,
//     offset (m):     0.00   0.03   0.07   0.11
//     2 m/s:          1.00   1.11   1.16  10.1
//     4 m/s:          1.01   1.35   1.22   1.54
//     8 m/s:          8.06   1.05   1.02   1.21
// Where (8 m/s, centred, step 14): the strain-limit Newton solve with the box's six
// unknowns (src/string/strain_limit.cpp, limitStrain) starts from the prediction, 8 cm
// into the box, with penalty energy about 4e6 J; its Gauss-Newton Hessian lacks the
// second-order terms of the box's rotation in the contact gaps (the planes turn with the
// box), so its steps are poor (line-search factors of 1/16 to 1/128), the passes end at
// the iteration limit with 1e5 J of penalty left, and that is released as velocity (the
// rope's kinetic energy goes from 3.4 J to 235 J in that stage). Starting the free
// particles from the start of the step instead (feasible) does not cure it.
// Run it: build/tests/tearables_tests --gtest_also_run_disabled_tests --gtest_filter='*BoxRopeEnergy*'
#include "bullet_fixture.hpp"
#include "tearables/bullet.hpp"

#include <btBulletDynamicsCommon.h>
#include <gtest/gtest.h>

#include <algorithm>

namespace tearables {
namespace {

TEST(KnownBug, DISABLED_BoxRopeEnergyNeverGrows) {
    for (double speed : {2.0, 4.0, 8.0})
        for (double offset : {0.0, 0.03, 0.07, 0.11}) {
            testing::Physics phys(0.0);
            btRigidBody& box = phys.add(std::make_unique<btBoxShape>(btVector3(0.1f, 0.1f, 0.1f)), 1.0,
                                        btVector3(static_cast<btScalar>(offset), 0.5f, 0));
            box.setLinearVelocity(btVector3(0, static_cast<btScalar>(-speed), 0));
            box.setActivationState(DISABLE_DEACTIVATION);
            WorldSettings settings;
            settings.rigid_contacts = true;
            BulletWorld ropes(*phys.world, settings);
            StringDesc d = StringDesc::straight({-0.5, 0, 0}, {0.5, 0, 0}, 40);
            d.material.variation = 0.0;
            d.radius = 0.005;
            d.bending = 0.0;
            d.tearable = false;
            const StringId id = ropes.addString(d);
            auto energy = [&] {
                double e = testing::kineticEnergy(box);
                const auto v = ropes.core().view(id);
                for (std::size_t i = 0; i < v.particleCount(); ++i) e += 0.5 * (*v.masses)[i] * (*v.velocities)[i].squaredNorm();
                return e;
            };
            const double start = energy();
            double worst = 0.0;
            for (int step = 0; step < 100; ++step) {
                phys.step(1);
                worst = std::max(worst, energy() / start);
            }
            EXPECT_LT(worst, 1.05) << "speed " << speed << " m/s, offset " << offset << " m";
        }
}

}  // namespace
}  // namespace tearables
