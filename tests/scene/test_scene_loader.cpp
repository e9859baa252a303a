// Tests of the headless scene loader: values, defaults, and the JSON path of every error.
#include "tearables/scene.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

namespace tearables::scene {
namespace {

// ---------------------------------------------------------------------------------------------
// Helpers
// ---------------------------------------------------------------------------------------------

/// A scene with one static beam and one string "rope" of 10 segments (11 particles) whose
/// remaining fields are `fields` (with a leading comma when not empty).
/// A scene with a dynamic box "b", a static box "post" and `joint` as its one joint.
std::string jointScene(const std::string& joint) {
    return R"({"bodies": [{"name": "b", "shape": {"box": [0.5, 0.1, 0.1]}, "mass": 1, "position": [0.5, 1, 0]},
                           {"name": "post", "shape": {"box": [0.1, 0.5, 0.1]}, "mass": 0, "position": [-0.1, 0.5, 0]}],
               "joints": [)" + joint + "]}";
}

std::string ropeScene(const std::string& fields) {
    return R"({"bodies": [{"name": "beam", "shape": {"box": [1, 0.1, 0.1]}, "mass": 0}],
               "strings": [{"name": "rope", "from": [0, 2, 0], "to": [0, 1, 0])" +
           fields + "}]}";
}

/// ropeScene with a single driver.
std::string driverScene(const std::string& driver) {
    return R"({"strings": [{"name": "rope", "from": [0, 2, 0], "to": [0, 1, 0]}], "drivers": [)" + driver + "]}";
}

/// A scene with the given bodies array content.
std::string bodiesScene(const std::string& bodies) { return R"({"bodies": [)" + bodies + "]}"; }

// ---------------------------------------------------------------------------------------------
// Valid scenes
// ---------------------------------------------------------------------------------------------

TEST(SceneLoader, FullSceneParsesEveryField) {
    const Scene s = parseScene(R"({
      "format": "tearables-scene/1",
      "description": "everything",
      "camera": {"eye": [0, 1, 3]},
      "dt": 0.005, "steps": 1200, "gravity": [0, -3.5, 0.5], "seed": 42,
      "bodies": [
        {"name": "beam", "shape": {"box": [1, 0.1, 0.2]}, "mass": 0, "kinematic": true,
         "position": [0, 3, 0], "orientation": [0, 0, 0, 2],
         "linear_velocity": [1, 0, 0], "angular_velocity": [0, 1, 0],
         "friction": 0.8, "restitution": 0.25},
        {"name": "ball", "shape": {"sphere": 0.3}, "mass": 2},
        {"name": "pill", "shape": {"capsule": [0.1, 0.4]}},
        {"name": "ground", "shape": {"plane": [0, 2, 0, 1]}}
      ],
      "strings": [
        {"name": "rope", "from": [0, 3, 0], "to": [0, 1, 0], "segments": 4,
         "radius": 0.004, "density": 1000, "particle_masses": {"-1": 0.5, "1": 0.01},
         "material": {"tensile": {"young": 1e9, "yield": 2e7, "plastic_modulus": 1e8, "rupture": 5e7},
                      "torsion": {"modulus": 2e9, "yield": 0.02, "plastic_modulus": 2e8, "rupture": 0.2},
                      "variation": 0.01},
         "csm_half_width": 3, "twist_half_width": [1, 2, 3, 4], "tension": "local", "integrator": "bdf2",
         "tearable": false, "yield_in_solve": true, "damping": 0.5,
         "attachments": [{"particle": 0, "body": "beam", "local": [0, -0.1, 0]},
                         {"particle": -1, "world": [0, 1, 0]}]},
        {"name": "thread", "points": [[0, 0, 0], [1, 0, 0], [1, 1, 0]], "twist_half_width": 5}
      ],
      "papers": [], "cloths": [],
      "drivers": [
        {"type": "force", "target": "rope", "particle": -1, "value": [0, -20, 0], "from": 0, "until": 2},
        {"type": "ramp", "target": "rope", "particle": 2, "value": [0, -3, 4], "rate": 5, "from": 1, "until": 3.5},
        {"type": "twist", "target": "thread", "end": 0, "rate": 6.28, "from": 0.5, "until": 3},
        {"type": "move", "target": "rope", "velocity": [0.1, 0, 0], "from": 0, "until": 1},
        {"type": "release", "target": "rope", "particle": 0, "at": 2.5},
        {"type": "wind", "value": [2, 0, 0], "gust": 0.5, "from": 1},
        {"type": "spawn", "body": {"name": "crate", "shape": {"box": [0.2, 0.2, 0.2]}, "mass": 5,
                                   "position": [0, 4, 0]}, "at": 1.5}
      ],
      "output": {"every": 10}
    })");

    EXPECT_DOUBLE_EQ(s.dt, 0.005);
    EXPECT_EQ(s.steps, 1200);
    EXPECT_EQ(s.gravity, Vec3(0, -3.5, 0.5));
    EXPECT_EQ(s.seed, 42u);
    ASSERT_TRUE(s.camera.eye.has_value());
    EXPECT_EQ(*s.camera.eye, Vec3(0, 1, 3));
    EXPECT_FALSE(s.camera.target.has_value());
    EXPECT_EQ(s.camera.fov, 40.0);
    EXPECT_EQ(s.output_every, 10);
    EXPECT_TRUE(s.source.empty());

    ASSERT_EQ(s.bodies.size(), 4u);
    const Body& beam = s.bodies[0];
    EXPECT_EQ(beam.name, "beam");
    EXPECT_EQ(beam.shape.kind, Shape::Kind::Box);
    EXPECT_EQ(beam.shape.half_extents, Vec3(1, 0.1, 0.2));
    EXPECT_EQ(beam.mass, 0.0);
    EXPECT_TRUE(beam.kinematic);
    EXPECT_EQ(beam.position, Vec3(0, 3, 0));
    EXPECT_DOUBLE_EQ(beam.orientation.w(), 1.0);  // [0, 0, 0, 2] normalised
    EXPECT_DOUBLE_EQ(beam.orientation.vec().norm(), 0.0);
    EXPECT_EQ(beam.linear_velocity, Vec3(1, 0, 0));
    EXPECT_EQ(beam.angular_velocity, Vec3(0, 1, 0));
    EXPECT_DOUBLE_EQ(beam.friction, 0.8);
    EXPECT_DOUBLE_EQ(beam.restitution, 0.25);
    EXPECT_EQ(s.bodies[1].shape.kind, Shape::Kind::Sphere);
    EXPECT_DOUBLE_EQ(s.bodies[1].shape.radius, 0.3);
    EXPECT_DOUBLE_EQ(s.bodies[1].mass, 2.0);
    EXPECT_EQ(s.bodies[2].shape.kind, Shape::Kind::Capsule);
    EXPECT_DOUBLE_EQ(s.bodies[2].shape.radius, 0.1);
    EXPECT_DOUBLE_EQ(s.bodies[2].shape.half_height, 0.4);
    const Body& ground = s.bodies[3];
    EXPECT_EQ(ground.shape.kind, Shape::Kind::Plane);
    EXPECT_EQ(ground.shape.plane_normal, Vec3(0, 1, 0));  // normalised
    EXPECT_DOUBLE_EQ(ground.shape.plane_offset, 0.5);    // 2y = 1 is y = 0.5
    EXPECT_EQ(ground.mass, 0.0);                          // planes default to static

    ASSERT_EQ(s.strings.size(), 2u);
    const StringDesc& rope = s.strings[0].desc;
    EXPECT_EQ(rope.name, "rope");
    ASSERT_EQ(rope.points.size(), 5u);
    EXPECT_TRUE(rope.points[0].isApprox(Vec3(0, 3, 0)));
    EXPECT_TRUE(rope.points[2].isApprox(Vec3(0, 2, 0)));
    EXPECT_TRUE(rope.points[4].isApprox(Vec3(0, 1, 0)));
    EXPECT_DOUBLE_EQ(rope.radius, 0.004);
    EXPECT_DOUBLE_EQ(rope.density, 1000.0);
    const std::vector<std::pair<int, double>> masses = {{-1, 0.5}, {1, 0.01}};
    EXPECT_EQ(rope.particle_masses, masses);  // key order: "-1" < "1"
    EXPECT_DOUBLE_EQ(rope.material.tensile.young, 1e9);
    EXPECT_DOUBLE_EQ(rope.material.tensile.yield, 2e7);
    EXPECT_DOUBLE_EQ(rope.material.tensile.plastic_modulus, 1e8);
    EXPECT_DOUBLE_EQ(rope.material.tensile.rupture, 5e7);
    EXPECT_DOUBLE_EQ(rope.material.torsion.modulus, 2e9);
    EXPECT_DOUBLE_EQ(rope.material.torsion.yield, 0.02);
    EXPECT_DOUBLE_EQ(rope.material.torsion.plastic_modulus, 2e8);
    EXPECT_DOUBLE_EQ(rope.material.torsion.rupture, 0.2);
    EXPECT_DOUBLE_EQ(rope.material.variation, 0.01);
    EXPECT_EQ(rope.csm_half_width, 3);
    EXPECT_EQ(rope.twist_half_width, (std::vector<int>{1, 2, 3, 4}));
    EXPECT_EQ(rope.tension, TensionEstimator::Local);
    EXPECT_EQ(rope.integrator, tearables::StringIntegrator::BDF2);
    EXPECT_FALSE(rope.tearable);
    EXPECT_TRUE(rope.yield_in_solve);
    EXPECT_DOUBLE_EQ(rope.damping, 0.5);
    EXPECT_EQ(rope.seed, 42u);  // scene seed + string index
    EXPECT_EQ(s.strings[1].desc.seed, 43u);

    const std::vector<Attachment>& at = s.strings[0].attachments;
    ASSERT_EQ(at.size(), 2u);
    EXPECT_EQ(at[0].particle, 0);
    EXPECT_EQ(at[0].body, std::optional<std::string>("beam"));
    EXPECT_EQ(at[0].local, std::optional<Vec3>(Vec3(0, -0.1, 0)));
    EXPECT_FALSE(at[0].world.has_value());
    EXPECT_EQ(at[1].particle, 4);  // -1 resolved
    EXPECT_FALSE(at[1].body.has_value());
    EXPECT_EQ(at[1].world, std::optional<Vec3>(Vec3(0, 1, 0)));

    const StringDesc& thread = s.strings[1].desc;
    ASSERT_EQ(thread.points.size(), 3u);
    EXPECT_EQ(thread.points[2], Vec3(1, 1, 0));
    EXPECT_EQ(thread.twist_half_width, std::vector<int>{5});
    EXPECT_EQ(thread.integrator, tearables::StringIntegrator::BackwardEuler);
    EXPECT_FALSE(thread.yield_in_solve);

    ASSERT_EQ(s.drivers.size(), 7u);
    const Driver& force = s.drivers[0];
    EXPECT_EQ(force.type, Driver::Type::Force);
    EXPECT_EQ(force.target, "rope");
    EXPECT_EQ(force.particle, 4);
    EXPECT_EQ(force.value, Vec3(0, -20, 0));
    EXPECT_DOUBLE_EQ(force.from, 0.0);
    EXPECT_DOUBLE_EQ(force.until, 2.0);
    const Driver& ramp = s.drivers[1];
    EXPECT_EQ(ramp.type, Driver::Type::Ramp);
    EXPECT_EQ(ramp.particle, 2);
    EXPECT_TRUE(ramp.value.isApprox(Vec3(0, -0.6, 0.8)));  // normalised
    EXPECT_DOUBLE_EQ(ramp.rate, 5.0);
    EXPECT_DOUBLE_EQ(ramp.from, 1.0);
    EXPECT_DOUBLE_EQ(ramp.until, 3.5);
    const Driver& twist = s.drivers[2];
    EXPECT_EQ(twist.type, Driver::Type::Twist);
    EXPECT_EQ(twist.target, "thread");
    EXPECT_EQ(twist.end, 0);
    EXPECT_DOUBLE_EQ(twist.rate, 6.28);
    EXPECT_DOUBLE_EQ(twist.from, 0.5);
    EXPECT_DOUBLE_EQ(twist.until, 3.0);
    const Driver& move = s.drivers[3];
    EXPECT_EQ(move.type, Driver::Type::Move);
    EXPECT_EQ(move.particle, 4);  // default: the last particle
    EXPECT_EQ(move.velocity, Vec3(0.1, 0, 0));
    const Driver& release = s.drivers[4];
    EXPECT_EQ(release.type, Driver::Type::Release);
    EXPECT_EQ(release.particle, 0);
    EXPECT_DOUBLE_EQ(release.at, 2.5);
    const Driver& wind = s.drivers[5];
    EXPECT_EQ(wind.type, Driver::Type::Wind);
    EXPECT_EQ(wind.value, Vec3(2, 0, 0));
    EXPECT_DOUBLE_EQ(wind.gust, 0.5);
    EXPECT_DOUBLE_EQ(wind.from, 1.0);
    EXPECT_DOUBLE_EQ(wind.until, 1e300);
    const Driver& spawn = s.drivers[6];
    EXPECT_EQ(spawn.type, Driver::Type::Spawn);
    ASSERT_TRUE(spawn.body.has_value());
    EXPECT_EQ(spawn.body->name, "crate");
    EXPECT_DOUBLE_EQ(spawn.body->mass, 5.0);
    EXPECT_EQ(spawn.body->position, Vec3(0, 4, 0));
    EXPECT_DOUBLE_EQ(spawn.at, 1.5);
}

// Every field of SCENE_FORMAT.md's papers example, and the extensions, arrive in the descriptor.
TEST(SceneLoader, PapersParseEveryField) {
    const Scene scene = parseScene(R"({
      "bodies": [{"name": "clip", "shape": {"box": [0.05, 0.05, 0.05]}, "mass": 1}],
      "papers": [
        { "name": "sheet", "center": [0, 1, 0], "size": [0.21, 0.297], "resolution": [22, 30],
          "orientation": [0, 0, 0, 1],
          "areal_density": 0.08,
          "stiffness": 5e3, "damping": 0.01, "jacobi_iterations": 8,
          "phi": 1.0, "psi": 0.5, "hinge_threshold": 0.5,
          "breakable": true, "tearable": false, "rupture_stretch": 0.02,
          "attachments": [ {"vertex": [0, 0], "world": true} ] },
        { "name": "card", "center": [1, 2, 3], "size": [0.1, 0.2], "resolution": [3, 4],
          "orientation": [0, 0.7071068, 0, 0.7071068], "areal_density": 0.3, "stiffness": 2e4, "bending": 0.2, "damping": 0.05,
          "solver": "conjugate_gradient", "tolerance": 1e-4, "jacobi_iterations": 12, "integrator": "explicit", "phi": 3, "psi": 1.5, "hinge_threshold": 0.25,
          "breakable": false, "tearable": true, "rupture_stretch": 0.05, "tension": "momentum", "thickness": 0.002, "friction": 0.8, "seed": 42,
          "attachments": [ {"vertex": [-1, -1], "world": [5, 6, 7]}, {"vertex": 1, "body": "clip", "local": [0.1, 0, 0]},
                           {"edge": "x-", "body": "clip"} ] },
        { "name": "mesh", "vertices": [[0, 0, 0], [1, 0, 0], [0, 0, 1]], "triangles": [[0, 2, 1]] }
      ],
      "drivers": [{"type": "velocity", "body": "clip", "value": [0, -1, 0], "from": 0.5, "until": 1},
                  {"type": "move", "target": "sheet", "vertex": [-1, 0], "velocity": [0.1, 0, 0]},
                  {"type": "force", "target": "card", "vertex": 5, "value": [0, 1, 0]}]
    })");
    ASSERT_EQ(scene.papers.size(), 3u);
    const PaperDesc& a = scene.papers[0].desc;
    EXPECT_EQ(a.name, "sheet");
    EXPECT_EQ(a.center, std::optional<Vec3>(Vec3(0, 1, 0)));
    EXPECT_FALSE(a.corner.has_value());
    EXPECT_DOUBLE_EQ(a.size[0], 0.21);
    EXPECT_DOUBLE_EQ(a.size[1], 0.297);
    EXPECT_EQ(a.resolution[0], 22);
    EXPECT_EQ(a.resolution[1], 30);
    EXPECT_DOUBLE_EQ(a.areal_density, 0.08);
    EXPECT_DOUBLE_EQ(a.stiffness, 5e3);
    EXPECT_DOUBLE_EQ(a.damping, 0.01);
    EXPECT_EQ(a.jacobi_iterations, 8);
    EXPECT_EQ(a.solver, PaperSolver::Paper);
    EXPECT_DOUBLE_EQ(a.tolerance, 1e-6);
    EXPECT_EQ(scene.papers[1].desc.solver, PaperSolver::ConjugateGradient);
    EXPECT_DOUBLE_EQ(scene.papers[1].desc.tolerance, 1e-4);
    EXPECT_DOUBLE_EQ(a.phi, 1.0);
    EXPECT_DOUBLE_EQ(a.psi, 0.5);
    EXPECT_DOUBLE_EQ(a.hinge_threshold, 0.5);
    EXPECT_TRUE(a.breakable);
    EXPECT_FALSE(a.tearable);
    EXPECT_DOUBLE_EQ(a.rupture_stretch, 0.02);
    ASSERT_EQ(a.attachments.size(), 1u);
    EXPECT_EQ(a.attachments[0].vertex, 0);
    EXPECT_FALSE(a.attachments[0].world.has_value());  // true: where the vertex is
    EXPECT_EQ(a.seed, scene.seed + 1000);
    const Paper& b = scene.papers[1];
    EXPECT_NEAR(b.desc.orientation.y(), std::sqrt(0.5), 1e-6);
    EXPECT_DOUBLE_EQ(b.desc.bending, 0.2);
    EXPECT_EQ(b.desc.integrator, PaperIntegrator::Explicit);
    EXPECT_DOUBLE_EQ(b.desc.phi, 3.0);
    EXPECT_DOUBLE_EQ(b.desc.psi, 1.5);
    EXPECT_DOUBLE_EQ(b.desc.hinge_threshold, 0.25);
    EXPECT_FALSE(b.desc.breakable);
    EXPECT_TRUE(b.desc.tearable);
    EXPECT_DOUBLE_EQ(b.desc.rupture_stretch, 0.05);
    EXPECT_EQ(b.desc.tension, PaperTension::Momentum);
    EXPECT_EQ(a.tension, PaperTension::Stretch);
    EXPECT_DOUBLE_EQ(b.desc.thickness, 0.002);
    EXPECT_DOUBLE_EQ(b.desc.friction, 0.8);
    EXPECT_EQ(b.desc.seed, 42u);
    ASSERT_EQ(b.desc.attachments.size(), 1u);
    EXPECT_EQ(b.desc.attachments[0].vertex, 11);  // [-1, -1] on a 3 x 4 grid
    EXPECT_EQ(*b.desc.attachments[0].world, Vec3(5, 6, 7));
    ASSERT_EQ(b.glue.size(), 1u + 4u);  // vertex 1 and the x- edge (4 vertices)
    EXPECT_EQ(b.glue[0].vertex, 1u);
    EXPECT_EQ(b.glue[0].body, "clip");
    EXPECT_EQ(*b.glue[0].local, Vec3(0.1, 0, 0));
    EXPECT_EQ(b.glue[1].vertex, 0u);
    EXPECT_EQ(b.glue[4].vertex, 9u);
    EXPECT_FALSE(b.glue[1].local.has_value());
    EXPECT_EQ(scene.papers[2].desc.vertices.size(), 3u);
    ASSERT_EQ(scene.drivers.size(), 3u);
    EXPECT_EQ(scene.drivers[0].type, Driver::Type::Velocity);
    EXPECT_EQ(scene.drivers[0].body_name, "clip");
    EXPECT_EQ(scene.drivers[0].paper_vertex, -1);
    EXPECT_EQ(scene.drivers[1].paper_vertex, 21);  // [-1, 0] on a 22-wide grid
    EXPECT_EQ(scene.drivers[2].paper_vertex, 5);
}

TEST(SceneLoader, AbsentFieldsTakeTheirDefaults) {
    const Scene s = parseScene(R"({"bodies": [{"name": "b", "shape": {"sphere": 1}}],
                                   "strings": [{"name": "r", "from": [0, 0, 0], "to": [1, 0, 0]}]})");
    const Scene defaults;
    EXPECT_EQ(s.dt, defaults.dt);
    EXPECT_EQ(s.steps, 500);
    EXPECT_EQ(s.gravity, Vec3(0, -9.81, 0));
    EXPECT_EQ(s.seed, 1u);
    EXPECT_EQ(s.output_every, 1);
    EXPECT_TRUE(s.drivers.empty());

    const Body& b = s.bodies.at(0);
    EXPECT_DOUBLE_EQ(b.mass, 1.0);
    EXPECT_FALSE(b.kinematic);
    EXPECT_EQ(b.position, Vec3::Zero());
    EXPECT_TRUE(b.orientation.isApprox(Quat::Identity()));
    EXPECT_EQ(b.linear_velocity, Vec3::Zero());
    EXPECT_EQ(b.angular_velocity, Vec3::Zero());
    EXPECT_DOUBLE_EQ(b.friction, 0.5);
    EXPECT_DOUBLE_EQ(b.restitution, 0.0);

    const StringDesc& d = s.strings.at(0).desc;
    const StringDesc desc_defaults;
    EXPECT_EQ(d.points.size(), 11u);  // 10 segments
    EXPECT_EQ(d.radius, desc_defaults.radius);
    EXPECT_EQ(d.density, desc_defaults.density);
    EXPECT_TRUE(d.particle_masses.empty());
    EXPECT_EQ(d.material.tensile.young, desc_defaults.material.tensile.young);
    EXPECT_EQ(d.material.tensile.rupture, desc_defaults.material.tensile.rupture);
    EXPECT_EQ(d.material.torsion.modulus, desc_defaults.material.torsion.modulus);
    EXPECT_EQ(d.material.variation, desc_defaults.material.variation);
    EXPECT_EQ(d.csm_half_width, 2);
    EXPECT_EQ(d.twist_half_width, std::vector<int>{2});
    EXPECT_EQ(d.tension, TensionEstimator::Momentum);
    EXPECT_TRUE(d.tearable);
    EXPECT_EQ(d.damping, 0.0);
    EXPECT_EQ(d.seed, 1u);
    EXPECT_TRUE(s.strings[0].attachments.empty());
}

TEST(SceneLoader, EmptyObjectIsAValidScene) {
    const Scene s = parseScene("{}");
    EXPECT_TRUE(s.bodies.empty());
    EXPECT_TRUE(s.strings.empty());
    EXPECT_EQ(s.steps, 500);
}

TEST(SceneLoader, CommentsAreAccepted) {
    const Scene s = parseScene(R"(// a scene
    {
      "dt": 0.02,   // the step
      /* block comments too */ "steps": 7
    })");
    EXPECT_DOUBLE_EQ(s.dt, 0.02);
    EXPECT_EQ(s.steps, 7);
}

TEST(SceneLoader, WholeNumbersWrittenAsDecimalsAreIntegers) {
    const Scene s = parseScene(ropeScene(R"(, "segments": 4.0, "csm_half_width": 3e0)"));
    EXPECT_EQ(s.strings[0].desc.points.size(), 5u);
    EXPECT_EQ(s.strings[0].desc.csm_half_width, 3);
}

TEST(SceneLoader, PartialMaterialKeepsOtherDefaults) {
    const Scene s = parseScene(ropeScene(R"(, "material": {"tensile": {"rupture": 9e7}})"));
    const Material& m = s.strings[0].desc.material;
    EXPECT_EQ(m.tensile.rupture, 9e7);
    EXPECT_EQ(m.tensile.yield, Material().tensile.yield);
    EXPECT_EQ(m.torsion.rupture, Material().torsion.rupture);
}

// ---------------------------------------------------------------------------------------------
// Errors: each names the exact JSON path of the offending field
// ---------------------------------------------------------------------------------------------

struct ErrorCase {
    const char* label;     ///< test name suffix
    std::string scene;     ///< JSON text
    std::string field;     ///< expected InvalidInput::field()
    std::string message;   ///< expected to occur in problem()
};

std::ostream& operator<<(std::ostream& os, const ErrorCase& c) { return os << c.label; }

class SceneErrors : public ::testing::TestWithParam<ErrorCase> {};

TEST_P(SceneErrors, NamesTheField) {
    const ErrorCase& c = GetParam();
    try {
        parseScene(c.scene);
        FAIL() << "no error; expected one at " << c.field;
    } catch (const InvalidInput& e) {
        EXPECT_EQ(e.field(), c.field) << e.what();
        EXPECT_NE(e.problem().find(c.message), std::string::npos) << "problem: " << e.problem();
        EXPECT_EQ(std::string(e.what()), c.field.empty() ? e.problem() : c.field + ": " + e.problem());
    }
}

const ErrorCase kErrorCases[] = {
    // --- JSON text and the top level
    {"SyntaxError", "{\"dt\": 0.01,\n \"steps\": }", "", "byte"},
    {"SyntaxErrorHasLine", "{\"dt\": 0.01,\n \"steps\": }", "", "line 2"},
    {"TrailingGarbage", "{} x", "", "invalid JSON"},
    {"NotAnObject", "[1, 2]", "", "a scene must be a JSON object, got an array"},
    {"NumberTooLarge", R"({"dt": 1e999})", "dt", "finite"},
    {"NumberTooLargeNested", ropeScene(R"(, "radius": -1e999)"), "strings[0].radius", "1e999"},
    {"NumberTooLargeInArray", R"({"strings": [{"name": "r", "points": [[0, 0, 0], [1, 1, 1e400]]}]})",
     "strings[0].points[1][2]", "finite"},
    {"DuplicateKey", R"({"dt": 0.01, "dt": 0.02})", "dt", "duplicate field"},
    {"UnknownTopLevelField", R"({"dtt": 0.01})", "dtt", "unknown field (allowed: format,"},
    {"UnknownOddField", R"({"a b": 1})", "[\"a b\"]", "unknown field"},
    {"BadFormat", R"({"format": "tearables-scene/2"})", "format", "unsupported format \"tearables-scene/2\""},
    {"FormatNotString", R"({"format": 1})", "format", "expected a string, got a number"},
    {"DescriptionNotString", R"({"description": 1})", "description", "expected a string"},
    {"CameraNotObject", R"({"camera": [1]})", "camera", "expected an object, got an array of 1 element"},
    {"CameraUnknownField", R"({"camera": {"eyes": [0, 1, 3]}})", "camera.eyes", "unknown field (allowed: eye, target, fov)"},
    {"CameraEyeShort", R"({"camera": {"eye": [0, 1]}})", "camera.eye", "expected an array of 3 numbers"},
    {"CameraTargetNotNumber", R"({"camera": {"target": [0, "1", 0]}})", "camera.target[1]", "expected a number"},
    {"CameraFovTooWide", R"({"camera": {"fov": 180}})", "camera.fov", "must be in (1, 170) (got 180)"},
    {"CameraEyeOnTarget", R"({"camera": {"eye": [0, 1, 0], "target": [0, 1, 0]}})", "camera.target", "must differ from eye"},
    {"DtTooLarge", R"({"dt": 0.5})", "dt", "must be in (0, 0.1] (got 0.5)"},
    {"DtZero", R"({"dt": 0})", "dt", "must be in (0, 0.1] (got 0)"},
    {"DtString", R"({"dt": "0.01"})", "dt", "expected a number, got a string"},
    {"StepsNegative", R"({"steps": -1})", "steps", "must be in [0, 1000000000] (got -1)"},
    {"StepsTooMany", R"({"steps": 2e9})", "steps", "must be in [0, 1000000000]"},
    {"StepsFraction", R"({"steps": 2.5})", "steps", "must be a whole number (got 2.5)"},
    {"SeedNegative", R"({"seed": -3})", "seed", "must be at least 0 (got -3)"},
    {"SeedTooLarge", R"({"seed": 18446744073709551615})", "seed", "must be at most 9223372036854775807"},
    {"GravityTooShort", R"({"gravity": [0, -9.81]})", "gravity", "expected an array of 3 numbers, got an array of 2 elements"},
    {"GravityElementType", R"({"gravity": [0, null, 0]})", "gravity[1]", "expected a number, got null"},
    {"OutputEveryZero", R"({"output": {"every": 0}})", "output.every", "must be in [1, 1000000000] (got 0)"},
    {"OutputUnknownField", R"({"output": {"evry": 2}})", "output.evry", "unknown field (allowed: every)"},
    // --- cloths
    {"ClothMissingName", R"({"cloths": [{}]})", "cloths[0].name", "missing required field"},
    {"ClothUnknownField", R"({"cloths": [{"name": "c", "colour": 1}]})", "cloths[0].colour", "unknown field"},
    {"ClothResolutionZero", R"({"cloths": [{"name": "c", "resolution": [0, 3]}]})", "cloths[0].resolution[0]", "must be in [1, 2000]"},
    {"ClothSizeNegative", R"({"cloths": [{"name": "c", "size": [0.5, -1]}]})", "cloths[0].size[1]", "must be in [0, 2000000]"},
    {"ClothYarnRadiusZero", R"({"cloths": [{"name": "c", "yarn_radius": 0}]})", "cloths[0].yarn_radius", "greater than 0"},
    {"ClothBothDensities", R"({"cloths": [{"name": "c", "density": 1000, "areal_density": 0.1}]})", "cloths[0].density", "not both"},
    {"ClothRuptureBelowYield", R"({"cloths": [{"name": "c", "material": {"tensile": {"rupture": 1e7}}}]})",
     "cloths[0].material.tensile.rupture", "must be greater than yield"},
    {"ClothLambdaOutOfRange", R"({"cloths": [{"name": "c", "lambda": 2}]})", "cloths[0].lambda", "in [0, 1]"},
    {"ClothOrientationZero", R"({"cloths": [{"name": "c", "orientation": [0, 0, 0, 0]}]})", "cloths[0].orientation", "of norm in [1e-06, 1000000] (got norm 0)"},
    {"ClothVertexOutOfRange", R"({"cloths": [{"name": "c", "resolution": [3, 3], "attachments": [{"vertex": [0, 5], "world": true}]}]})",
     "cloths[0].attachments[0].vertex[1]", "vertex index out of range"},
    {"ClothVertexTwice", R"({"cloths": [{"name": "c", "attachments": [{"vertex": [0, 0], "world": true}, {"vertex": [0, -21], "world": true}]}]})",
     "cloths[0].attachments[1].vertex", "already has an attachment"},
    {"ClothAttachUnknownBody", R"({"cloths": [{"name": "c", "attachments": [{"vertex": [0, 0], "body": "b"}]}]})",
     "cloths[0].attachments[0].body", "no body named \"b\""},
    {"ClothWorldFalse", R"({"cloths": [{"name": "c", "attachments": [{"vertex": [0, 0], "world": false}]}]})",
     "cloths[0].attachments[0].world", "false attaches nothing"},
    {"ClothNameTaken", R"({"strings": [{"name": "c", "from": [0, 1, 0], "to": [0, 0, 0]}], "cloths": [{"name": "c"}]})",
     "cloths[0].name", "duplicate"},
    {"ClothWeakYarnNotArray", R"({"cloths": [{"name": "c", "weak_yarns": {"vertex": [0, 0]}}]})", "cloths[0].weak_yarns",
     "expected an array"},
    {"ClothWeakYarnUnknownField", R"({"cloths": [{"name": "c", "weak_yarns": [{"vertex": [0, 0], "yarn": "warp", "strength": 0.5, "width": 1}]}]})",
     "cloths[0].weak_yarns[0].width", "unknown field (allowed: vertex, yarn, strength)"},
    {"ClothWeakYarnNoVertex", R"({"cloths": [{"name": "c", "weak_yarns": [{"yarn": "warp", "strength": 0.5}]}]})",
     "cloths[0].weak_yarns[0].vertex", "missing required field"},
    {"ClothWeakYarnVertexOutOfRange", R"({"cloths": [{"name": "c", "resolution": [3, 3], "weak_yarns": [{"vertex": [0, 3], "yarn": "warp", "strength": 0.5}]}]})",
     "cloths[0].weak_yarns[0].vertex[1]", "vertex index out of range"},
    {"ClothWeakYarnBadKind", R"({"cloths": [{"name": "c", "weak_yarns": [{"vertex": [0, 0], "yarn": "diagonal", "strength": 0.5}]}]})",
     "cloths[0].weak_yarns[0].yarn", "must be \"warp\" or \"weft\" (got \"diagonal\")"},
    {"ClothWeakYarnNoKind", R"({"cloths": [{"name": "c", "weak_yarns": [{"vertex": [0, 0], "strength": 0.5}]}]})",
     "cloths[0].weak_yarns[0].yarn", "missing required field"},
    {"ClothWeakWarpInLastColumn", R"({"cloths": [{"name": "c", "resolution": [3, 3], "weak_yarns": [{"vertex": [-1, 0], "yarn": "warp", "strength": 0.5}]}]})",
     "cloths[0].weak_yarns[0].vertex[0]", "no warp yarn starts in the last column"},
    {"ClothWeakWeftInLastRow", R"({"cloths": [{"name": "c", "resolution": [3, 3], "weak_yarns": [{"vertex": [0, 2], "yarn": "weft", "strength": 0.5}]}]})",
     "cloths[0].weak_yarns[0].vertex[1]", "no weft yarn starts in the last row"},
    {"ClothWeakYarnNoStrength", R"({"cloths": [{"name": "c", "weak_yarns": [{"vertex": [0, 0], "yarn": "warp"}]}]})",
     "cloths[0].weak_yarns[0].strength", "missing required field"},
    {"ClothWeakYarnStrengthZero", R"({"cloths": [{"name": "c", "weak_yarns": [{"vertex": [0, 0], "yarn": "warp", "strength": 0}]}]})",
     "cloths[0].weak_yarns[0].strength", "must be in (0, 1] (got 0)"},
    {"ClothWeakYarnStronger", R"({"cloths": [{"name": "c", "weak_yarns": [{"vertex": [0, 0], "yarn": "warp", "strength": 1.5}]}]})",
     "cloths[0].weak_yarns[0].strength", "must be in (0, 1] (got 1.5)"},
    {"ClothWeakYarnTwice", R"({"cloths": [{"name": "c", "resolution": [3, 3], "weak_yarns": [{"vertex": [1, 1], "yarn": "weft", "strength": 0.5}, {"vertex": [-2, -2], "yarn": "weft", "strength": 0.9}]}]})",
     "cloths[0].weak_yarns[1]", "weft yarn (1, 1) is already listed"},
    {"DriverClothParticle", R"({"cloths": [{"name": "c"}], "drivers": [{"type": "force", "target": "c", "particle": 0, "value": [0, 1, 0]}]})",
     "drivers[0].particle", "vertex: [i, j]"},
    {"DriverClothVertexMissing", R"({"cloths": [{"name": "c"}], "drivers": [{"type": "force", "target": "c", "value": [0, 1, 0]}]})",
     "drivers[0].vertex", "missing required field"},
    // --- the words of docs/SCENE_FORMAT.md, "Words": an old meaning is refused with what to write now
    {"PaperOrigin", R"({"papers": [{"name": "s", "origin": [0, 1, 0]}]})", "papers[0].origin",
     "a paper's origin was its centre; write \"center\": [0,1,0]"},
    {"ClothOrigin", R"({"cloths": [{"name": "c", "origin": [0, 1, 0]}]})", "cloths[0].origin",
     "a cloth's origin was its corner, vertex [0, 0]; write \"corner\": [0,1,0]"},
    {"PaperDensityIsAreal", R"({"papers": [{"name": "s", "density": 0.08}]})", "papers[0].density",
     "a sheet's mass per area is areal_density, kg/m^2: write \"areal_density\": 0.08"},
    {"PaperCenterAndCorner", R"({"papers": [{"name": "s", "center": [0, 1, 0], "corner": [0, 1, 0]}]})", "papers[0].corner",
     "give center or corner, not both"},
    {"ClothCenterAndCorner", R"({"cloths": [{"name": "c", "center": [0, 1, 0], "corner": [0, 1, 0]}]})", "cloths[0].corner",
     "give center or corner, not both"},
    {"PaperMeshWithCenter", R"({"papers": [{"name": "s", "center": [0, 1, 0], "vertices": [[0,0,0],[1,0,0],[0,0,1]], "triangles": [[0,2,1]]}]})",
     "papers[0].center", "belongs to a rectangle"},
    {"ClothCornerPastBound", R"({"cloths": [{"name": "c", "corner": [999999, 0, 0], "size": [1, 1]}]})", "cloths[0].size",
     "the largest coordinate of its corner plus the farthest a vertex lies from it"},
    {"ClothFlatVertexOutOfRange", R"({"cloths": [{"name": "c", "resolution": [3, 3], "attachments": [{"vertex": 9, "world": true}]}]})",
     "cloths[0].attachments[0].vertex", "vertex index out of range (got 9; the cloth has 9 vertices: 0..8, or -9..-1 from the end)"},
    {"ClothBadEdge", R"({"cloths": [{"name": "c", "attachments": [{"edge": "y+", "world": true}]}]})",
     "cloths[0].attachments[0].edge", "must be \"x-\""},
    {"ClothEdgeWithLocal", R"({"bodies": [{"name": "b", "shape": {"sphere": 1}}], "cloths": [{"name": "c", "attachments": [{"edge": "x-", "body": "b", "local": [0, 0, 0]}]}]})",
     "cloths[0].attachments[0].local", "an edge is glued where it is"},
    {"StringWorldFalse", R"({"strings": [{"name": "r", "from": [0, 1, 0], "to": [0, 0, 0], "attachments": [{"particle": 0, "world": false}]}]})",
     "strings[0].attachments[0].world", "false attaches nothing"},
    // --- papers
    {"PaperMissingName", R"({"papers": [{}]})", "papers[0].name", "missing required field"},
    {"PaperDuplicateName", R"({"papers": [{"name": "s"}, {"name": "s"}]})", "papers[1].name", "duplicate paper name"},
    {"PaperUnknownField", R"({"papers": [{"name": "s", "colour": 1}]})", "papers[0].colour", "unknown field"},
    {"PaperSizeZero", R"({"papers": [{"name": "s", "size": [0.2, 0]}]})", "papers[0].size[1]", "must be in (0, 2000000]"},
    {"PaperResolutionOne", R"({"papers": [{"name": "s", "resolution": [1, 4]}]})", "papers[0].resolution[0]", "in [2, 1024]"},
    {"PaperDensity", R"({"papers": [{"name": "s", "areal_density": -1}]})", "papers[0].areal_density", "in [1e-09, 1000000]"},
    {"PaperStiffness", R"({"papers": [{"name": "s", "stiffness": 0}]})", "papers[0].stiffness", "greater than 0"},
    {"PaperDamping", R"({"papers": [{"name": "s", "damping": 2}]})", "papers[0].damping", "in [0, 1]"},
    {"PaperSolver", R"({"papers": [{"name": "s", "solver": "amg"}]})", "papers[0].solver", "\"conjugate_gradient\", \"multigrid\" or \"paper\" (got \"amg\")"},
    {"PaperTolerance", R"({"papers": [{"name": "s", "tolerance": 0}]})", "papers[0].tolerance", "in [1e-12, 0.1]"},
    {"PaperJacobi", R"({"papers": [{"name": "s", "jacobi_iterations": 0}]})", "papers[0].jacobi_iterations", "in [1, 256]"},
    {"PaperPhi", R"({"papers": [{"name": "s", "phi": 0}]})", "papers[0].phi", "in (0, 1000]"},
    {"PaperPsi", R"({"papers": [{"name": "s", "psi": -1}]})", "papers[0].psi", "in [0, 4]"},
    {"PaperHinge", R"({"papers": [{"name": "s", "hinge_threshold": 1}]})", "papers[0].hinge_threshold", "in [0, 1)"},
    {"PaperBreakable", R"({"papers": [{"name": "s", "breakable": 1}]})", "papers[0].breakable", "expected a boolean"},
    {"PaperRupture", R"({"papers": [{"name": "s", "rupture_stretch": 0}]})", "papers[0].rupture_stretch", "in (0, 100]"},
    {"PaperIntegrator", R"({"papers": [{"name": "s", "integrator": "rk4"}]})", "papers[0].integrator", "\"implicit\" or \"explicit\""},
    {"PaperTension", R"({"papers": [{"name": "s", "tension": "local"}]})", "papers[0].tension", "\"stretch\" or \"momentum\""},
    {"PaperOrientationZero", R"({"papers": [{"name": "s", "orientation": [0, 0, 0, 0]}]})", "papers[0].orientation", "of norm in [1e-06, 1000000] (got norm 0)"},
    {"PaperMeshWithSize", R"({"papers": [{"name": "s", "size": [1, 1], "vertices": [[0,0,0],[1,0,0],[0,0,1]], "triangles": [[0,2,1]]}]})",
     "papers[0].size", "belongs to a rectangle"},
    {"PaperMeshBadIndex", R"({"papers": [{"name": "s", "vertices": [[0,0,0],[1,0,0],[0,0,1]], "triangles": [[0,2,3]]}]})",
     "papers[0].triangles[0][2]", "in [0, 2]"},
    {"PaperMeshDegenerate", R"({"papers": [{"name": "s", "vertices": [[0,0,0],[1,0,0],[2,0,0]], "triangles": [[0,2,1]]}]})",
     "papers[0].triangles[0]", "degenerate"},
    {"PaperAttachmentVertexRange", R"({"papers": [{"name": "s", "resolution": [3, 3], "attachments": [{"vertex": [3, 0], "world": true}]}]})",
     "papers[0].attachments[0].vertex[0]", "vertex index out of range (got 3; the sheet has 3 vertices along this axis)"},
    {"PaperAttachmentIndexRange", R"({"papers": [{"name": "s", "resolution": [3, 3], "attachments": [{"vertex": 9, "world": true}]}]})",
     "papers[0].attachments[0].vertex", "vertex index out of range (got 9; the sheet has 9 vertices: 0..8, or -9..-1 from the end)"},
    {"PaperAttachmentTwice", R"({"papers": [{"name": "s", "resolution": [3, 3], "attachments": [{"vertex": 0, "world": true}, {"vertex": [0, 0], "world": true}]}]})",
     "papers[0].attachments[1].vertex", "already has an attachment (papers[0].attachments[0])"},
    {"PaperAttachmentNoBody", R"({"papers": [{"name": "s", "attachments": [{"vertex": 0, "body": "nope"}]}]})",
     "papers[0].attachments[0].body", "no body named \"nope\""},
    {"PaperAttachmentNeither", R"({"papers": [{"name": "s", "attachments": [{"vertex": 0}]}]})",
     "papers[0].attachments[0]", "needs body"},
    {"PaperAttachmentWorldFalse", R"({"papers": [{"name": "s", "attachments": [{"vertex": 0, "world": false}]}]})",
     "papers[0].attachments[0].world", "false attaches nothing"},
    {"PaperAttachmentBadEdge", R"({"papers": [{"name": "s", "attachments": [{"edge": "y+", "world": true}]}]})",
     "papers[0].attachments[0].edge", "must be \"x-\""},
    {"PaperDriverParticle", R"({"papers": [{"name": "s"}], "drivers": [{"type": "force", "target": "s", "particle": 0, "vertex": 0, "value": [0, 1, 0]}]})",
     "drivers[0].particle", "a paper's vertex is given as \"vertex\""},
    {"PaperDriverNoVertex", R"({"papers": [{"name": "s"}], "drivers": [{"type": "move", "target": "s", "velocity": [0, 1, 0]}]})",
     "drivers[0].vertex", "missing required field"},
    {"StringDriverVertex", R"({"strings": [{"name": "r", "from": [0, 1, 0], "to": [0, 0, 0]}], "drivers": [{"type": "force", "target": "r", "vertex": 0, "value": [0, 1, 0]}]})",
     "drivers[0].vertex", "only for a cloth or paper target"},
    {"VelocityDriverNoBody", R"({"drivers": [{"type": "velocity", "body": "ball", "value": [0, 1, 0]}]})",
     "drivers[0].body", "no body named \"ball\""},
    {"PapersNotArray", R"({"papers": {}})", "papers", "expected an array, got an object"},
    // --- bodies
    {"BodyNegativeMass", bodiesScene(R"({"name": "b", "shape": {"sphere": 1}, "mass": -1})"), "bodies[0].mass",
     "must be at least 0 (got -1)"},
    {"BodyMissingName", bodiesScene(R"({"shape": {"sphere": 1}})"), "bodies[0].name", "missing required field"},
    {"BodyEmptyName", bodiesScene(R"({"name": "", "shape": {"sphere": 1}})"), "bodies[0].name", "must not be empty"},
    {"BodyMissingShape", bodiesScene(R"({"name": "b"})"), "bodies[0].shape", "missing required field"},
    {"DuplicateBodyName",
     bodiesScene(R"({"name": "b", "shape": {"sphere": 1}}, {"name": "b", "shape": {"sphere": 2}})"), "bodies[1].name",
     "duplicate body name \"b\" (also used by bodies[0])"},
    {"BodyUnknownField", bodiesScene(R"({"name": "b", "shape": {"sphere": 1}, "colour": "red"})"),
     "bodies[0].colour", "unknown field"},
    {"ShapeUnknownKind", bodiesScene(R"({"name": "b", "shape": {"cone": 1}})"), "bodies[0].shape.cone",
     "unknown field (allowed: box, sphere, capsule, plane)"},
    {"ShapeTwoKinds", bodiesScene(R"({"name": "b", "shape": {"sphere": 1, "box": [1, 1, 1]}})"), "bodies[0].shape",
     "needs exactly one of box, sphere, capsule, plane (got box, sphere)"},
    {"ShapeNoKind", bodiesScene(R"({"name": "b", "shape": {}})"), "bodies[0].shape", "(got none)"},
    {"BoxNonPositive", bodiesScene(R"({"name": "b", "shape": {"box": [1, 0, 1]}})"), "bodies[0].shape.box[1]",
     "must be in [0.0001, 1000000] (got 0)"},
    {"SphereNegative", bodiesScene(R"({"name": "b", "shape": {"sphere": -2}})"), "bodies[0].shape.sphere",
     "must be in [0.0001, 1000000] (got -2)"},
    {"CapsuleShort", bodiesScene(R"({"name": "b", "shape": {"capsule": [1]}})"), "bodies[0].shape.capsule",
     "expected an array of 2 numbers"},
    {"PlaneZeroNormal", bodiesScene(R"({"name": "g", "shape": {"plane": [0, 0, 0, 1]}})"), "bodies[0].shape.plane",
     "normal"},
    {"PlaneWithMass", bodiesScene(R"({"name": "g", "shape": {"plane": [0, 1, 0, 0]}, "mass": 3})"), "bodies[0].mass",
     "a plane must be static"},
    {"PlaneKinematic", bodiesScene(R"({"name": "g", "shape": {"plane": [0, 1, 0, 0]}, "kinematic": true})"),
     "bodies[0].kinematic", "cannot be kinematic"},
    {"ZeroQuaternion", bodiesScene(R"({"name": "b", "shape": {"sphere": 1}, "orientation": [0, 0, 0, 0]})"),
     "bodies[0].orientation", "of norm in [1e-06, 1000000] (got norm 0)"},
    {"RestitutionTooLarge", bodiesScene(R"({"name": "b", "shape": {"sphere": 1}, "restitution": 2})"),
     "bodies[0].restitution", "must be in [0, 1] (got 2)"},
    {"KinematicNotBool", bodiesScene(R"({"name": "b", "shape": {"sphere": 1}, "kinematic": 1})"),
     "bodies[0].kinematic", "expected a boolean"},
    // --- strings
    {"StringMissingName", R"({"strings": [{"from": [0, 0, 0], "to": [1, 0, 0]}]})", "strings[0].name",
     "missing required field"},
    {"DuplicateStringName",
     R"({"strings": [{"name": "r", "from": [0, 0, 0], "to": [1, 0, 0]}, {"name": "r", "from": [0, 0, 0], "to": [1, 0, 0]}]})",
     "strings[1].name", "duplicate string name \"r\""},
    {"UnknownStringField", ropeScene(R"(, "colour": "red")"), "strings[0].colour", "unknown field"},
    {"UnknownTensileField", ropeScene(R"(, "material": {"tensile": {"foo": 1}})"), "strings[0].material.tensile.foo",
     "unknown field (allowed: young, yield, plastic_modulus, rupture)"},
    {"UnknownMaterialField", ropeScene(R"(, "material": {"colour": 1})"), "strings[0].material.colour",
     "unknown field"},
    {"RadiusString", ropeScene(R"(, "radius": "thick")"), "strings[0].radius", "expected a number, got a string"},
    {"RadiusNegative", ropeScene(R"(, "radius": -1)"), "strings[0].radius", "must be greater than 0 (got -1)"},
    {"RadiusZero", ropeScene(R"(, "radius": 0)"), "strings[0].radius", "must be greater than 0 (got 0)"},
    {"DensityZero", ropeScene(R"(, "density": 0)"), "strings[0].density", "must be greater than 0"},
    {"ZeroLengthSegment",
     R"({"strings": [{"name": "r", "points": [[0, 0, 0], [1, 0, 0], [1, 0, 0], [2, 0, 0]]}]})",
     "strings[0].points[2]", "zero-length segment"},
    {"TooFewPoints", R"({"strings": [{"name": "r", "points": [[0, 0, 0]]}]})", "strings[0].points",
     "at least 2 points (got 1)"},
    {"PointNotVec3", R"({"strings": [{"name": "r", "points": [[0, 0, 0], [1, 0]]}]})", "strings[0].points[1]",
     "expected an array of 3 numbers"},
    {"FromEqualsTo", R"({"strings": [{"name": "r", "from": [0, 1, 0], "to": [0, 1, 0]}]})", "strings[0].to",
     "must differ from from"},
    {"MissingTo", R"({"strings": [{"name": "r", "from": [0, 1, 0]}]})", "strings[0].to", "missing required field"},
    {"NoGeometry", R"({"strings": [{"name": "r"}]})", "strings[0]", "needs its geometry"},
    {"PointsAndFrom", R"({"strings": [{"name": "r", "points": [[0, 0, 0], [1, 0, 0]], "from": [0, 0, 0]}]})",
     "strings[0].from", "not allowed together with points"},
    {"PointsAndSegments", R"({"strings": [{"name": "r", "points": [[0, 0, 0], [1, 0, 0]], "segments": 3}]})",
     "strings[0].segments", "not allowed together with points"},
    {"SegmentsFraction", ropeScene(R"(, "segments": 2.5)"), "strings[0].segments", "must be a whole number (got 2.5)"},
    {"SegmentsZero", ropeScene(R"(, "segments": 0)"), "strings[0].segments", "must be in [1, 1000000] (got 0)"},
    {"TensileRuptureBelowYield", ropeScene(R"(, "material": {"tensile": {"yield": 5e7, "rupture": 4e7}})"),
     "strings[0].material.tensile.rupture", "must be greater than yield"},
    {"TorsionRuptureBelowYield", ropeScene(R"(, "material": {"torsion": {"yield": 0.2, "rupture": 0.1}})"),
     "strings[0].material.torsion.rupture", "must be greater than yield"},
    {"YoungNegative", ropeScene(R"(, "material": {"tensile": {"young": -3e9}})"), "strings[0].material.tensile.young",
     "must be greater than 0"},
    {"VariationTooLarge", ropeScene(R"(, "material": {"variation": 0.9})"), "strings[0].material.variation",
     "must be in [0, 0.5] (got 0.9)"},
    {"CsmHalfWidthTooLarge", ropeScene(R"(, "csm_half_width": 9)"), "strings[0].csm_half_width", "must be in [1, 8]"},
    {"TwistHalfWidthWrongCount", ropeScene(R"(, "twist_half_width": [1, 2])"), "strings[0].twist_half_width",
     "one value per segment (10), got 2"},
    {"TwistHalfWidthElement", ropeScene(R"(, "twist_half_width": [1, 2, 3, 4, 5, 6, 7, 8, 9, 1])"),
     "strings[0].twist_half_width[8]", "must be in [1, 8] (got 9)"},
    {"TwistHalfWidthType", ropeScene(R"(, "twist_half_width": "2")"), "strings[0].twist_half_width",
     "expected an integer or an array of integers"},
    {"TensionUnknown", ropeScene(R"(, "tension": "global")"), "strings[0].tension",
     "must be \"momentum\" or \"local\" (got \"global\")"},
    {"IntegratorUnknown", ropeScene(R"(, "integrator": "rk4")"), "strings[0].integrator",
     "must be \"backward_euler\" or \"bdf2\" (got \"rk4\")"},
    {"TearableNotBool", ropeScene(R"(, "tearable": 1)"), "strings[0].tearable", "expected a boolean"},
    {"YieldInSolveNotBool", ropeScene(R"(, "yield_in_solve": "yes")"), "strings[0].yield_in_solve", "expected a boolean"},
    {"DampingNegative", ropeScene(R"(, "damping": -0.1)"), "strings[0].damping", "must be at least 0"},
    {"DampingTooLargeForValidate", ropeScene(R"(, "damping": 1e4)"), "strings[0].damping", "must be in [0, 1000]"},
    {"ParticleMassOutOfRange", ropeScene(R"(, "particle_masses": {"-12": 1})"), "strings[0].particle_masses[\"-12\"]",
     "particle index out of range"},
    {"ParticleMassOutOfRangeHigh", ropeScene(R"(, "particle_masses": {"11": 1})"),
     "strings[0].particle_masses[\"11\"]", "the string has 11 particles"},
    {"ParticleMassBadKey", ropeScene(R"(, "particle_masses": {"last": 1})"), "strings[0].particle_masses.last",
     "particle index such as"},
    {"ParticleMassNotPositive", ropeScene(R"(, "particle_masses": {"-1": 0})"), "strings[0].particle_masses[\"-1\"]",
     "must be greater than 0 (got 0)"},
    {"ParticleMassTwice", ropeScene(R"(, "particle_masses": {"0": 1, "-11": 2})"), "strings[0].particle_masses[\"0\"]",
     "already has a mass"},
    // --- attachments
    {"AttachmentUnknownBody",
     ropeScene(R"(, "attachments": [{"particle": 0, "body": "beam"}, {"particle": -1, "body": "beem"}])"),
     "strings[0].attachments[1].body", "no body named \"beem\" (bodies: beam)"},
    {"AttachmentParticleOutOfRange", ropeScene(R"(, "attachments": [{"particle": 11, "world": [0, 0, 0]}])"),
     "strings[0].attachments[0].particle", "particle index out of range"},
    {"AttachmentParticleMissing", ropeScene(R"(, "attachments": [{"world": [0, 0, 0]}])"),
     "strings[0].attachments[0].particle", "missing required field"},
    {"AttachmentTwiceOnAParticle",
     ropeScene(R"(, "attachments": [{"particle": 10, "world": [0, 0, 0]}, {"particle": -1, "body": "beam"}])"),
     "strings[0].attachments[1].particle", "particle 10 already has an attachment (strings[0].attachments[0])"},
    {"AttachmentBodyAndWorld", ropeScene(R"(, "attachments": [{"particle": 0, "body": "beam", "world": [0, 0, 0]}])"),
     "strings[0].attachments[0].world", "either body or world"},
    {"AttachmentNeither", ropeScene(R"(, "attachments": [{"particle": 0}])"), "strings[0].attachments[0]",
     "needs body"},
    {"AttachmentLocalWithWorld",
     ropeScene(R"(, "attachments": [{"particle": 0, "world": [0, 0, 0], "local": [0, 0, 0]}])"),
     "strings[0].attachments[0].local", "only allowed with body"},
    {"AttachmentUnknownField", ropeScene(R"(, "attachments": [{"particle": 0, "world": [0, 0, 0], "offset": 1}])"),
     "strings[0].attachments[0].offset", "unknown field"},
    // --- drivers
    {"DriverUnknownType", driverScene(R"({"type": "shake", "target": "rope"})"), "drivers[0].type",
     "unknown driver type \"shake\" (allowed: force, ramp, twist, move, release, wind, spawn, velocity, shoot)"},
    {"DriverMissingType", driverScene(R"({"target": "rope"})"), "drivers[0].type", "missing required field"},
    {"DriverUnknownTarget", driverScene(R"({"type": "force", "target": "rop", "value": [0, 1, 0]})"),
     "drivers[0].target", "no string, cloth or paper named \"rop\" (strings, cloths and papers: rope)"},
    {"DriverParticleOutOfRange", driverScene(R"({"type": "force", "target": "rope", "particle": -12, "value": [0, 1, 0]})"),
     "drivers[0].particle", "particle index out of range"},
    {"DriverParticleFraction", driverScene(R"({"type": "release", "target": "rope", "particle": 1.5})"),
     "drivers[0].particle", "whole number"},
    {"DriverFieldOfAnotherType", driverScene(R"({"type": "force", "target": "rope", "value": [0, 1, 0], "rate": 1, "until": 2})"),
     "drivers[0].rate", "unknown field (allowed: type, target, particle, vertex, value, from, until)"},
    {"RampUntilBeforeFrom", driverScene(R"({"type": "ramp", "target": "rope", "value": [0, 1, 0], "rate": 1, "from": 2, "until": 2})"),
     "drivers[0].until", "must be greater than from (got 2 <= 2)"},
    {"DriverUntilBeforeFrom", driverScene(R"({"type": "force", "target": "rope", "value": [0, 1, 0], "from": 2, "until": 1})"),
     "drivers[0].until", "must be greater than from"},
    {"DriverFromNegative", driverScene(R"({"type": "wind", "value": [1, 0, 0], "from": -1})"), "drivers[0].from",
     "must be at least 0"},
    {"DriverForceNeedsValue", driverScene(R"({"type": "force", "target": "rope"})"), "drivers[0].value",
     "missing required field"},
    {"RampZeroDirection", driverScene(R"({"type": "ramp", "target": "rope", "value": [0, 0, 0], "rate": 1})"),
     "drivers[0].value", "non-zero direction"},
    {"RampRateZero", driverScene(R"({"type": "ramp", "target": "rope", "value": [0, 1, 0], "rate": 0})"),
     "drivers[0].rate", "must be in (0, 1e+09] (got 0)"},
    {"TwistBadEnd", driverScene(R"({"type": "twist", "target": "rope", "end": 3, "rate": 1})"), "drivers[0].end",
     "must be 0 (the first end) or -1 (the last end)"},
    {"ReleaseAtNegative", driverScene(R"({"type": "release", "target": "rope", "at": -1})"), "drivers[0].at",
     "must be at least 0"},
    {"WindGustTooLarge", driverScene(R"({"type": "wind", "value": [1, 0, 0], "gust": 11})"), "drivers[0].gust",
     "must be in [0, 10]"},
    {"WindHasNoTarget", driverScene(R"({"type": "wind", "target": "rope", "value": [1, 0, 0]})"), "drivers[0].target",
     "unknown field"},
    {"SpawnBodyBadField", driverScene(R"({"type": "spawn", "body": {"name": "c", "shape": {"sphere": 1}, "size": 1}})"),
     "drivers[0].body.size", "unknown field"},
    {"SpawnBodyBadBox", driverScene(R"({"type": "spawn", "body": {"name": "c", "shape": {"box": [1, -1, 1]}}})"),
     "drivers[0].body.shape.box[1]", "must be in [0.0001, 1000000]"},
    {"SpawnDuplicatesBodyName",
     R"({"bodies": [{"name": "crate", "shape": {"sphere": 1}}],
         "drivers": [{"type": "spawn", "body": {"name": "crate", "shape": {"sphere": 1}}, "at": 1}]})",
     "drivers[0].body.name", "duplicate body name \"crate\" (also used by bodies[0])"},
    {"DriverNotObject", driverScene("3"), "drivers[0]", "expected an object, got a number"},
    // --- shoot
    {"ShootNeedsRay", driverScene(R"({"type": "shoot", "impulse": 1, "times": [1]})"), "drivers[0].ray",
     "missing required field"},
    {"ShootRayUnknownField", driverScene(R"({"type": "shoot", "ray": {"from": [0, 0, 0], "toward": [1, 0, 0]}, "impulse": 1, "times": [1]})"),
     "drivers[0].ray.toward", "unknown field (allowed: from, to)"},
    {"ShootRayBadPoint", driverScene(R"({"type": "shoot", "ray": {"from": [0, 0], "to": [1, 0, 0]}, "impulse": 1, "times": [1]})"),
     "drivers[0].ray.from", "expected an array of 3 numbers"},
    {"ShootRayTooShort", driverScene(R"({"type": "shoot", "ray": {"from": [0, 0, 0], "to": [0, 0, 1e-4]}, "impulse": 1, "times": [1]})"),
     "drivers[0].ray.to", "must be at least 1 mm from ray.from"},
    {"ShootImpulseZero", driverScene(R"({"type": "shoot", "ray": {"from": [0, 0, 0], "to": [1, 0, 0]}, "impulse": 0, "times": [1]})"),
     "drivers[0].impulse", "must be greater than 0"},
    {"ShootImpulseNaNLike", driverScene(R"({"type": "shoot", "ray": {"from": [0, 0, 0], "to": [1, 0, 0]}, "impulse": 1e300, "times": [1]})"),
     "drivers[0].impulse", "must be in (0, "},
    {"ShootNoTimes", driverScene(R"({"type": "shoot", "ray": {"from": [0, 0, 0], "to": [1, 0, 0]}, "impulse": 1})"),
     "drivers[0].times", "missing required field (or every, with from and until)"},
    {"ShootTimesEmpty", driverScene(R"({"type": "shoot", "ray": {"from": [0, 0, 0], "to": [1, 0, 0]}, "impulse": 1, "times": []})"),
     "drivers[0].times", "at least one time"},
    {"ShootTimesNotAscending", driverScene(R"({"type": "shoot", "ray": {"from": [0, 0, 0], "to": [1, 0, 0]}, "impulse": 1, "times": [1, 2, 2]})"),
     "drivers[0].times[2]", "must be after the time before it (got 2 <= 2)"},
    {"ShootTimeNegative", driverScene(R"({"type": "shoot", "ray": {"from": [0, 0, 0], "to": [1, 0, 0]}, "impulse": 1, "times": [-1]})"),
     "drivers[0].times[0]", "must be in [0, "},
    {"ShootTimesAndEvery", driverScene(R"({"type": "shoot", "ray": {"from": [0, 0, 0], "to": [1, 0, 0]}, "impulse": 1, "times": [1], "every": 1})"),
     "drivers[0].every", "either times or every"},
    {"ShootTimesWithFrom", driverScene(R"({"type": "shoot", "ray": {"from": [0, 0, 0], "to": [1, 0, 0]}, "impulse": 1, "times": [1], "from": 1})"),
     "drivers[0].from", "only with every"},
    {"ShootEveryNeedsUntil", driverScene(R"({"type": "shoot", "ray": {"from": [0, 0, 0], "to": [1, 0, 0]}, "impulse": 1, "every": 1})"),
     "drivers[0].until", "with every, the shots end at until"},
    {"ShootEveryZero", driverScene(R"({"type": "shoot", "ray": {"from": [0, 0, 0], "to": [1, 0, 0]}, "impulse": 1, "every": 0, "until": 2})"),
     "drivers[0].every", "must be in (0, "},
    {"ShootEveryTooMany", driverScene(R"({"type": "shoot", "ray": {"from": [0, 0, 0], "to": [1, 0, 0]}, "impulse": 1, "every": 1e-6, "until": 1})"),
     "drivers[0].every", "more than 100000 shots"},
    {"ShootHasNoTarget", driverScene(R"({"type": "shoot", "target": "rope", "ray": {"from": [0, 0, 0], "to": [1, 0, 0]}, "impulse": 1, "times": [1]})"),
     "drivers[0].target", "unknown field"},
    // --- joints
    {"JointUnknownType", jointScene(R"({"type": "cone", "body": "b", "pivot": [0, 1, 0]})"), "joints[0].type",
     "must be \"ball\", \"hinge\", \"slider\", \"fixed\" or \"spring\" (got \"cone\")"},
    {"JointUnknownBody", jointScene(R"({"type": "ball", "body": "nobody", "pivot": [0, 1, 0]})"), "joints[0].body",
     "no body named \"nobody\""},
    {"JointStaticBody", jointScene(R"({"type": "ball", "body": "post", "pivot": [0, 1, 0]})"), "joints[0].body",
     "must name a dynamic body"},
    {"JointOtherIsBody", jointScene(R"({"type": "ball", "body": "b", "other": "b", "pivot": [0, 1, 0]})"),
     "joints[0].other", "must name another body"},
    {"JointBallWithAxis", jointScene(R"({"type": "ball", "body": "b", "pivot": [0, 1, 0], "axis": [0, 0, 1]})"),
     "joints[0].axis", "is for hinges, sliders and springs only (this joint is a ball joint)"},
    {"JointFixedWithLimits", jointScene(R"({"type": "fixed", "body": "b", "pivot": [0, 1, 0], "limits": [0, 1]})"),
     "joints[0].limits", "is for hinges, sliders and springs only (this joint is a fixed joint)"},
    {"JointSliderWithoutAxis", jointScene(R"({"type": "slider", "body": "b", "pivot": [0, 1, 0]})"), "joints[0].axis",
     "missing required field"},
    {"JointSliderZeroAxis", jointScene(R"({"type": "slider", "body": "b", "pivot": [0, 1, 0], "axis": [0, 0, 0]})"),
     "joints[0].axis", "must not be zero (a slider moves along it)"},
    {"JointSliderLimitsReversed", jointScene(R"({"type": "slider", "body": "b", "pivot": [0, 1, 0], "axis": [0, 1, 0], "limits": [0.5, -0.5]})"),
     "joints[0].limits", "lower <= upper"},
    {"JointSliderMotorWithImpulse", jointScene(R"({"type": "slider", "body": "b", "pivot": [0, 1, 0], "axis": [0, 1, 0], "motor": {"velocity": 1, "impulse": 1}})"),
     "joints[0].motor.impulse", "unknown field"},
    {"JointSliderMotorWithoutForce", jointScene(R"({"type": "slider", "body": "b", "pivot": [0, 1, 0], "axis": [0, 1, 0], "motor": {"velocity": 1}})"),
     "joints[0].motor.force", "missing required field"},
    {"JointFixedWithMotor", jointScene(R"({"type": "fixed", "body": "b", "pivot": [0, 1, 0], "motor": {"velocity": 1, "force": 1}})"),
     "joints[0].motor", "is for hinges and sliders only (this joint is a fixed joint)"},
    {"JointHingeWithoutAxis", jointScene(R"({"type": "hinge", "body": "b", "pivot": [0, 1, 0]})"), "joints[0].axis",
     "missing required field"},
    {"JointZeroAxis", jointScene(R"({"type": "hinge", "body": "b", "pivot": [0, 1, 0], "axis": [0, 0, 0]})"),
     "joints[0].axis", "must not be zero"},
    {"JointLimitsReversed", jointScene(R"({"type": "hinge", "body": "b", "pivot": [0, 1, 0], "axis": [0, 0, 1], "limits": [0.5, -0.5]})"),
     "joints[0].limits", "lower <= upper"},
    {"JointLimitPastPi", jointScene(R"({"type": "hinge", "body": "b", "pivot": [0, 1, 0], "axis": [0, 0, 1], "limits": [-4, 0]})"),
     "joints[0].limits[0]", "must be in"},
    {"JointBallWithMotor", jointScene(R"({"type": "ball", "body": "b", "pivot": [0, 1, 0], "motor": {"velocity": 1, "impulse": 1}})"),
     "joints[0].motor", "is for hinges and sliders only"},
    {"JointMotorWithoutImpulse", jointScene(R"({"type": "hinge", "body": "b", "pivot": [0, 1, 0], "axis": [0, 0, 1], "motor": {"velocity": 1}})"),
     "joints[0].motor.impulse", "missing required field"},
    {"JointMotorZeroImpulse", jointScene(R"({"type": "hinge", "body": "b", "pivot": [0, 1, 0], "axis": [0, 0, 1], "motor": {"velocity": 1, "impulse": 0}})"),
     "joints[0].motor.impulse", "must be in"},
    {"JointMotorTooFast", jointScene(R"({"type": "hinge", "body": "b", "pivot": [0, 1, 0], "axis": [0, 0, 1], "motor": {"velocity": 1e4, "impulse": 1}})"),
     "joints[0].motor.velocity", "must be in"},
    {"JointSpringWithoutStiffness", jointScene(R"({"type": "spring", "body": "b", "pivot": [0, 1, 0], "axis": [0, 1, 0]})"),
     "joints[0].stiffness", "missing required field"},
    {"JointSpringZeroStiffness", jointScene(R"({"type": "spring", "body": "b", "pivot": [0, 1, 0], "axis": [0, 1, 0], "stiffness": 0})"),
     "joints[0].stiffness", "must be in"},
    {"JointSpringNegativeDamping", jointScene(R"({"type": "spring", "body": "b", "pivot": [0, 1, 0], "axis": [0, 1, 0], "stiffness": 1, "damping": -1})"),
     "joints[0].damping", "must be in"},
    {"JointSpringZeroAxis", jointScene(R"({"type": "spring", "body": "b", "pivot": [0, 1, 0], "axis": [0, 0, 0], "stiffness": 1})"),
     "joints[0].axis", "must not be zero (a spring moves along it)"},
    {"JointSpringWithMotor", jointScene(R"({"type": "spring", "body": "b", "pivot": [0, 1, 0], "axis": [0, 1, 0], "stiffness": 1, "motor": {"velocity": 1, "force": 1}})"),
     "joints[0].motor", "is for hinges and sliders only (this joint is a spring)"},
    {"JointSliderWithStiffness", jointScene(R"({"type": "slider", "body": "b", "pivot": [0, 1, 0], "axis": [0, 1, 0], "stiffness": 1})"),
     "joints[0].stiffness", "is for springs only (this joint is a slider)"},
    {"JointMotorUnknownField", jointScene(R"({"type": "hinge", "body": "b", "pivot": [0, 1, 0], "axis": [0, 0, 1], "motor": {"velocity": 1, "impulse": 1, "torque": 2}})"),
     "joints[0].motor.torque", "unknown field"},
};

INSTANTIATE_TEST_SUITE_P(SceneLoader, SceneErrors, ::testing::ValuesIn(kErrorCases),
                         [](const ::testing::TestParamInfo<ErrorCase>& param) { return std::string(param.param.label); });

// ---------------------------------------------------------------------------------------------
// Files and built-in scenes
// ---------------------------------------------------------------------------------------------

TEST(SceneLoader, JointsAreRead) {
    const Scene s = parseScene(jointScene(
        R"({"type": "hinge", "body": "b", "other": "post", "pivot": [0, 1, 0], "axis": [0, 0, 2], "limits": [-0.5, 0.25]},
           {"type": "ball", "body": "b", "pivot": [1, 1, 0]})"));
    ASSERT_EQ(s.joints.size(), 2u);
    EXPECT_EQ(s.joints[0].kind, tearables::scene::Joint::Kind::Hinge);
    EXPECT_EQ(s.joints[0].body, "b");
    EXPECT_EQ(s.joints[0].other, std::optional<std::string>("post"));
    EXPECT_EQ(s.joints[0].axis, Vec3(0, 0, 1));  // normalised
    ASSERT_TRUE(s.joints[0].limits.has_value());
    EXPECT_EQ((*s.joints[0].limits)[0], -0.5);
    EXPECT_EQ((*s.joints[0].limits)[1], 0.25);
    EXPECT_FALSE(s.joints[0].motor.has_value());
    EXPECT_EQ(s.joints[1].kind, tearables::scene::Joint::Kind::Ball);
    EXPECT_FALSE(s.joints[1].other.has_value());
    EXPECT_EQ(s.joints[1].pivot, Vec3(1, 1, 0));
}

// A slider's limits are metres along its axis (a hinge's are radians within [-pi, pi]) and
// its motor's bound a force (a hinge's an impulse); a fixed joint has a pivot only.
TEST(SceneLoader, SlidersAndFixedJointsAreRead) {
    const Scene s = parseScene(jointScene(
        R"({"type": "slider", "body": "b", "other": "post", "pivot": [0, 1, 0], "axis": [0, -3, 0], "limits": [-5, 0.5], "motor": {"velocity": -0.25, "force": 40}},
           {"type": "fixed", "body": "b", "pivot": [1, 1, 0]})"));
    ASSERT_EQ(s.joints.size(), 2u);
    EXPECT_EQ(s.joints[0].kind, tearables::scene::Joint::Kind::Slider);
    EXPECT_EQ(s.joints[0].axis, Vec3(0, -1, 0));  // normalised
    ASSERT_TRUE(s.joints[0].limits.has_value());
    EXPECT_EQ((*s.joints[0].limits)[0], -5.0);
    EXPECT_EQ((*s.joints[0].limits)[1], 0.5);
    ASSERT_TRUE(s.joints[0].motor.has_value());
    EXPECT_EQ(s.joints[0].motor->velocity, -0.25);
    EXPECT_EQ(s.joints[0].motor->force, 40.0);
    EXPECT_EQ(s.joints[1].kind, tearables::scene::Joint::Kind::Fixed);
    EXPECT_FALSE(s.joints[1].other.has_value());
    EXPECT_EQ(s.joints[1].pivot, Vec3(1, 1, 0));
}

TEST(SceneLoader, SpringJointIsRead) {
    const Scene s = parseScene(jointScene(
        R"({"type": "spring", "body": "b", "other": "post", "pivot": [0, 1, 0], "axis": [0, 2, 0], "stiffness": 300, "damping": 12.5, "limits": [-0.3, 0.1]},
           {"type": "spring", "body": "b", "pivot": [0, 1, 0], "axis": [1, 0, 0], "stiffness": 5})"));
    ASSERT_EQ(s.joints.size(), 2u);
    EXPECT_EQ(s.joints[0].kind, tearables::scene::Joint::Kind::Spring);
    EXPECT_EQ(s.joints[0].axis, Vec3(0, 1, 0));  // normalised
    EXPECT_EQ(s.joints[0].stiffness, 300.0);
    EXPECT_EQ(s.joints[0].damping, 12.5);
    ASSERT_TRUE(s.joints[0].limits.has_value());
    EXPECT_EQ((*s.joints[0].limits)[0], -0.3);
    EXPECT_EQ(s.joints[1].damping, 0.0);  // the default
    EXPECT_FALSE(s.joints[1].limits.has_value());
}

TEST(SceneLoader, HingeMotorIsRead) {
    const Scene s = parseScene(jointScene(
        R"({"type": "hinge", "body": "b", "pivot": [0, 1, 0], "axis": [0, 0, 1], "motor": {"velocity": -2.5, "impulse": 0.75}})"));
    ASSERT_EQ(s.joints.size(), 1u);
    ASSERT_TRUE(s.joints[0].motor.has_value());
    EXPECT_EQ(s.joints[0].motor->velocity, -2.5);
    EXPECT_EQ(s.joints[0].motor->impulse, 0.75);
}

TEST(SceneLoader, LoadSceneFileSetsTheSource) {
    const std::string path = ::testing::TempDir() + "tearables_scene_loader_test.json";
    {
        std::ofstream out(path);
        out << "// from a file\n{\"steps\": 12}\n";
    }
    const Scene s = loadSceneFile(path);
    EXPECT_EQ(s.steps, 12);
    EXPECT_EQ(s.source, path);
    std::remove(path.c_str());
}

TEST(SceneLoader, LoadSceneFileReportsAnUnreadableFile) {
    const std::string path = ::testing::TempDir() + "tearables_no_such_scene.json";
    try {
        loadSceneFile(path);
        FAIL() << "no error";
    } catch (const InvalidInput&) {
        FAIL() << "an unreadable file is not invalid input";
    } catch (const std::runtime_error& e) {
        EXPECT_EQ(std::string(e.what()).rfind("cannot read " + path + ": ", 0), 0u) << e.what();
    }
}

TEST(SceneLoader, LoadSceneFileReportsADirectory) {
    EXPECT_THROW(loadSceneFile(::testing::TempDir()), std::runtime_error);
}

TEST(SceneLoader, LoadSceneFileReportsBadContent) {
    const std::string path = ::testing::TempDir() + "tearables_bad_scene.json";
    {
        std::ofstream out(path);
        out << "{\"dt\": -1}";
    }
    try {
        loadSceneFile(path);
        FAIL() << "no error";
    } catch (const InvalidInput& e) {
        EXPECT_EQ(e.field(), "dt");
    }
    std::remove(path.c_str());
}

TEST(BuiltinScenes, EveryBuiltinSceneParses) {
    const auto scenes = builtinScenes();  // may be empty in a build without demos/scenes/*.json
    for (const auto& [name, description] : scenes) {
        SCOPED_TRACE(name);
        EXPECT_FALSE(name.empty());
        const std::optional<std::string> text = builtinSceneText(name);
        ASSERT_TRUE(text.has_value());
        try {
            parseScene(*text);
        } catch (const InvalidInput& e) {
            ADD_FAILURE() << "built-in scene " << name << ": " << e.what();
        }
    }
}

// A shoot driver's shots: listed, or every so many seconds from `from` until (not at) `until`.
TEST(SceneLoader, ShootDriverTimes) {
    const Scene listed = parseScene(driverScene(
        R"({"type": "shoot", "ray": {"from": [0, 1, 2], "to": [0, 1, -2]}, "impulse": 0.5, "times": [0.25, 1]})"));
    ASSERT_EQ(listed.drivers.size(), 1u);
    const Driver& d = listed.drivers[0];
    EXPECT_EQ(d.type, Driver::Type::Shoot);
    EXPECT_EQ(d.ray_from, Vec3(0, 1, 2));
    EXPECT_EQ(d.ray_to, Vec3(0, 1, -2));
    EXPECT_EQ(d.impulse, 0.5);
    EXPECT_EQ(d.times, (std::vector<double>{0.25, 1.0}));
    const Scene periodic = parseScene(driverScene(
        R"({"type": "shoot", "ray": {"from": [0, 1, 2], "to": [0, 1, -2]}, "impulse": 0.5, "every": 0.5, "from": 1, "until": 3})"));
    EXPECT_EQ(periodic.drivers[0].times, (std::vector<double>{1.0, 1.5, 2.0, 2.5}));
}

// Force and ramp drivers act only between from and until (SCENE_FORMAT.md). Two free
// strings without gravity: internal forces cancel in pairs, so a string's momentum is the
// driver's impulse. A step starting at t0 = (s - 1) dt is driven when from <= t0 < until,
// so a force F gives F dt per driven step, and a ramp rate (t0 - from) dt: with from = 0.1,
// until = 0.3, dt = 0.01 the driven steps have t0 - from = k dt, k = 0..19, and the impulse
// is rate dt^2 (0 + ... + 19) = 190 rate dt^2. Before from and after until it is constant.
// The force reaches the string through Bullet's single-precision btVector3 (0.02 is stored
// as 0.0199999996), so the impulses hold to float precision, a relative 1e-7, not 1e-16.
TEST(SceneRun, ForceAndRampActOnlyBetweenFromAndUntil) {
    const Scene scene = parseScene(R"({"dt": 0.01, "steps": 50, "gravity": [0, 0, 0],
      "strings": [{"name": "pushed", "from": [0, 0, 0], "to": [0, 1, 0], "segments": 4, "radius": 0.005, "density": 1000},
                  {"name": "ramped", "from": [1, 0, 0], "to": [1, 1, 0], "segments": 4, "radius": 0.005, "density": 1000}],
      "drivers": [{"type": "force", "target": "pushed", "particle": -1, "value": [0, 0, 0.02], "from": 0.1, "until": 0.3},
                  {"type": "ramp", "target": "ramped", "particle": -1, "value": [0, 0, 1], "rate": 0.4, "from": 0.1, "until": 0.3}]})");
    const double dt = 0.01;
    const double force_impulse = 0.02 * 20 * dt, ramp_impulse = 0.4 * 190 * dt * dt;  // N s
    std::vector<double> times, pushed, ramped;
    RunOptions options;
    options.every = 1;
    options.on_frame = [&](const FrameState& f) {
        times.push_back(f.time);
        for (const FrameString& s : f.strings) {
            Vec3 p = Vec3::Zero();
            for (std::size_t i = 0; i < s.view.particleCount(); ++i) p += (*s.view.masses)[i] * (*s.view.velocities)[i];
            EXPECT_NEAR(p.x(), 0.0, 1e-9);
            EXPECT_NEAR(p.y(), 0.0, 1e-9);
            (s.name == "pushed" ? pushed : ramped).push_back(p.z());
        }
    };
    runScene(scene, options);
    ASSERT_EQ(times.size(), 51u);
    for (std::size_t k = 0; k < times.size(); ++k) {
        const double t = times[k];  // the end of step k: steps 1..k have t0 < t
        const double driven = std::clamp(std::round((t - 0.1) / dt), 0.0, 20.0);  // driven steps so far
        const double ramp_expected = 0.4 * dt * dt * driven * (driven - 1) / 2;
        EXPECT_NEAR(pushed[k], 0.02 * dt * driven, 1e-6 * force_impulse) << "t = " << t;
        EXPECT_NEAR(ramped[k], ramp_expected, 1e-6 * ramp_impulse) << "t = " << t;
    }
    EXPECT_NEAR(pushed.back(), force_impulse, 1e-6 * force_impulse);
    EXPECT_NEAR(ramped.back(), ramp_impulse, 1e-6 * ramp_impulse);
}

// A scene's slider motor drives its body along the axis relative to the world at its
// velocity up to its force, and its limits stop it: a 3 kg platform on a vertical slider
// with a light rope hanging from it (so the island solves it), its motor at 0.3 m/s with
// 200 N (seven times its weight), rises at 0.3 m/s (1%) and rests on its upper limit, 0.1 m
// above where it started (1 mm).
TEST(SceneRun, SliderMotorLiftsItsPlatformToItsLimit) {
    const Scene scene = parseScene(R"({"dt": 0.01, "steps": 100, "gravity": [0, -9.81, 0],
      "bodies": [{"name": "platform", "shape": {"box": [0.3, 0.025, 0.2]}, "mass": 3, "position": [0, 1, 0]}],
      "joints": [{"type": "slider", "body": "platform", "pivot": [0, 1, 0], "axis": [0, 1, 0], "limits": [-1, 0.1],
                  "motor": {"velocity": 0.3, "force": 200}}],
      "strings": [{"name": "tail", "from": [0.25, 0.975, 0], "to": [0.25, 0.775, 0], "segments": 8, "radius": 0.002, "density": 1150,
                   "attachments": [{"particle": 0, "body": "platform", "local": [0.25, -0.025, 0]}]}]})");
    std::vector<double> heights;
    RunOptions options;
    options.every = 1;
    options.on_frame = [&](const FrameState& f) { heights.push_back(f.bodies.at(0).position.y()); };
    runScene(scene, options);
    ASSERT_EQ(heights.size(), 101u);
    EXPECT_NEAR((heights[25] - heights[15]) / 0.1, 0.3, 0.003);  // rising, well before the limit (0.33 s)
    EXPECT_NEAR(heights.back(), 1.1, 1e-3);
}

// A scene's spring joint is a spring along its axis, at rest where the bodies start: a 3 kg
// platform on a vertical spring of 300 N/m with a light rope hanging from it (so the island
// solves it), released there, swings down to twice its static sag, 2 m g / k (3%), and back
// with the period 2 pi sqrt(m / k) (its lowest points 0.63 s apart, 1%); damped at a ratio
// of 1/2 it settles at the sag m g / k (0.5%).
TEST(SceneRun, SpringJointHoldsItsBodyAtItsSag) {
    constexpr double kPi = 3.14159265358979323846;
    for (const double damping : {0.0, 30.0}) {
        SCOPED_TRACE(damping);
        const Scene scene = parseScene(R"({"dt": 0.01, "steps": 200, "gravity": [0, -9.81, 0],
          "bodies": [{"name": "platform", "shape": {"box": [0.3, 0.025, 0.2]}, "mass": 3, "position": [0, 1, 0]}],
          "joints": [{"type": "spring", "body": "platform", "pivot": [0, 1, 0], "axis": [0, 1, 0], "stiffness": 300, "damping": )" +
                                       std::to_string(damping) + R"(}],
          "strings": [{"name": "tail", "from": [0.25, 0.975, 0], "to": [0.25, 0.775, 0], "segments": 8, "radius": 0.002, "density": 1150,
                       "attachments": [{"particle": 0, "body": "platform", "local": [0.25, -0.025, 0]}]}]})");
        const double mass = 3.0 + 1150.0 * kPi * 0.002 * 0.002 * 0.2, sag = mass * 9.81 / 300.0;
        std::vector<double> heights;
        RunOptions options;
        options.every = 1;
        options.on_frame = [&](const FrameState& f) { heights.push_back(f.bodies.at(0).position.y() - 1.0); };
        runScene(scene, options);
        ASSERT_EQ(heights.size(), 201u);
        if (damping > 0.0) {
            EXPECT_NEAR(heights.back(), -sag, 0.005 * sag);
            continue;
        }
        const auto lowest = std::min_element(heights.begin(), heights.begin() + 64);
        EXPECT_NEAR(*lowest, -2.0 * sag, 0.03 * 2.0 * sag);
        const auto next = std::min_element(heights.begin() + 64, heights.begin() + 127);
        const double period = 2.0 * kPi * std::sqrt(mass / 300.0);
        EXPECT_NEAR(0.01 * static_cast<double>(next - lowest), period, 0.01 * period + 0.01);  // whole frames
    }
}

// A scene's slider to another body bounds body's travel relative to that body, and a fixed
// joint welds two bodies where they start: a platform on a slider along a static post's
// axis, free to drop 0.2 m relative to it, drops 0.2 m (2 mm); two boards welded end to
// end, each held by a rope at its outer end, stay one straight beam (their ends together
// within 1 mm, their x axes within 1 mrad) while each rope carries half their weight (1%).
TEST(SceneRun, SliderToABodyAndFixedJointHoldWhatTheySay) {
    const Scene scene = parseScene(R"({"dt": 0.01, "steps": 200, "gravity": [0, -9.81, 0],
      "bodies": [{"name": "post", "shape": {"box": [0.05, 1, 0.05]}, "mass": 0, "position": [-1, 1, 0]},
                 {"name": "platform", "shape": {"box": [0.3, 0.025, 0.2]}, "mass": 3, "position": [-0.6, 1, 0]},
                 {"name": "left", "shape": {"box": [0.5, 0.025, 0.15]}, "mass": 3, "position": [0.5, 1, 0]},
                 {"name": "right", "shape": {"box": [0.5, 0.025, 0.15]}, "mass": 3, "position": [1.5, 1, 0]}],
      "joints": [{"type": "slider", "body": "platform", "other": "post", "pivot": [-1, 1, 0], "axis": [0, 1, 0], "limits": [-0.2, 0]},
                 {"type": "fixed", "body": "right", "other": "left", "pivot": [1, 1, 0]}],
      "strings": [{"name": "tail", "from": [-0.4, 0.975, 0], "to": [-0.4, 0.775, 0], "segments": 8, "radius": 0.002, "density": 1150,
                   "attachments": [{"particle": 0, "body": "platform", "local": [0.2, -0.025, 0]}]},
                  {"name": "a", "from": [0.05, 2, 0], "to": [0.05, 1.025, 0], "segments": 40, "radius": 0.002, "density": 1150,
                   "attachments": [{"particle": 0, "world": [0.05, 2, 0]}, {"particle": -1, "body": "left", "local": [-0.45, 0.025, 0]}]},
                  {"name": "b", "from": [1.95, 2, 0], "to": [1.95, 1.025, 0], "segments": 40, "radius": 0.002, "density": 1150,
                   "attachments": [{"particle": 0, "world": [1.95, 2, 0]}, {"particle": -1, "body": "right", "local": [0.45, 0.025, 0]}]}]})");
    FrameState last;
    std::vector<double> pulls;
    RunOptions options;
    options.every = 200;
    options.on_frame = [&](const FrameState& f) {
        last.bodies = f.bodies;
        pulls.clear();
        for (const FrameString& str : f.strings) {
            if (str.name == "tail") continue;
            const auto& x = *str.view.positions;
            pulls.push_back(str.view.tension->back() * (x[x.size() - 2] - x.back()).normalized().y());
        }
    };
    runScene(scene, options);
    ASSERT_EQ(last.bodies.size(), 4u);
    EXPECT_NEAR(last.bodies[1].position.y(), 0.8, 0.002);
    EXPECT_NEAR(last.bodies[1].position.x(), -0.6, 1e-3);
    const FrameBody& left = last.bodies[2];
    const FrameBody& right = last.bodies[3];
    EXPECT_LT(((left.position + left.orientation * Vec3(0.5, 0, 0)) - (right.position + right.orientation * Vec3(-0.5, 0, 0))).norm(), 1e-3);
    EXPECT_LT((left.orientation * Vec3::UnitX()).cross(right.orientation * Vec3::UnitX()).norm(), 1e-3);
    ASSERT_EQ(pulls.size(), 2u);
    for (const double pull : pulls) EXPECT_NEAR(pull, 3.0 * 9.81, 0.01 * 3.0 * 9.81);
}


// The same on sheets (SCENE_FORMAT.md, drivers: "force" on a cloth or paper vertex):
// free, without gravity, a sheet's springs and yarns act in pairs, so its momentum is the
// force's impulse, F dt per driven step, along F (a corner pushed: the sheet also turns
// and bends, which moves no momentum). The paper's Jacobi sweeps stop at a residual whose
// sum is a momentum error, which a uniform velocity removes (implicit.cpp, keepMomentum);
// the conjugate gradient stops within its tolerance (1e-12 here). A
// "move" driver takes its vertex along velocity dt per driven step, exactly (a pin).
// The force reaches the sheet as Bullet's single-precision btVector3, each component
// rounded by at most 2^-24 of itself: the impulse holds to that, relative.
TEST(SceneRun, ForceAndMoveDriversOnSheetVertices) {
    const double kFloat = std::ldexp(1.0, -24);
    for (const char* solver : {"paper", "conjugate_gradient", "multigrid"}) {
        SCOPED_TRACE(solver);
        const Scene scene = parseScene(std::string(R"({"dt": 0.01, "steps": 40, "gravity": [0, 0, 0],
          "papers": [{"name": "sheet", "center": [0, 1, 0], "size": [0.2, 0.3], "resolution": [7, 9], "breakable": false,
                      "solver": ")") + solver + R"(", "tolerance": 1e-12},
                     {"name": "led", "center": [1, 1, 0], "size": [0.2, 0.2], "resolution": [5, 5], "breakable": false}],
          "cloths": [{"name": "cloth", "corner": [0, 1, 1], "size": [0.2, 0.2], "resolution": [6, 6]}],
          "drivers": [{"type": "force", "target": "sheet", "vertex": [0, 0], "value": [0.02, 0.01, -0.015], "from": 0.1, "until": 0.3},
                      {"type": "force", "target": "cloth", "vertex": [5, 0], "value": [0.002, 0.003, 0.001], "from": 0.1, "until": 0.3},
                      {"type": "move", "target": "led", "vertex": [4, 4], "velocity": [0.1, 0.2, -0.05], "from": 0.1, "until": 0.3}]})");
        const double dt = 0.01;
        const Vec3 paper_force(0.02, 0.01, -0.015), cloth_force(0.002, 0.003, 0.001), velocity(0.1, 0.2, -0.05);
        Vec3 led_start = Vec3::Constant(NAN);
        int frames = 0;
        RunOptions options;
        options.every = 1;
        options.on_frame = [&](const FrameState& f) {
            const double driven = std::clamp(std::round((f.time - 0.1) / dt), 0.0, 20.0);  // driven steps so far
            for (const FramePaper& p : f.papers) {
                if (p.name == "led") {
                    const Vec3 x = (*p.view.positions)[24];
                    if (f.step == 0) led_start = x;
                    if (driven > 0.0) EXPECT_LT((x - (led_start + velocity * dt * driven)).norm(), 1e-12) << "t = " << f.time;
                    continue;
                }
                Vec3 momentum = Vec3::Zero();
                for (std::size_t i = 0; i < p.view.vertexCount(); ++i) momentum += (*p.view.masses)[i] * (*p.view.velocities)[i];
                const Vec3 impulse = paper_force * dt * driven;
                EXPECT_LE((momentum - impulse).norm(), kFloat * impulse.norm() + 1e-15) << "t = " << f.time;
            }
            for (const FrameCloth& c : f.cloths) {
                Vec3 momentum = Vec3::Zero();
                for (std::size_t i = 0; i < c.view.vertexCount(); ++i) momentum += (*c.view.masses)[i] * (*c.view.velocities)[i];
                const Vec3 impulse = cloth_force * dt * driven;
                EXPECT_LE((momentum - impulse).norm(), kFloat * impulse.norm() + 1e-15) << "t = " << f.time;
            }
            ++frames;
        };
        runScene(scene, options);
        EXPECT_EQ(frames, 41);
    }
}

TEST(BuiltinScenes, UnknownNameHasNoText) {
    EXPECT_FALSE(builtinSceneText("no such scene").has_value());
}

}  // namespace
}  // namespace tearables::scene
