// Material presets: each is a valid string material, the names are unique and found, and
// physically ordered facts hold (rubber is soft and stretchy, spaghetti weak, steel stiff,
// breaking loads at the suggested radii in the ranges known for such strings).
#include "tearables/presets.hpp"
#include "tearables/string.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <set>
#include <stdexcept>
#include <string>

namespace {

using tearables::MaterialPreset;

const double kPi = 3.14159265358979323846;

const MaterialPreset& preset(const std::string& name) {
    const MaterialPreset* p = tearables::findMaterialPreset(name);
    if (!p) throw std::runtime_error("no preset " + name);
    return *p;
}

/// Strain at rupture of the bilinear tensile curve.
double ruptureStrain(const MaterialPreset& p) {
    const tearables::TensileCurve& t = p.material.tensile;
    return t.yield / t.young + (t.rupture - t.yield) / t.plastic_modulus;
}

/// Breaking load at the suggested radius, N.
double breakingLoad(const MaterialPreset& p) { return kPi * p.radius * p.radius * p.material.tensile.rupture; }

}  // namespace

TEST(MaterialPresets, EveryPresetIsAValidString) {
    ASSERT_GE(tearables::materialPresets().size(), 5u);
    for (const MaterialPreset& p : tearables::materialPresets()) {
        SCOPED_TRACE(p.name);
        tearables::StringDesc d = tearables::StringDesc::straight({0, 1, 0}, {0, 0, 0}, 10);
        d.material = p.material;
        d.radius = p.radius;
        d.density = p.density;
        EXPECT_NO_THROW(tearables::validate(d));
        EXPECT_EQ(p.material.variation, 1e-4);
        EXPECT_NE(std::string(p.description), "");
        // The plastic branch starts past the elastic one and breaks later.
        EXPECT_GT(ruptureStrain(p), p.material.tensile.yield / p.material.tensile.young);
        // Every preset holds at least 1 m of itself hanging (breaking length > 1 m).
        EXPECT_GT(p.material.tensile.rupture / (p.density * 9.81), 1.0);
    }
}

TEST(MaterialPresets, NamesAreUniqueAndFound) {
    std::set<std::string> names;
    for (const MaterialPreset& p : tearables::materialPresets()) {
        EXPECT_TRUE(names.insert(p.name).second) << "duplicate preset " << p.name;
        EXPECT_EQ(tearables::findMaterialPreset(p.name), &p);
    }
    for (const char* n : {"thread", "rubber_cord", "nylon_rope", "braided_rope", "spaghetti", "steel_wire", "fishing_line"})
        EXPECT_NE(tearables::findMaterialPreset(n), nullptr) << n;
    EXPECT_EQ(tearables::findMaterialPreset("kevlar"), nullptr);
    EXPECT_EQ(tearables::findMaterialPreset(""), nullptr);
    EXPECT_EQ(tearables::findMaterialPreset("Thread"), nullptr);  // exact match only
}

TEST(MaterialPresets, PhysicalOrdering) {
    const MaterialPreset& rubber = preset("rubber_cord");
    const MaterialPreset& thread = preset("thread");
    const MaterialPreset& nylon = preset("nylon_rope");
    const MaterialPreset& pasta = preset("spaghetti");
    const MaterialPreset& braid = preset("braided_rope");
    const MaterialPreset& line = preset("fishing_line");

    // Rubber is at least 100x softer than nylon (MPa against GPa).
    EXPECT_LE(100.0 * rubber.material.tensile.young, nylon.material.tensile.young);
    EXPECT_LE(100.0 * rubber.material.tensile.young, line.material.tensile.young);
    // Rubber stretches past 100 % before breaking; thread and nylon well under 50 %.
    EXPECT_GT(ruptureStrain(rubber), 1.0);
    EXPECT_LT(ruptureStrain(thread), 0.5);
    EXPECT_LT(ruptureStrain(nylon), 0.5);
    EXPECT_LT(ruptureStrain(line), 0.5);
    // Nylon rope stretches more than polyester rope before breaking (cordage data).
    EXPECT_GT(ruptureStrain(nylon), ruptureStrain(braid));

    for (const MaterialPreset& p : tearables::materialPresets()) {
        if (&p == &pasta) continue;
        EXPECT_LT(pasta.material.tensile.rupture, p.material.tensile.rupture) << "spaghetti is not the weakest: " << p.name;
    }
    if (const MaterialPreset* steel = tearables::findMaterialPreset("steel_wire")) {
        for (const MaterialPreset& p : tearables::materialPresets()) {
            if (&p == steel) continue;
            EXPECT_GT(steel->material.tensile.young, p.material.tensile.young) << "steel is not the stiffest: " << p.name;
            EXPECT_GT(steel->material.torsion.modulus, p.material.torsion.modulus) << p.name;
            EXPECT_LT(ruptureStrain(*steel), ruptureStrain(p)) << "steel is not the least ductile in tension: " << p.name;
        }
    }
}

TEST(MaterialPresets, BreakingLoadsAtSuggestedRadii) {
    const double threadLoad = breakingLoad(preset("thread"));
    EXPECT_GE(threadLoad, 5.0);
    EXPECT_LE(threadLoad, 50.0);
    EXPECT_GT(breakingLoad(preset("nylon_rope")), 1e3);
    EXPECT_GT(breakingLoad(preset("braided_rope")), 1e3);
    EXPECT_LT(breakingLoad(preset("spaghetti")), 2.0);
    EXPECT_GT(breakingLoad(preset("spaghetti")), 0.05);  // still holds its own weight and a little more
    const double rubberLoad = breakingLoad(preset("rubber_cord"));
    EXPECT_GT(rubberLoad, 50.0);
    EXPECT_LT(rubberLoad, 1e3);
    const double lineLoad = breakingLoad(preset("fishing_line"));  // 0.30 mm mono: ~3-8 kg test
    EXPECT_GT(lineLoad, 30.0);
    EXPECT_LT(lineLoad, 80.0);
    const double wireLoad = breakingLoad(preset("steel_wire"));  // 1 mm high-tensile wire: ~1.2-1.7 kN
    EXPECT_GT(wireLoad, 1e3);
    EXPECT_LT(wireLoad, 2e3);
}
