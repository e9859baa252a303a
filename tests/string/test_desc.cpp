// Every descriptor field refused with a message that names it; nothing half-created.
#include "tearables/world.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <limits>

namespace {

using tearables::StringDesc;

struct BadField {
    const char* field;
    std::function<void(StringDesc&)> spoil;
};

}  // namespace

TEST(StringDesc, EveryBadFieldIsRefusedByName) {
    const double nan = std::numeric_limits<double>::quiet_NaN();
    const double inf = std::numeric_limits<double>::infinity();
    const std::vector<BadField> cases = {
        {"points", [](StringDesc& d) { d.points.resize(1); }},
        {"points[2]", [&](StringDesc& d) { d.points[2].x() = nan; }},
        {"points[3]", [](StringDesc& d) { d.points[3] = d.points[2]; }},
        {"radius", [](StringDesc& d) { d.radius = -0.001; }},
        {"radius", [](StringDesc& d) { d.radius = 0.0; }},
        {"radius", [&](StringDesc& d) { d.radius = nan; }},
        {"density", [&](StringDesc& d) { d.density = inf; }},
        {"density", [](StringDesc& d) { d.density = -1.0; }},
        {"particle_masses[7]", [](StringDesc& d) { d.particle_masses = {{7, 1.0}}; }},
        {"particle_masses[-1]", [](StringDesc& d) { d.particle_masses = {{-1, 0.0}}; }},
        {"material.tensile.young", [](StringDesc& d) { d.material.tensile.young = 0.0; }},
        {"material.tensile.yield", [&](StringDesc& d) { d.material.tensile.yield = nan; }},
        {"material.tensile.plastic_modulus", [](StringDesc& d) { d.material.tensile.plastic_modulus = -3.0; }},
        {"material.tensile.rupture", [](StringDesc& d) { d.material.tensile.rupture = 1e7; }},
        {"material.torsion.modulus", [](StringDesc& d) { d.material.torsion.modulus = -1.0; }},
        {"material.torsion.rupture", [](StringDesc& d) { d.material.torsion.rupture = 0.01; }},
        {"material.variation", [](StringDesc& d) { d.material.variation = 0.9; }},
        {"csm_half_width", [](StringDesc& d) { d.csm_half_width = 0; }},
        {"twist_half_width", [](StringDesc& d) { d.twist_half_width = {1, 2}; }},
        {"twist_half_width", [](StringDesc& d) { d.twist_half_width = {9}; }},
        {"damping", [](StringDesc& d) { d.damping = -1.0; }},
        {"integrator", [](StringDesc& d) { d.integrator = static_cast<tearables::StringIntegrator>(7); }},
    };
    for (const BadField& c : cases) {
        tearables::World world;
        const auto before = world.addString(StringDesc::straight({0, 0, 0}, {1, 0, 0}, 5));
        StringDesc d = StringDesc::straight({0, 0, 0}, {0, -1, 0}, 5);
        c.spoil(d);
        try {
            world.addString(d);
            ADD_FAILURE() << "accepted a bad " << c.field;
        } catch (const tearables::InvalidInput& e) {
            EXPECT_EQ(e.field(), c.field) << e.what();
            EXPECT_NE(std::string(e.what()).find(c.field), std::string::npos);
        }
        EXPECT_EQ(world.strings().size(), 1u) << c.field;  // nothing half-created
        world.step(0.01);
        for (const auto& p : *world.view(before).positions) EXPECT_TRUE(p.allFinite());
    }
}

TEST(StringDesc, RuptureBelowYieldSaysSo) {
    StringDesc d = StringDesc::straight({0, 0, 0}, {1, 0, 0}, 3);
    d.material.tensile.rupture = d.material.tensile.yield * 0.5;
    try {
        tearables::validate(d);
        FAIL();
    } catch (const tearables::InvalidInput& e) {
        EXPECT_NE(std::string(e.what()).find("must be greater than yield"), std::string::npos) << e.what();
    }
}

TEST(StringDesc, StraightNeedsASegment) {
    EXPECT_THROW(StringDesc::straight({0, 0, 0}, {1, 0, 0}, 0), tearables::InvalidInput);
}
