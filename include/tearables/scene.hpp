// tearables: headless scenes (the format is docs/SCENE_FORMAT.md, "tearables-scene/1").
// Loading checks every field; a bad one throws InvalidInput whose field() is the JSON path
// ("strings[0].material.tensile.rupture") and whose problem() says what is wrong.
#pragma once

#include "tearables/cloth.hpp"
#include "tearables/paper.hpp"
#include "tearables/string.hpp"
#include "tearables/types.hpp"
#include "tearables/world.hpp"

#include <functional>
#include <memory>
#include <array>
#include <optional>
#include <string>
#include <vector>

class btDiscreteDynamicsWorld;
class btRigidBody;
namespace tearables {
class BulletWorld;
}

namespace tearables::scene {

/// Scripted forces (force drivers, and a ramp's force once it has grown), N: the loader
/// refuses more, and a ramp stops growing there.
inline constexpr double kMaxDriverForce = 1e9;
/// The speed no scripted velocity, wind or shot may ask for, m/s (WorldSettings::max_speed):
/// a shot's impulse is clamped to what brings the particle or body it hits to this speed.
inline constexpr double kMaxDriverSpeed = 500.0;

/// A collision shape of a rigid body.
struct Shape {
    enum class Kind { Box, Sphere, Capsule, Plane };
    Kind kind = Kind::Box;
    Vec3 half_extents{0.5, 0.5, 0.5};  ///< box, m, each > 0
    double radius = 0.5;               ///< sphere and capsule, m, > 0
    double half_height = 0.5;          ///< capsule: half the cylinder's length (axis y), m, > 0
    Vec3 plane_normal{0.0, 1.0, 0.0};  ///< plane: unit normal (normalised on load; non-zero)
    double plane_offset = 0.0;         ///< plane: n . x = offset, m
};

/// A Bullet rigid body.
struct Body {
    std::string name;                    ///< unique among bodies, non-empty
    Shape shape;
    double mass = 1.0;                   ///< kg, >= 0; 0 = static (planes must be static)
    bool kinematic = false;              ///< moved only by its velocities
    Vec3 position = Vec3::Zero();        ///< m
    Quat orientation = Quat::Identity(); ///< from [x, y, z, w], normalised on load; non-zero
    Vec3 linear_velocity = Vec3::Zero(); ///< m/s
    Vec3 angular_velocity = Vec3::Zero();///< rad/s
    double friction = 0.5;               ///< >= 0
    double restitution = 0.0;            ///< [0, 1]
};

/// A Bullet joint (docs/SCENE_FORMAT.md, "joints"): a ball joint (btPoint2PointConstraint), a
/// hinge (btHingeConstraint), a slider (btSliderConstraint), a fixed joint
/// (btFixedConstraint) or a spring (btGeneric6DofSpring2Constraint free along its axis only,
/// on a spring there) between a dynamic body and another body or the world, at a world
/// point (and axis) where the bodies start.
struct Joint {
    enum class Kind { Ball, Hinge, Slider, Fixed, Spring };
    Kind kind = Kind::Hinge;
    std::string body;                      ///< a dynamic body's name
    std::optional<std::string> other;      ///< the other body's name (not `body`); none: the world
    Vec3 pivot = Vec3::Zero();             ///< m, world, where the bodies start
    Vec3 axis = Vec3::UnitZ();             ///< hinge, slider, spring: world axis (normalised on load; non-zero)
    /// [lower, upper], lower <= upper: a hinge's angle, rad in [-pi, pi]; a slider's or a
    /// spring's travel along its axis, m: body's displacement relative to other (or the
    /// world) from where they start. None: a hinge turns freely, a slider slides freely.
    std::optional<std::array<double, 2>> limits;
    /// A hinge's angular motor (btHingeConstraint::enableAngularMotor): its target rate,
    /// rad/s in [-1e3, 1e3], and its largest impulse a step, N m s in (0, 1e6]; or a
    /// slider's linear motor (btSliderConstraint::setPoweredLinMotor): body's target rate
    /// along the axis relative to other, m/s in [-1e3, 1e3], and its largest force, N in
    /// (0, 1e6].
    struct Motor {
        double velocity = 0.0;
        double impulse = 0.0;  ///< hinge
        double force = 0.0;    ///< slider
    };
    std::optional<Motor> motor;
    /// A spring's stiffness, N/m in (0, 1e9], and damping, N s/m in [0, 1e9]: it pulls body
    /// back along the axis toward where it started relative to other.
    double stiffness = 0.0;
    double damping = 0.0;
};

/// What holds a string's particle (the same words as a sheet's: docs/SCENE_FORMAT.md, "Words").
struct Attachment {
    int particle = 0;                  ///< index; negative counts from the end; checked in range
    std::optional<std::string> body;   ///< the body's name (must exist), or
    std::optional<Vec3> local;         ///< with body: point in the body's frame, m; default: where the particle is
    std::optional<Vec3> world;         ///< a world point, m (exactly one of body / world; "world": true gives the particle's rest point)
};

/// A string of the scene.
struct String {
    StringDesc desc;                      ///< name, points, material, ... (name unique, non-empty)
    std::vector<Attachment> attachments;  ///< at most one per particle
    int collision_group = 1;              ///< Bullet's collision filter (as addSoftBody): btBroadphaseProxy::DefaultFilter
    int collision_mask = -1;              ///< AllFilter: touches every body whose mask has its group
    std::string geometry_field = "segments";  ///< the field that gave the particles: "segments" or "points" (for messages)
};

/// A vertex of a cloth or a paper sheet glued to a body of the scene (pins to world points
/// are in ClothDesc::attachments and PaperDesc::attachments: a scene names its bodies, which
/// exist only once the scene runs).
struct SheetGlue {
    std::uint32_t vertex = 0;          ///< resolved flat vertex index
    std::string body;                  ///< the body's name (must exist)
    std::optional<Vec3> local;         ///< point in the body's frame, m; default: where the vertex is
};

/// A cloth of the scene.
struct Cloth {
    ClothDesc desc;                          ///< name, weave, material, world pins, ... (name unique among strings and cloths)
    std::vector<SheetGlue> glue;             ///< vertices glued to bodies
    int collision_group = 1;              ///< Bullet's collision filter (as addSoftBody): btBroadphaseProxy::DefaultFilter
    int collision_mask = -1;              ///< AllFilter: touches every body whose mask has its group
};

/// A paper sheet of the scene.
struct Paper {
    PaperDesc desc;                    ///< name (unique among papers, non-empty), mesh, material, world pins
    std::vector<SheetGlue> glue;       ///< vertices glued to bodies
    int collision_group = 1;              ///< Bullet's collision filter (as addSoftBody): btBroadphaseProxy::DefaultFilter
    int collision_mask = -1;              ///< AllFilter: touches every body whose mask has its group
};

/// A scripted action.
struct Driver {
    enum class Type { Force, Ramp, Twist, Move, Release, Wind, Spawn, Velocity, Shoot };
    Type type = Type::Force;
    std::string target;       ///< string or cloth name (force, ramp, twist, move, release)
    int particle = -1;        ///< particle index (force, ramp, move, release), or the cloth's flat vertex index
    bool cloth = false;       ///< the target is a cloth: "vertex": [i, j] instead of "particle"
    int end = -1;             ///< twist: 0 or -1 (which clamped end)
    Vec3 value = Vec3::Zero();///< force: N; ramp: direction (non-zero, normalised on load); wind: m/s
    double rate = 0.0;        ///< ramp: N/s (> 0); twist: rad/s
    Vec3 velocity = Vec3::Zero(); ///< move: m/s
    double gust = 0.0;        ///< wind: relative gust amplitude, [0, 10]
    double from = 0.0;        ///< s, >= 0
    double until = 1e300;     ///< s, > from (default: the whole run)
    double at = 0.0;          ///< release, spawn: s, >= 0
    std::optional<Body> body; ///< spawn: the body (its name unique among all bodies)
    std::string body_name;    ///< velocity: the body whose linear velocity is set (value, m/s) between from and until
    int paper_vertex = -1;    ///< force, move on a paper target: the vertex (resolved); -1 = the target is a string
    Vec3 ray_from = Vec3::Zero();  ///< shoot: where the ray starts, m
    Vec3 ray_to = Vec3::Zero();    ///< shoot: where it ends, m (at least 1 mm from ray_from)
    double impulse = 0.0;          ///< shoot: N s along the ray's direction, (0, 1e6]
    /// shoot: the times of the shots, s, ascending, each >= 0 (from "times", or from "every"
    /// seconds between from and until).
    std::vector<double> times;
};

/// Where the pictures (`--png`) look from. Every field is optional: what is absent is
/// fitted to the scene's bounds (fitCamera, demos/render/scene_painter.hpp).
struct Camera {
    std::optional<Vec3> eye;     ///< camera position, m (must differ from target)
    std::optional<Vec3> target;  ///< the point looked at, m
    double fov = 40.0;           ///< vertical field of view, degrees, (1, 170)
};

/// A whole scene.
struct Scene {
    double dt = 0.01;                 ///< fixed internal step, s, (0, 0.1]
    long long steps = 500;            ///< >= 0
    Vec3 gravity{0.0, -9.81, 0.0};    ///< m/s^2
    std::uint64_t seed = 1;           ///< seeds every random choice (string i gets seed + i)
    std::vector<Body> bodies;
    std::vector<Joint> joints;
    std::vector<String> strings;
    std::vector<Cloth> cloths;
    std::vector<Paper> papers;        ///< paper i gets seed + 1000 + i unless it gives its own
    std::vector<Driver> drivers;
    int output_every = 1;             ///< write a trace frame every this many steps, >= 1
    Camera camera;                    ///< for pictures; absent fields are fitted to the scene
    std::string source;               ///< file name or built-in scene name, for messages
};

/// Parses and checks a scene given as JSON text (with // comments allowed).
/// Throws InvalidInput with the JSON path of the first bad field.
Scene parseScene(const std::string& json_text);

/// Reads a file and parses it. Throws InvalidInput (bad content) or std::runtime_error (unreadable).
Scene loadSceneFile(const std::string& path);

/// The built-in scenes: (name, one-line description).
std::vector<std::pair<std::string, std::string>> builtinScenes();
/// The JSON text of a built-in scene, or nullopt.
std::optional<std::string> builtinSceneText(const std::string& name);

/// A rigid body as a frame callback sees it.
struct FrameBody {
    std::string name;
    Shape shape;
    Vec3 position = Vec3::Zero();        ///< m
    Quat orientation = Quat::Identity(); ///< body to world
};

/// A string as a frame callback sees it.
struct FrameString {
    std::string name;
    StringView view;             ///< positions, tension, broken, radius: valid during the callback only
    double rupture_stress = 0.0; ///< the material's tensile rupture stress, Pa (for colouring by load)
    double torsion_rupture = 0.0;///< the material's torsional rupture strain (for colouring by load; 0 = not coloured by twist)
};

/// A cloth as a frame callback sees it.
struct FrameCloth {
    std::string name;
    ClothView view;              ///< positions, edges, tension, broken: valid during the callback only
    double rupture_stress = 0.0; ///< the yarns' tensile rupture stress, Pa (for colouring by load)
};

/// A paper sheet as a frame callback sees it.
struct FramePaper {
    std::string name;
    PaperView view;              ///< positions, triangles, springs: valid during the callback only
};

/// The state of a run at a written frame (for pictures; see RunOptions::on_frame).
struct FrameState {
    long long step = 0;
    double time = 0.0;  ///< s
    std::vector<FrameString> strings;
    std::vector<FrameCloth> cloths;
    std::vector<FramePaper> papers;
    std::vector<FrameBody> bodies;  ///< including spawned ones, in creation order
};

/// How to run a scene.
/// What a run may take, as estimated from the scene before anything is built
/// (estimateResources). A scene past either limit is refused (InvalidInput naming the
/// field of the object that costs most: `strings[0].segments`, `cloths[1].resolution`).
struct ResourceLimits {
    double memory_bytes = 4e9;   ///< estimated peak memory, bytes, > 0 (`--max-memory`)
    double step_seconds = 10.0;  ///< estimated wall time of one step on one core, s, > 0 (`--max-step-seconds`)
};

/// A scene's estimated needs: totals, and the object field that costs most of each.
struct ResourceEstimate {
    double memory_bytes = 0.0;   ///< bytes, the whole run (the program's own included)
    double step_seconds = 0.0;   ///< s, one step on one core
    std::string memory_field;    ///< JSON path of the field behind the largest share of memory ("" for none)
    double memory_share = 0.0;   ///< bytes, that object's
    std::string step_field;      ///< JSON path of the field behind the largest share of a step's time
    double step_share = 0.0;     ///< s, that object's
};

/// The estimate: per string particle and per pair of segments within reach of each other
/// along the chain (a thick string of short segments: about 2 r / l per segment), per cloth
/// vertex (its yarns' least-squares tension solve grows as V^1.5) and per paper vertex.
/// The per-item costs are measured (docs/resource-limits.md).
ResourceEstimate estimateResources(const Scene& scene);

/// Throws InvalidInput naming the costliest field when the estimate passes a limit (or a
/// limit is not a positive finite number: "--max-memory", "--max-step-seconds").
void checkResources(const Scene& scene, const ResourceLimits& limits);

struct RunOptions {
    std::string out_dir;               ///< where trace.jsonl, events.jsonl, summary.json go; "" = write nothing
    std::optional<long long> steps;    ///< overrides Scene::steps
    std::optional<int> every;          ///< overrides Scene::output_every
    bool progress = false;             ///< draw a progress bar on stderr
    /// Called at step 0 and at every written frame (every `every` steps and the last), even
    /// when out_dir is "": the CLI renders pictures from it. An exception it throws ends the run.
    std::function<void(const FrameState&)> on_frame;
    ResourceLimits limits;             ///< checked before anything is built (checkResources)
};

/// How the islands' solves went over a run (see IslandSummary): one solve per island per
/// step; unconverged ones ended at their iteration cap with a move above tolerance.
struct IslandTotals {
    long long solves = 0;
    long long iterations = 0;   ///< Newton iterations, all solves
    int most_iterations = 0;    ///< of one solve
    long long unconverged = 0;  ///< solves whose residual stayed >= 1
};

/// What a run did.
struct RunResult {
    long long steps = 0;
    double simulated_seconds = 0.0;
    double wall_seconds = 0.0;                      ///< time spent stepping (not loading or writing)
    std::vector<std::pair<std::string, long long>> event_counts;  ///< by type, sorted by name
    std::string digest;                             ///< of the final state: equal for equal runs
    IslandTotals islands;
};

/// A scene run one step at a time: runScene drives one to the end; the viewer steps one as
/// it likes and reaches into its worlds to drag, cut and drop bodies.
class SceneRun {
public:
    /// Builds the Bullet world and the objects of `scene` (checks as runScene), opens the
    /// outputs in options.out_dir (none when "") and writes frame 0 (and calls on_frame).
    SceneRun(const Scene& scene, const RunOptions& options = {});
    ~SceneRun();
    SceneRun(const SceneRun&) = delete;
    SceneRun& operator=(const SceneRun&) = delete;

    /// One step: the drivers, Bullet's step (and the strings'), the events; a trace frame
    /// (and on_frame) every `every` steps and at steps(). Steps past steps() are allowed
    /// (the viewer plays on); they write no trace frame unless on the `every` grid.
    void advance();
    /// Steps taken; the run's planned length (RunOptions::steps, else Scene::steps); time, s.
    long long step() const;
    long long steps() const;
    double time() const;
    /// The state now (views valid until the next advance()).
    FrameState frame() const;
    /// The events of the last advance().
    const std::vector<Event>& lastEvents() const;
    /// Writes summary.json (with out_dir) and returns what the run did so far.
    RunResult finish();

    const Scene& scene() const;
    BulletWorld& ropes();
    btDiscreteDynamicsWorld& dynamicsWorld();
    /// The ids of the scene's strings, cloths and papers, by their index in the scene.
    StringId stringId(std::size_t index) const;
    ClothId clothId(std::size_t index) const;
    PaperId paperId(std::size_t index) const;
    /// The rigid bodies in creation order (the scene's, then spawned and added ones).
    std::size_t bodyCount() const;
    btRigidBody& body(std::size_t index);
    const Body& bodySpec(std::size_t index) const;
    /// Adds a rigid body now, as a spawn driver does. Throws InvalidInput("body.name") when
    /// the name is taken.
    btRigidBody& addBody(const Body& body);
    /// The scene's wind drivers act (true, the default) or not.
    void setSceneWind(bool on);
    bool sceneWind() const;
    /// A steady wind (m/s) on every string besides the scene's, as a wind driver without
    /// gusts; zero = none. Throws InvalidInput("wind") when not finite or over kMaxDriverSpeed.
    void setExtraWind(const Vec3& velocity);

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

/// Builds the Bullet world and the strings of `scene`, runs it and writes the outputs.
/// Throws InvalidInput (a field that cannot be honoured, e.g. a driver on a particle
/// that cannot be moved) before simulating, std::runtime_error for anything else.
RunResult runScene(const Scene& scene, const RunOptions& options);

}  // namespace tearables::scene
