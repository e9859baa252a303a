// A free box thrown at a free rope in zero gravity never gains energy, at any speed or
// offset: the rope wraps the box, slides on it, touches itself and is dragged along, and
// the total kinetic energy only falls (an inelastic impact). What makes it hold: the
// box's faces are linearised where the solve starts (a convex energy), its rotation is set
// from the solve's total turn (rotations do not commute), and friction is part of the
// solve, not applied after it contact by contact (src/string/strain_limit.cpp).
#include "bullet_fixture.hpp"
#include "tearables/bullet_core.hpp"

#include <btBulletDynamicsCommon.h>
#include <gtest/gtest.h>

#include <algorithm>

namespace tearables {
namespace {

/// A 1 kg box (0.2 m cube) thrown at `speed` down onto a free rope of radius `radius`
/// lying 0.5 m below it, `offset` off the rope's middle, in zero gravity; 100 steps. The
/// momentum's drift is asserted where `self_contacts` is off or `check_momentum` is set.
void throwBoxAtRope(double speed, double offset, double radius, bool self_contacts = true, bool check_momentum = true) {
    {
        {
            testing::Physics phys(0.0);
            btRigidBody& box = phys.add(std::make_unique<btBoxShape>(btVector3(0.1f, 0.1f, 0.1f)), 1.0,
                                        btVector3(static_cast<btScalar>(offset), 0.5f, 0));
            box.setLinearVelocity(btVector3(0, static_cast<btScalar>(-speed), 0));
            box.setActivationState(DISABLE_DEACTIVATION);
            WorldSettings settings;
            settings.rigid_contacts = true;
            settings.string_collisions = self_contacts;
            BulletWorld ropes(*phys.world, settings);
            StringDesc d = StringDesc::straight({-0.5, 0, 0}, {0.5, 0, 0}, 40);
            d.material.variation = 0.0;
            d.radius = radius;
            d.bending = 0.0;
            d.tearable = false;
            const StringId id = ropes.addString(d);
            auto energy = [&] {
                double e = testing::kineticEnergy(box);
                const auto v = ropes.core().view(id);
                for (std::size_t i = 0; i < v.particleCount(); ++i) e += 0.5 * (*v.masses)[i] * (*v.velocities)[i].squaredNorm();
                return e;
            };
            auto momentum = [&] {
                Vec3 m = toCore(box.getLinearVelocity()) / box.getInvMass();
                const auto v = ropes.core().view(id);
                for (std::size_t i = 0; i < v.particleCount(); ++i) m += (*v.masses)[i] * (*v.velocities)[i];
                return m;
            };
            const Vec3 momentum_start = momentum();
            double drift = 0.0;
            const double start = energy();
            double worst = 0.0;
            bool touched = false;
            for (int step = 0; step < 100; ++step) {
                phys.step(1);
                worst = std::max(worst, energy() / start);
                touched = touched || !ropes.core().lastContacts().empty();
                drift = std::max(drift, (momentum() - momentum_start).norm() / momentum_start.norm());
            }
            EXPECT_TRUE(touched) << "speed " << speed << " m/s, offset " << offset << " m";
            EXPECT_LT(worst, 1.01) << "speed " << speed << " m/s, offset " << offset << " m";
            // Momentum: exchanged between box and rope (the island solve of box and rope,
            // the rope's contacts with itself included, conserves it to rounding), except
            // in the steps where that solve does not converge and the rope's contacts take
            // the joint solve that holds the box still (cluster_solve.cpp): up to 1.0% in
            // these cases (docs/island-plan.md).
            if (check_momentum) EXPECT_LT(drift, 0.015) << "speed " << speed << " m/s, offset " << offset << " m";
            // The impact took energy: the box drags the rope along.
            EXPECT_LT(testing::kineticEnergy(box), 0.99 * start) << "speed " << speed << " m/s, offset " << offset << " m";
        }
    }
}

TEST(RigidCollision, FreeBoxThrownAtAFreeRopeNeverGainsEnergy) {
    for (double speed : {2.0, 4.0, 8.0})
        for (double offset : {0.0, 0.03, 0.07, 0.11}) throwBoxAtRope(speed, offset, 0.005);  // rope 0.09 kg
}

// The same with a rope heavier than the box (radius 2 cm: 1.43 kg against 1 kg). The rope
// wraps the box and touches itself; in the steps where the island's solve with its contacts
// does not converge they take the joint solve that holds the box still, which withholds
// 3.4-6.2% of the momentum in these cases (measured), so the momentum is asserted with self
// contacts off: the island's exchange between box and heavy rope. Energy never rises either
// way.
TEST(RigidCollision, FreeBoxThrownAtAHeavierFreeRopeNeverGainsEnergy) {
    for (double speed : {4.0, 8.0})
        for (double offset : {0.0, 0.07}) {
            throwBoxAtRope(speed, offset, 0.02, true, false);
            throwBoxAtRope(speed, offset, 0.02, false, true);
        }
}

}  // namespace
}  // namespace tearables
