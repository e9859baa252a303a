// The long rope of the tests and benchmarks that need one string long enough for a stage
// to split its own work over the pool (5001 particles, past kParallelItems) and to fold
// onto itself when it tears: 50 m of 1 cm segments (radius 4 mm, the default material)
// rising 5 m along its length, pinned at its start and at particle 1700, a 20 kg tip.
#pragma once

#include "tearables/world.hpp"

namespace tearables::testing {

inline StringId addLongRope(World& world) {
    auto desc = StringDesc::straight({0, 0, 0}, {50.0, 0.0, 5.0}, 5000);
    desc.radius = 0.004;
    desc.particle_masses = {{-1, 20.0}};
    const StringId id = world.addString(desc);
    world.attachToPoint(id, 0, {0, 0, 0});
    world.attachToPoint(id, 1700, (*world.view(id).positions)[1700]);
    return id;
}

}  // namespace tearables::testing
