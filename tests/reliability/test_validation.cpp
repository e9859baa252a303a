// Issue 8, validation at every entry point of the C++ API: a table of bad values (NaN,
// +-infinity, negative, zero, out of range) for every StringDesc, Material and
// WorldSettings field and for every call that takes an argument. Each is refused with an
// InvalidInput whose field() names it, nothing is half-created, and a rope already in the
// world steps on unharmed (finite, its length right).
#include "tearables/world.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <limits>
#include <string>
#include <vector>

namespace {

using tearables::InvalidInput;
using tearables::RigidId;
using tearables::RigidState;
using tearables::StringDesc;
using tearables::StringId;
using tearables::Vec3;
using tearables::World;
using tearables::WorldSettings;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

/// The rope that must survive every refusal: 1 m, 10 segments, pinned at the top.
StringId addWitness(World& world) {
    StringDesc d = StringDesc::straight({0, 1, 0}, {0, 0, 0}, 10);
    d.name = "witness";
    const StringId id = world.addString(d);
    world.attachToPoint(id, 0, {0, 1, 0});
    return id;
}

/// Steps the world and checks the witness is finite and still 1 m long (inextensible
/// until it yields: its own weight stretches it by far less than 0.1%).
void expectWitnessUnharmed(World& world, StringId id, const std::string& label) {
    for (int i = 0; i < 20; ++i) world.step(0.01);
    const auto v = world.view(id);
    EXPECT_FALSE(v.frozen) << label;
    double length = 0.0;
    for (std::size_t p = 0; p < v.particleCount(); ++p) {
        EXPECT_TRUE((*v.positions)[p].allFinite()) << label;
        EXPECT_TRUE((*v.velocities)[p].allFinite()) << label;
        if (p > 0) length += ((*v.positions)[p] - (*v.positions)[p - 1]).norm();
    }
    EXPECT_NEAR(length, 1.0, 1e-3) << label;
    for (std::uint8_t b : *v.broken) EXPECT_EQ(b, 0) << label;
}

/// Runs `call`, which must throw InvalidInput naming `field`.
void expectRefused(const std::string& field, const std::function<void()>& call, const std::string& label) {
    try {
        call();
        ADD_FAILURE() << label << ": accepted (expected a refusal naming " << field << ")";
    } catch (const InvalidInput& e) {
        EXPECT_EQ(e.field(), field) << label << ": " << e.what();
        EXPECT_EQ(std::string(e.what()).rfind(field + ": ", 0), 0u) << label << ": " << e.what();
        EXPECT_FALSE(e.problem().empty()) << label;
    } catch (const std::exception& e) {
        ADD_FAILURE() << label << ": threw something other than InvalidInput: " << e.what();
    }
}

// ------------------------------------------------------------------------------------------
// StringDesc and Material
// ------------------------------------------------------------------------------------------

struct DescCase {
    std::string field;
    std::function<void(StringDesc&)> spoil;
    std::string label;
};

/// NaN, +inf, -inf, negative and zero for a field that must be a positive finite number.
void positive(std::vector<DescCase>& cases, const std::string& field, std::function<double&(StringDesc&)> ref) {
    for (double bad : {kNaN, kInf, -kInf, -1.0, 0.0})
        cases.push_back({field, [ref, bad](StringDesc& d) { ref(d) = bad; }, field + "=" + std::to_string(bad)});
}

/// NaN, infinities and values just outside [lo, hi].
void ranged(std::vector<DescCase>& cases, const std::string& field, double lo, double hi,
            std::function<double&(StringDesc&)> ref) {
    for (double bad : {kNaN, kInf, -kInf, lo - 1e-3 - std::abs(lo) * 0.5, hi + 1e-3 + std::abs(hi) * 0.5})
        cases.push_back({field, [ref, bad](StringDesc& d) { ref(d) = bad; }, field + "=" + std::to_string(bad)});
}

std::vector<DescCase> descCases() {
    std::vector<DescCase> c;
    c.push_back({"points", [](StringDesc& d) { d.points.clear(); }, "no points"});
    c.push_back({"points", [](StringDesc& d) { d.points.resize(1); }, "one point"});
    for (double bad : {kNaN, kInf, -kInf})
        for (int k = 0; k < 3; ++k)
            c.push_back({"points[3]", [bad, k](StringDesc& d) { d.points[3][k] = bad; },
                         "points[3][" + std::to_string(k) + "]=" + std::to_string(bad)});
    c.push_back({"points[4]", [](StringDesc& d) { d.points[4] = d.points[3]; }, "coincident points"});
    positive(c, "radius", [](StringDesc& d) -> double& { return d.radius; });
    positive(c, "density", [](StringDesc& d) -> double& { return d.density; });
    // Finite but so extreme that a segment's mass or stiffness is not a number the solver
    // can use (underflows to 0 or overflows to infinity).
    c.push_back({"radius", [](StringDesc& d) { d.radius = 1e-200; }, "radius underflows the area"});
    c.push_back({"radius", [](StringDesc& d) { d.radius = 1e200; }, "radius overflows the mass"});
    c.push_back({"density", [](StringDesc& d) { d.density = 1e-320; }, "density underflows the mass"});
    c.push_back({"material.tensile.young", [](StringDesc& d) { d.material.tensile.young = 1e-310; },
                 "young underflows the stiffness"});
    c.push_back({"particle_masses[11]", [](StringDesc& d) { d.particle_masses = {{11, 1.0}}; }, "mass index past end"});
    c.push_back({"particle_masses[-12]", [](StringDesc& d) { d.particle_masses = {{-12, 1.0}}; }, "mass index before start"});
    for (double bad : {kNaN, kInf, -1.0, 0.0})
        c.push_back({"particle_masses[2]", [bad](StringDesc& d) { d.particle_masses = {{2, bad}}; },
                     "particle mass " + std::to_string(bad)});
    c.push_back({"particle_masses[-11]", [](StringDesc& d) { d.particle_masses = {{0, 1.0}, {-11, 2.0}}; },
                 "a particle given two masses"});
    positive(c, "material.tensile.young", [](StringDesc& d) -> double& { return d.material.tensile.young; });
    positive(c, "material.tensile.yield", [](StringDesc& d) -> double& { return d.material.tensile.yield; });
    positive(c, "material.tensile.plastic_modulus", [](StringDesc& d) -> double& { return d.material.tensile.plastic_modulus; });
    positive(c, "material.tensile.rupture", [](StringDesc& d) -> double& { return d.material.tensile.rupture; });
    c.push_back({"material.tensile.rupture", [](StringDesc& d) { d.material.tensile.rupture = d.material.tensile.yield; },
                 "tensile rupture equal to yield"});
    positive(c, "material.torsion.modulus", [](StringDesc& d) -> double& { return d.material.torsion.modulus; });
    positive(c, "material.torsion.yield", [](StringDesc& d) -> double& { return d.material.torsion.yield; });
    positive(c, "material.torsion.plastic_modulus", [](StringDesc& d) -> double& { return d.material.torsion.plastic_modulus; });
    positive(c, "material.torsion.rupture", [](StringDesc& d) -> double& { return d.material.torsion.rupture; });
    c.push_back({"material.torsion.rupture", [](StringDesc& d) { d.material.torsion.rupture = 0.5 * d.material.torsion.yield; },
                 "torsion rupture below yield"});
    ranged(c, "material.variation", 0.0, 0.5, [](StringDesc& d) -> double& { return d.material.variation; });
    for (int bad : {-1, 0, 9, 1 << 30})
        c.push_back({"csm_half_width", [bad](StringDesc& d) { d.csm_half_width = bad; }, "csm_half_width=" + std::to_string(bad)});
    ranged(c, "bending", 0.0, 1.0, [](StringDesc& d) -> double& { return d.bending; });
    c.push_back({"twist_half_width", [](StringDesc& d) { d.twist_half_width.clear(); }, "no twist widths"});
    c.push_back({"twist_half_width", [](StringDesc& d) { d.twist_half_width = {2, 2}; }, "twist widths count"});
    for (int bad : {-1, 0, 9})
        c.push_back({"twist_half_width", [bad](StringDesc& d) { d.twist_half_width = {bad}; },
                     "twist_half_width=" + std::to_string(bad)});
    c.push_back({"twist_half_width[7]",
                 [](StringDesc& d) {
                     d.twist_half_width.assign(10, 2);
                     d.twist_half_width[7] = 0;
                 },
                 "one per-segment twist width"});
    c.push_back({"tension", [](StringDesc& d) { d.tension = static_cast<tearables::TensionEstimator>(7); },
                 "tension estimator out of the enum"});
    ranged(c, "damping", 0.0, 1e3, [](StringDesc& d) -> double& { return d.damping; });
    ranged(c, "axial_damping", 0.0, 1.0, [](StringDesc& d) -> double& { return d.axial_damping; });
    return c;
}

TEST(Validation, EveryBadStringDescFieldIsRefusedByNameAndTheWorldStepsOn) {
    const std::vector<DescCase> cases = descCases();
    ASSERT_GT(cases.size(), 100u);
    for (const DescCase& c : cases) {
        World world;
        const StringId witness = addWitness(world);
        StringDesc d = StringDesc::straight({0.5, 1, 0}, {0.5, 0, 0}, 10);
        c.spoil(d);
        expectRefused(c.field, [&] { world.addString(d); }, c.label);
        EXPECT_EQ(world.strings().size(), 1u) << c.label << ": half-created";
        EXPECT_FALSE(world.contains(StringId{1})) << c.label;
        expectWitnessUnharmed(world, witness, c.label);
    }
}

TEST(Validation, StraightRefusesBadSegmentCounts) {
    for (int bad : {0, -1, -1000})
        expectRefused("segments", [&] { StringDesc::straight({0, 0, 0}, {1, 0, 0}, bad); }, std::to_string(bad));
}

// ------------------------------------------------------------------------------------------
// WorldSettings: at construction and when changed through settings() before a step
// ------------------------------------------------------------------------------------------

struct SettingsCase {
    std::string field;
    std::function<void(WorldSettings&)> spoil;
    std::string label;
};

std::vector<SettingsCase> settingsCases() {
    std::vector<SettingsCase> c;
    for (double bad : {kNaN, kInf, -kInf})
        for (int k = 0; k < 3; ++k)
            c.push_back({"gravity", [bad, k](WorldSettings& s) { s.gravity[k] = bad; },
                         "gravity[" + std::to_string(k) + "]=" + std::to_string(bad)});
    for (int bad : {-1, 0, 65, 1 << 30}) {
        c.push_back({"strain_iterations", [bad](WorldSettings& s) { s.strain_iterations = bad; },
                     "strain_iterations=" + std::to_string(bad)});
        c.push_back({"coupling_iterations", [bad](WorldSettings& s) { s.coupling_iterations = bad; },
                     "coupling_iterations=" + std::to_string(bad)});
    }
    for (double bad : {kNaN, kInf, -kInf, -1e-6, 0.0, 0.02})
        c.push_back({"strain_tolerance", [bad](WorldSettings& s) { s.strain_tolerance = bad; },
                     "strain_tolerance=" + std::to_string(bad)});
    for (double bad : {kNaN, kInf, -kInf, -1.0, 0.0})
        c.push_back({"max_speed", [bad](WorldSettings& s) { s.max_speed = bad; }, "max_speed=" + std::to_string(bad)});
    return c;
}

TEST(Validation, EveryBadWorldSettingIsRefusedAtConstruction) {
    for (const SettingsCase& c : settingsCases()) {
        WorldSettings s;
        c.spoil(s);
        expectRefused(c.field, [&] { World world(s); }, c.label);
        expectRefused(c.field, [&] { tearables::validate(s); }, c.label);
    }
}

// settings() hands out a reference: a bad value written through it is refused by the next
// step, which then changes nothing; restoring the value lets the world step on.
TEST(Validation, BadSettingWrittenLaterIsRefusedByTheStep) {
    for (const SettingsCase& c : settingsCases()) {
        World world;
        const StringId witness = addWitness(world);
        world.step(0.01);
        const WorldSettings good = world.settings();
        const std::vector<Vec3> before = *world.view(witness).positions;
        c.spoil(world.settings());
        expectRefused(c.field, [&] { world.step(0.01); }, c.label);
        EXPECT_EQ(world.stepCount(), 1) << c.label;
        EXPECT_EQ(*world.view(witness).positions, before) << c.label;
        world.settings() = good;
        expectWitnessUnharmed(world, witness, c.label);
    }
}

// ------------------------------------------------------------------------------------------
// API calls
// ------------------------------------------------------------------------------------------

struct CallCase {
    std::string field;
    std::function<void(World&, StringId, RigidId)> call;
    std::string label;
};

std::vector<CallCase> callCases() {
    const StringId gone{2};        // removed before the call
    const StringId never{12345};   // never existed
    const RigidId no_body{777};
    std::vector<CallCase> c;
    auto add = [&](std::string field, std::string label, std::function<void(World&, StringId, RigidId)> f) {
        c.push_back({std::move(field), std::move(f), std::move(label)});
    };
    for (StringId bad : {gone, never, StringId{}}) {
        const std::string s = " on string " + std::to_string(bad.index);
        add("string", "attachToPoint" + s, [bad](World& w, StringId, RigidId) { w.attachToPoint(bad, 0, {0, 0, 0}); });
        add("string", "attachToRigid" + s, [bad](World& w, StringId, RigidId b) { w.attachToRigid(bad, 0, b, {0, 0, 0}); });
        add("string", "applyForce" + s, [bad](World& w, StringId, RigidId) { w.applyForce(bad, 0, {0, 1, 0}); });
        add("string", "movePin" + s, [bad](World& w, StringId, RigidId) { w.movePin(bad, 0, {0, 1, 0}); });
        add("string", "detach" + s, [bad](World& w, StringId, RigidId) { w.detach(bad, 0); });
        add("string", "turnEnd" + s, [bad](World& w, StringId, RigidId) { w.turnEnd(bad, 0, 0.1); });
        add("string", "removeString" + s, [bad](World& w, StringId, RigidId) { w.removeString(bad); });
        add("string", "view" + s, [bad](World& w, StringId, RigidId) { w.view(bad); });
        add("string", "desc" + s, [bad](World& w, StringId, RigidId) { w.desc(bad); });
        add("string", "isAttached" + s, [bad](World& w, StringId, RigidId) { w.isAttached(bad, 0); });
        add("string", "resolveParticle" + s, [bad](World& w, StringId, RigidId) { w.resolveParticle(bad, 0); });
    }
    for (int p : {11, -12, 1 << 30, -(1 << 30), std::numeric_limits<int>::min()}) {
        const std::string s = " particle " + std::to_string(p);
        add("particle", "attachToPoint" + s, [p](World& w, StringId id, RigidId) { w.attachToPoint(id, p, {0, 0, 0}); });
        add("particle", "attachToRigid" + s, [p](World& w, StringId id, RigidId b) { w.attachToRigid(id, p, b, {0, 0, 0}); });
        add("particle", "applyForce" + s, [p](World& w, StringId id, RigidId) { w.applyForce(id, p, {0, 1, 0}); });
        add("particle", "movePin" + s, [p](World& w, StringId id, RigidId) { w.movePin(id, p, {0, 1, 0}); });
        add("particle", "detach" + s, [p](World& w, StringId id, RigidId) { w.detach(id, p); });
        add("particle", "isAttached" + s, [p](World& w, StringId id, RigidId) { w.isAttached(id, p); });
    }
    for (double bad : {kNaN, kInf, -kInf}) {
        const std::string s = " " + std::to_string(bad);
        add("point", "attachToPoint" + s, [bad](World& w, StringId id, RigidId) { w.attachToPoint(id, 3, {0, bad, 0}); });
        add("local", "attachToRigid" + s, [bad](World& w, StringId id, RigidId b) { w.attachToRigid(id, 3, b, {bad, 0, 0}); });
        add("force", "applyForce" + s, [bad](World& w, StringId id, RigidId) { w.applyForce(id, -1, {0, 0, bad}); });
        add("point", "movePin" + s, [bad](World& w, StringId id, RigidId) { w.movePin(id, 0, {bad, 1, 0}); });
        add("angle", "turnEnd" + s, [bad](World& w, StringId id, RigidId) { w.turnEnd(id, 0, bad); });
        add("h", "step" + s, [bad](World& w, StringId, RigidId) { w.step(bad); });
    }
    for (double bad : {0.0, -0.01, -1e300, 1e-300, 1e-9, 10.0})
        add("h", "step " + std::to_string(bad), [bad](World& w, StringId, RigidId) { w.step(bad); });
    add("particle", "movePin on a free particle", [](World& w, StringId id, RigidId) { w.movePin(id, 5, {0, 1, 0}); });
    add("end", "turnEnd end 1", [](World& w, StringId id, RigidId) { w.turnEnd(id, 1, 0.1); });
    add("end", "turnEnd on a free end", [](World& w, StringId id, RigidId) { w.turnEnd(id, -1, 0.1); });
    add("end", "endTwist end 2", [](World& w, StringId id, RigidId) { w.endTwist(id, 2); });
    for (RigidId bad : {no_body, RigidId{}}) {
        const std::string s = " body " + std::to_string(bad.index);
        add("body", "attachToRigid" + s, [bad](World& w, StringId id, RigidId) { w.attachToRigid(id, 3, bad, {0, 0, 0}); });
        add("body", "rigid" + s, [bad](World& w, StringId, RigidId) { w.rigid(bad); });
        add("body", "removeRigid" + s, [bad](World& w, StringId, RigidId) { w.removeRigid(bad); });
    }
    for (double bad : {kNaN, kInf}) {
        const std::string s = " " + std::to_string(bad);
        add("body.position", "addRigid position" + s, [bad](World& w, StringId, RigidId) {
            RigidState r;
            r.position.x() = bad;
            w.addRigid(r);
        });
        add("body.orientation", "addRigid orientation" + s, [bad](World& w, StringId, RigidId) {
            RigidState r;
            r.orientation.w() = bad;
            w.addRigid(r);
        });
        add("body.linear_velocity", "addRigid velocity" + s, [bad](World& w, StringId, RigidId) {
            RigidState r;
            r.linear_velocity.y() = bad;
            w.addRigid(r);
        });
        add("body.angular_velocity", "addRigid spin" + s, [bad](World& w, StringId, RigidId) {
            RigidState r;
            r.angular_velocity.z() = bad;
            w.addRigid(r);
        });
        add("body.inverse_mass", "addRigid inverse mass" + s, [bad](World& w, StringId, RigidId) {
            RigidState r;
            r.inverse_mass = bad;
            w.addRigid(r);
        });
        add("body.inverse_inertia_local", "addRigid inertia" + s, [bad](World& w, StringId, RigidId) {
            RigidState r;
            r.inverse_inertia_local(1, 1) = bad;
            w.addRigid(r);
        });
    }
    add("body.inverse_mass", "addRigid negative inverse mass", [](World& w, StringId, RigidId) {
        RigidState r;
        r.inverse_mass = -1.0;
        w.addRigid(r);
    });
    add("body.orientation", "addRigid zero quaternion", [](World& w, StringId, RigidId) {
        RigidState r;
        r.orientation.coeffs().setZero();
        w.addRigid(r);
    });
    return c;
}

TEST(Validation, EveryBadCallIsRefusedByNameAndChangesNothing) {
    const std::vector<CallCase> cases = callCases();
    ASSERT_GT(cases.size(), 100u);
    for (const CallCase& c : cases) {
        World world;
        const StringId witness = addWitness(world);
        // The string the calls use, and one that is removed again (its id, 2, is stale;
        // slots are reused, so nothing may be created after it).
        const StringId target = world.addString(StringDesc::straight({0.5, 1, 0}, {0.5, 0, 0}, 10));
        world.removeString(world.addString(StringDesc::straight({2, 1, 0}, {2, 0, 0}, 3)));
        world.attachToPoint(target, 0, {0.5, 1, 0});
        RigidState state;
        state.position = {0.5, -0.2, 0};
        state.inverse_mass = 1.0;
        state.inverse_inertia_local = tearables::Mat3::Identity() * 10.0;
        const RigidId body = world.addRigid(state);
        world.step(0.01);
        const std::vector<Vec3> before = *world.view(target).positions;
        const std::size_t strings = world.strings().size();
        const std::int64_t steps = world.stepCount();

        expectRefused(c.field, [&] { c.call(world, target, body); }, c.label);

        EXPECT_EQ(world.strings().size(), strings) << c.label;
        EXPECT_EQ(world.stepCount(), steps) << c.label;
        EXPECT_EQ(*world.view(target).positions, before) << c.label;
        EXPECT_TRUE(world.isAttached(target, 0)) << c.label;
        EXPECT_FALSE(world.isAttached(target, 3)) << c.label;
        EXPECT_FALSE(world.isAttached(target, -1)) << c.label;
        EXPECT_TRUE(world.events().empty() || world.events().front().type != tearables::EventType::Release) << c.label;
        EXPECT_TRUE(world.rigid(body).position.allFinite()) << c.label;
        expectWitnessUnharmed(world, witness, c.label);
        for (const Vec3& p : *world.view(target).positions) EXPECT_TRUE(p.allFinite()) << c.label;
    }
}

}  // namespace
