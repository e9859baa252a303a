// Flicking (Strings Sec. 5.4, Fig. 9): a string pulled and released bounces back toward
// its anchor through the tension its stretch stores. Our strain limiter keeps the
// material's elasticity (compliance L / (E A)), so the stored stretch is real and the
// recoil comes out of the solve; the material's axial damping (Kelvin-Voigt retardation
// time) sets how much of it survives. An overdamped string is the "without flicking"
// case: released, it creeps back instead of snapping.
#include "tearables/presets.hpp"
#include "tearables/world.hpp"

#include <gtest/gtest.h>

namespace {

using tearables::StringDesc;
using tearables::Vec3;

/// Tip height 0.05 s after releasing a 10 N pull on a 0.5 m rubber cord hanging from a pin.
double tipRiseAfterRelease(double axial_damping, double* stretched_length) {
    tearables::World world;
    const tearables::MaterialPreset* rubber = tearables::findMaterialPreset("rubber_cord");
    StringDesc d = StringDesc::straight({0, 0, 0}, {0, -0.5, 0}, 25);
    d.material = rubber->material;
    d.material.variation = 0.0;
    d.radius = rubber->radius;
    d.density = rubber->density;
    d.axial_damping = axial_damping;
    const auto id = world.addString(d);
    world.attachToPoint(id, 0, {0, 0, 0});
    for (int i = 0; i < 400; ++i) {  // pull for 4 s
        world.applyForce(id, -1, {0, -10.0, 0});
        world.step(0.01);
    }
    const double before = world.view(id).positions->back().y();
    *stretched_length = -before;
    for (int i = 0; i < 5; ++i) world.step(0.01);
    return world.view(id).positions->back().y() - before;
}

}  // namespace

TEST(Flick, ReleasedCordSnapsBackMuchFasterThanAnOverdampedOne) {
    double stretched = 0.0, stretched_damped = 0.0;
    const double flick = tipRiseAfterRelease(0.01, &stretched);
    const double creep = tipRiseAfterRelease(1.0, &stretched_damped);
    // Both were stretched by the pull (E A = 31 N: 10 N is about 30%).
    EXPECT_GT(stretched, 0.6);
    EXPECT_GT(stretched_damped, 0.6);
    // The elastic cord recoils most of its stretch within 50 ms; the overdamped one creeps.
    EXPECT_GT(flick, 0.5 * (stretched - 0.5));
    EXPECT_GT(flick, 4.0 * creep);
}
