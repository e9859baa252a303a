// Issue 8: scene fields the loader's main error table (tests/scene/test_scene_loader.cpp)
// does not cover: infinities (JSON has no NaN; 1e999 is how a scene writes infinity),
// negatives, zeros and out-of-range values of every remaining field, and numbers Bullet
// would store as single-precision infinities. Each names the field's JSON path.
#include "tearables/scene.hpp"

#include <gtest/gtest.h>

#include <string>

namespace tearables::scene {
namespace {

std::string rope(const std::string& fields) {
    return R"({"bodies": [{"name": "beam", "shape": {"box": [1, 0.1, 0.1]}, "mass": 0}],
               "strings": [{"name": "rope", "from": [0, 2, 0], "to": [0, 1, 0])" +
           fields + "}]}";
}
std::string body(const std::string& fields) { return R"({"bodies": [{"name": "b", "shape": {"sphere": 1})" + fields + "}]}"; }
std::string shape(const std::string& s) { return R"({"bodies": [{"name": "b", "shape": )" + s + "}]}"; }
std::string driver(const std::string& d) {
    return R"({"strings": [{"name": "rope", "from": [0, 2, 0], "to": [0, 1, 0]}], "drivers": [)" + d + "]}";
}

struct Case {
    const char* label;
    std::string scene;
    std::string field;
    std::string message;
};

std::ostream& operator<<(std::ostream& os, const Case& c) { return os << c.label; }

class SceneFieldErrors : public ::testing::TestWithParam<Case> {};

TEST_P(SceneFieldErrors, NamesTheJsonPath) {
    const Case& c = GetParam();
    try {
        parseScene(c.scene);
        FAIL() << "accepted; expected an error at " << c.field;
    } catch (const InvalidInput& e) {
        EXPECT_EQ(e.field(), c.field) << e.what();
        EXPECT_NE(e.problem().find(c.message), std::string::npos) << e.what();
    }
}

const Case kCases[] = {
    // top level
    {"DtInfinite", R"({"dt": 1e999})", "dt", "finite"},
    {"DtNegative", R"({"dt": -0.01})", "dt", "must be in (0, 0.1]"},
    {"GravityInfinite", R"({"gravity": [0, -1e999, 0]})", "gravity[1]", "finite"},
    {"GravityPastFloat", R"({"gravity": [0, -1e300, 0]})", "gravity[1]", "must be in [-1000000, 1000000]"},
    {"SeedFraction", R"({"seed": 1.5})", "seed", "whole number"},
    {"StepsString", R"({"steps": "10"})", "steps", "expected"},
    {"BodiesNotArray", R"({"bodies": {}})", "bodies", "expected an array"},
    {"StringsNotArray", R"({"strings": 3})", "strings", "expected an array"},
    {"DriversNotArray", R"({"drivers": "none"})", "drivers", "expected an array"},
    {"OutputEveryFraction", R"({"output": {"every": 1.5}})", "output.every", "whole number"},
    {"OutputEveryNegative", R"({"output": {"every": -2}})", "output.every", "must be in [1, 1000000000]"},
    // bodies
    {"BodyMassInfinite", body(R"(, "mass": 1e999)"), "bodies[0].mass", "finite"},
    {"BodyMassHuge", body(R"(, "mass": 1e30)"), "bodies[0].mass", "must be 0 (static) or in [1e-06, 1e+09] kg"},
    {"BodyPositionInfinite", body(R"(, "position": [1e999, 0, 0])"), "bodies[0].position[0]", "finite"},
    {"BodyPositionPastFloat", body(R"(, "position": [0, 1e39, 0])"), "bodies[0].position[1]", "must be in"},
    {"BodyVelocityPastFloat", body(R"(, "linear_velocity": [0, 0, -1e200])"), "bodies[0].linear_velocity", "its length must be at most 500 m/s"},
    {"BodySpinInfinite", body(R"(, "angular_velocity": [0, 1e999, 0])"), "bodies[0].angular_velocity[1]", "finite"},
    {"BodyOrientationInfinite", body(R"(, "orientation": [0, 0, 1e999, 1])"), "bodies[0].orientation[2]", "finite"},
    {"BodyFrictionNegative", body(R"(, "friction": -0.5)"), "bodies[0].friction", "must be in [0, 1000]"},
    {"BodyFrictionHuge", body(R"(, "friction": 1e9)"), "bodies[0].friction", "must be in [0, 1000]"},
    {"BodyRestitutionNegative", body(R"(, "restitution": -0.1)"), "bodies[0].restitution", "must be in [0, 1]"},
    {"BodyNameNotString", R"({"bodies": [{"name": 3, "shape": {"sphere": 1}}]})", "bodies[0].name", "expected a string"},
    {"SphereZero", shape(R"({"sphere": 0})"), "bodies[0].shape.sphere", "must be in [0.0001, 1000000]"},
    {"SphereInfinite", shape(R"({"sphere": 1e999})"), "bodies[0].shape.sphere", "finite"},
    {"SpherePastFloat", shape(R"({"sphere": 1e50})"), "bodies[0].shape.sphere", "must be in [0.0001, 1000000]"},
    {"BoxNegative", shape(R"({"box": [-1, 1, 1]})"), "bodies[0].shape.box[0]", "must be in [0.0001, 1000000]"},
    {"BoxPastFloat", shape(R"({"box": [1, 1, 1e40]})"), "bodies[0].shape.box[2]", "must be in [0.0001, 1000000]"},
    {"CapsuleZeroHeight", shape(R"({"capsule": [0.1, 0]})"), "bodies[0].shape.capsule[1]", "must be in [0.0001, 1000000]"},
    {"CapsuleNegativeRadius", shape(R"({"capsule": [-0.1, 1]})"), "bodies[0].shape.capsule[0]", "must be in [0.0001, 1000000]"},
    {"PlaneOffsetInfinite", shape(R"({"plane": [0, 1, 0, 1e999]})"), "bodies[0].shape.plane[3]", "finite"},
    {"PlaneNormalPastFloat", shape(R"({"plane": [0, 1e200, 0, 0]})"), "bodies[0].shape.plane[1]", "must be in"},
    // strings: geometry
    {"FromInfinite", R"({"strings": [{"name": "r", "from": [1e999, 0, 0], "to": [1, 0, 0]}]})", "strings[0].from[0]", "finite"},
    {"ToPastFloat", R"({"strings": [{"name": "r", "from": [0, 0, 0], "to": [1e40, 0, 0]}]})", "strings[0].to[0]", "must be in"},
    {"PointPastFloat", R"({"strings": [{"name": "r", "points": [[0, 0, 0], [0, -1e300, 0]]}]})", "strings[0].points[1][1]",
     "must be in"},
    {"SegmentsNegative", rope(R"(, "segments": -3)"), "strings[0].segments", "must be in [1, 1000000]"},
    {"SegmentsHuge", rope(R"(, "segments": 1e12)"), "strings[0].segments", "must be in [1, 1000000]"},
    {"SegmentsTooShort", R"({"strings": [{"name": "r", "from": [0, 0, 0], "to": [1e-6, 0, 0], "segments": 100000}]})",
     "strings[0].to", "too close to from"},
    // strings: scalars
    {"RadiusInfinite", rope(R"(, "radius": 1e999)"), "strings[0].radius", "finite"},
    {"RadiusHuge", rope(R"(, "radius": 100)"), "strings[0].radius", "must be in [1e-07, 10]"},
    {"RadiusTiny", rope(R"(, "radius": 1e-12)"), "strings[0].radius", "must be in [1e-07, 10]"},
    {"DensityNegative", rope(R"(, "density": -1150)"), "strings[0].density", "must be greater than 0"},
    {"DensityHuge", rope(R"(, "density": 1e12)"), "strings[0].density", "must be in [0.001, 100000]"},
    {"DensityInfinite", rope(R"(, "density": 1e999)"), "strings[0].density", "finite"},
    {"ParticleMassInfinite", rope(R"(, "particle_masses": {"0": 1e999})"), "strings[0].particle_masses[\"0\"]", "finite"},
    {"ParticleMassHuge", rope(R"(, "particle_masses": {"0": 1e20})"), "strings[0].particle_masses[\"0\"]",
     "must be in (0, 1e+12]"},
    {"ParticleMassNegative", rope(R"(, "particle_masses": {"3": -2})"), "strings[0].particle_masses[\"3\"]",
     "must be greater than 0"},
    {"ParticleMassesNotObject", rope(R"(, "particle_masses": [1, 2])"), "strings[0].particle_masses", "expected an object"},
    {"CsmHalfWidthZero", rope(R"(, "csm_half_width": 0)"), "strings[0].csm_half_width", "must be in [1, 8]"},
    {"CsmHalfWidthFraction", rope(R"(, "csm_half_width": 1.5)"), "strings[0].csm_half_width", "whole number"},
    {"TwistHalfWidthZero", rope(R"(, "twist_half_width": 0)"), "strings[0].twist_half_width", "must be in [1, 8]"},
    {"BendingNegative", rope(R"(, "bending": -0.1)"), "strings[0].bending", "must be in [0, 1]"},
    {"BendingTooLarge", rope(R"(, "bending": 1.5)"), "strings[0].bending", "must be in [0, 1]"},
    {"AxialDampingNegative", rope(R"(, "axial_damping": -1)"), "strings[0].axial_damping", "must be in [0, 1]"},
    {"AxialDampingTooLarge", rope(R"(, "axial_damping": 2)"), "strings[0].axial_damping", "must be in [0, 1]"},
    {"DampingInfinite", rope(R"(, "damping": 1e999)"), "strings[0].damping", "finite"},
    {"TensionNotString", rope(R"(, "tension": 1)"), "strings[0].tension", "expected a string"},
    // strings: material
    {"YoungZero", rope(R"(, "material": {"tensile": {"young": 0}})"), "strings[0].material.tensile.young",
     "must be greater than 0"},
    {"YoungInfinite", rope(R"(, "material": {"tensile": {"young": 1e999}})"), "strings[0].material.tensile.young", "finite"},
    {"YoungHuge", rope(R"(, "material": {"tensile": {"young": 1e20}})"), "strings[0].material.tensile.young",
     "must be in [0.001, 1e+13]"},
    {"TensileYieldZero", rope(R"(, "material": {"tensile": {"yield": 0}})"), "strings[0].material.tensile.yield",
     "must be greater than 0"},
    {"TensilePlasticNegative", rope(R"(, "material": {"tensile": {"plastic_modulus": -1}})"),
     "strings[0].material.tensile.plastic_modulus", "must be greater than 0"},
    {"TensileRuptureInfinite", rope(R"(, "material": {"tensile": {"rupture": 1e999}})"),
     "strings[0].material.tensile.rupture", "finite"},
    {"TorsionModulusZero", rope(R"(, "material": {"torsion": {"modulus": 0}})"), "strings[0].material.torsion.modulus",
     "must be greater than 0"},
    {"TorsionYieldNegative", rope(R"(, "material": {"torsion": {"yield": -0.05}})"), "strings[0].material.torsion.yield",
     "must be greater than 0"},
    {"TorsionPlasticZero", rope(R"(, "material": {"torsion": {"plastic_modulus": 0}})"),
     "strings[0].material.torsion.plastic_modulus", "must be greater than 0"},
    {"TorsionRuptureHuge", rope(R"(, "material": {"torsion": {"rupture": 1e9}})"), "strings[0].material.torsion.rupture",
     "must be in [1e-09, 1000]"},
    {"TorsionUnknownField", rope(R"(, "material": {"torsion": {"shear": 1}})"), "strings[0].material.torsion.shear",
     "unknown field"},
    {"VariationNegative", rope(R"(, "material": {"variation": -0.1})"), "strings[0].material.variation", "must be in [0, 0.5]"},
    {"PresetUnknown", rope(R"(, "material": {"preset": "kevlar"})"), "strings[0].material.preset", "unknown material preset"},
    {"PresetNotString", rope(R"(, "material": {"preset": 2})"), "strings[0].material.preset", "expected a string"},
    // attachments
    {"AttachmentWorldInfinite", rope(R"(, "attachments": [{"particle": 0, "world": [0, 1e999, 0]}])"),
     "strings[0].attachments[0].world[1]", "finite"},
    {"AttachmentWorldPastFloat", rope(R"(, "attachments": [{"particle": 0, "world": [0, 1e100, 0]}])"),
     "strings[0].attachments[0].world[1]", "must be in"},
    {"AttachmentLocalInfinite", rope(R"(, "attachments": [{"particle": 0, "body": "beam", "local": [1e999, 0, 0]}])"),
     "strings[0].attachments[0].local[0]", "finite"},
    {"AttachmentParticleFraction", rope(R"(, "attachments": [{"particle": 0.5, "world": [0, 0, 0]}])"),
     "strings[0].attachments[0].particle", "whole number"},
    {"AttachmentsNotArray", rope(R"(, "attachments": {"particle": 0})"), "strings[0].attachments", "expected an array"},
    // drivers
    {"ForceInfinite", driver(R"({"type": "force", "target": "rope", "value": [0, -1e999, 0]})"), "drivers[0].value[1]", "finite"},
    {"ForceUntilInfinite", driver(R"({"type": "force", "target": "rope", "value": [0, 1, 0], "until": 1e999})"),
     "drivers[0].until", "finite"},
    {"RampRateNegative", driver(R"({"type": "ramp", "target": "rope", "value": [0, 1, 0], "rate": -5})"), "drivers[0].rate",
     "must be in (0, 1e+09]"},
    {"RampRateInfinite", driver(R"({"type": "ramp", "target": "rope", "value": [0, 1, 0], "rate": 1e999})"),
     "drivers[0].rate", "finite"},
    {"TwistRateInfinite", driver(R"({"type": "twist", "target": "rope", "rate": 1e999})"), "drivers[0].rate", "finite"},
    {"TwistNeedsRate", driver(R"({"type": "twist", "target": "rope"})"), "drivers[0].rate", "missing required field"},
    {"TwistEndFraction", driver(R"({"type": "twist", "target": "rope", "end": 0.5, "rate": 1})"), "drivers[0].end",
     "whole number"},
    {"MoveVelocityInfinite", driver(R"({"type": "move", "target": "rope", "velocity": [1e999, 0, 0]})"),
     "drivers[0].velocity[0]", "finite"},
    {"MoveVelocityPastFloat", driver(R"({"type": "move", "target": "rope", "velocity": [1e100, 0, 0]})"),
     "drivers[0].velocity", "its length must be at most 500 m/s"},
    {"MoveNeedsVelocity", driver(R"({"type": "move", "target": "rope"})"), "drivers[0].velocity", "missing required field"},
    {"ReleaseNeedsTarget", driver(R"({"type": "release", "particle": 0})"), "drivers[0].target", "missing required field"},
    {"ReleaseAtInfinite", driver(R"({"type": "release", "target": "rope", "at": 1e999})"), "drivers[0].at", "finite"},
    {"WindNeedsValue", driver(R"({"type": "wind"})"), "drivers[0].value", "missing required field"},
    {"WindGustNegative", driver(R"({"type": "wind", "value": [1, 0, 0], "gust": -1})"), "drivers[0].gust", "must be in [0, 10]"},
    {"SpawnNeedsBody", driver(R"({"type": "spawn", "at": 1})"), "drivers[0].body", "missing required field"},
    {"SpawnAtNegative", driver(R"({"type": "spawn", "body": {"name": "c", "shape": {"sphere": 1}}, "at": -2})"),
     "drivers[0].at", "must be at least 0"},
    {"SpawnBodyPastFloat",
     driver(R"({"type": "spawn", "body": {"name": "c", "shape": {"sphere": 1}, "position": [0, 1e300, 0]}})"),
     "drivers[0].body.position[1]", "must be in"},
    {"DriverTargetNotString", driver(R"({"type": "force", "target": 7, "value": [0, 1, 0]})"), "drivers[0].target",
     "expected a string"},
};

INSTANTIATE_TEST_SUITE_P(Reliability, SceneFieldErrors, ::testing::ValuesIn(kCases),
                         [](const ::testing::TestParamInfo<Case>& p) { return std::string(p.param.label); });

// Every built-in scene still loads with the tightened ranges.
TEST(SceneFieldErrors, BuiltinScenesStillLoad) {
    for (const auto& [name, description] : builtinScenes()) {
        SCOPED_TRACE(name);
        EXPECT_NO_THROW(parseScene(*builtinSceneText(name)));
    }
}

}  // namespace
}  // namespace tearables::scene
