// tearables: the core world. Knows nothing of Bullet: rigid bodies appear as RigidState
// proxies that a host (the Bullet plugin) fills before a step and reads back after it.
#pragma once

#include "tearables/cloth.hpp"
#include "tearables/events.hpp"
#include "tearables/paper.hpp"
#include "tearables/string.hpp"
#include "tearables/types.hpp"

#include <array>
#include <cstdint>
#include <memory>
#include <limits>
#include <vector>

namespace tearables {

namespace detail {
class ClothSystem;
struct WorldAccess;  // snapshots (src/world/snapshot.cpp) read and replace the whole state
}

/// World-wide solver settings.
struct WorldSettings {
    Vec3 gravity{0.0, -9.81, 0.0};  ///< m/s^2, finite
    /// Newton iterations of the strain-limit solves, 1..64; each stops when converged. The
    /// budget: a cloth's solve this many, a string's 2x (a taut rope takes 3-4), a string
    /// touching bodies or strings 4x.
    int strain_iterations = 8;
    /// Unused: strings sharing a dynamic body are solved together as one island (kept so
    /// that programs and snapshots setting it still work), 1..64.
    int coupling_iterations = 8;
    double strain_tolerance = 1e-6;  ///< relative stretch past L_max accepted, (0, 0.01]
    double max_speed = 500.0;        ///< particle speed clamp, m/s, > 0 (guards against blow-ups)
    /// Strings collide with rigid bodies (through the host's ContactProvider, the Bullet
    /// plugin's narrow phase). A string does not collide with a body it is glued to.
    bool rigid_contacts = true;
    /// Strings collide with each other and themselves (capsules per segment, found on the
    /// segments swept over the step by a box tree per string; the strings that touch are
    /// solved together, so they exchange momentum and never pass through each other). A
    /// string that hangs or swings nearly straight is proved free of self contacts from its
    /// shape in one pass over its particles; a curved one is searched (BENCHMARKS.md).
    /// Turn off for ropes that never meet.
    bool string_collisions = true;
    /// Strings that touch each other where one of them holds or touches a movable body are
    /// solved with that body's island, the bodies moving with the strings' contacts
    /// (momentum then passes between strings and bodies exactly; with it off the bodies are
    /// held still in the strings' joint solve, which leaks up to a few percent of a body's
    /// momentum where it presses a rope onto another). The island is solved a second time
    /// where such contacts exist (the `bridge` scene steps 1.1x slower), and a second solve
    /// that does not converge is undone: that step takes the held solve (docs/island-plan.md).
    bool island_string_contacts = true;
    /// Threads that step independent strings in parallel, 0..64: 1 steps on the calling
    /// thread only, 0 uses every core the machine reports. Where a stage has one string
    /// to step and it has 4096 particles or more (one long rope), the string's own work is
    /// split instead: its strain-limit solve in two halves (no glued particles, no rigid
    /// contacts), shape matching and tension in ranges. The collision tree of every string
    /// that long is built and searched in two halves. Results are bit-identical whatever
    /// the count (every split does the same operations in the same order; what strings
    /// share, the rigid bodies and the string-string joint solve, stays on the calling
    /// thread). Waiting workers spin for up to 0.2 ms before they sleep. Not part of
    /// snapshots.
    int threads = 1;
};

/// A rigid body as the core sees it: the host writes it before World::step and reads it
/// back after (position, orientation and velocities change where ropes pull it).
struct RigidState {
    Vec3 position = Vec3::Zero();        ///< centre of mass, m
    Quat orientation = Quat::Identity(); ///< body to world
    Vec3 linear_velocity = Vec3::Zero();   ///< m/s
    Vec3 angular_velocity = Vec3::Zero();  ///< rad/s, world frame
    double inverse_mass = 0.0;             ///< 1/kg; 0 = static or kinematic (moved by the host only)
    Mat3 inverse_inertia_local = Mat3::Zero();  ///< 1/(kg m^2), principal frame of the body
    bool awake = true;                     ///< a sleeping body is treated as immovable this step
    bool present = true;                   ///< false once the host has removed the body
    // Written by the core during a step:
    Vec3 impulse = Vec3::Zero();           ///< total linear impulse the strings applied this step, N s

    /// World-frame inverse inertia.
    Mat3 inverseInertiaWorld() const {
        const Mat3 r = orientation.toRotationMatrix();
        return r * inverse_inertia_local * r.transpose();
    }
};

/// A contact between a string segment and a rigid body, found by the host's narrow phase
/// (the Bullet plugin) during the collision stage of a step.
struct RigidContact {
    StringId string;               ///< the string
    std::uint32_t segment = 0;     ///< its segment
    double s = 0.0;                ///< fraction along the segment, [0, 1]
    Vec3 normal = Vec3::UnitY();   ///< unit, from the body toward the string
    Vec3 point = Vec3::Zero();     ///< on the body's surface, world, m
    RigidId body;                  ///< the body's proxy (inverse mass 0 = static)
    double friction = 0.5;         ///< Coulomb coefficient, >= 0
    /// The body's surface here is a sphere about its centre (a ball): as the body turns,
    /// its surface under the string stays where it is and only its material rolls past,
    /// so the contact plane keeps its direction. Otherwise the plane is fixed in the body
    /// and turns with it (a box's face).
    bool spherical = false;
};

/// A contact between two rigid bodies that the host hands to the island solve (the
/// Bullet plugin: the contact manifolds of the bodies it takes over from Bullet's solver).
/// Islands then keep such bodies apart together with the strings that hold them, exactly
/// non-penetrating with Coulomb friction, instead of the host's solver and the strings'
/// undoing each other. The gap is normal . (point_a - point_b), negative where they overlap.
struct BodyContact {
    RigidId a;                     ///< a movable body's proxy
    RigidId b;                     ///< the other body's proxy, or none: a surface the host alone moves
    Vec3 point_a = Vec3::Zero();   ///< world, m: a's nearest point, at the poses in the table
    Vec3 point_b = Vec3::Zero();   ///< world, m: b's nearest point
    Vec3 normal = Vec3::UnitY();   ///< unit, from b toward a
    /// m: how far a's point has moved relative to b's since the start of the step (the
    /// bodies' free motion so far): friction acts on the whole step's slip.
    Vec3 motion = Vec3::Zero();
    /// m, >= 0: how far a reached into b at the start of the step. An overlap the solve did
    /// not make is pushed out over several steps (a fraction a step), not in one.
    double depth = 0.0;
    double friction = 0.5;         ///< Coulomb coefficient, >= 0
    /// N: in, the normal force of the last step (friction acts from the first pass); out
    /// (World::lastBodyContacts), the force the solve found.
    double force = 0.0;
    std::size_t host_tag = 0;      ///< the host's own name for the contact, returned unchanged
};

/// A joint between two bodies, or between a body and a frame fixed in the world, that the
/// host hands to the island solve (ContactProvider::findBodyJoints) instead of solving it
/// itself: the body or bodies then move in one system with the strings that hold them
/// and the contacts they touch. A ball joint keeps the two pivots together; a hinge also
/// keeps the two axes parallel, free to turn about them within its limits; a frame joint
/// (a slider, a 6-dof joint, a weld, a cone-twist joint) holds each of six coordinates of
/// b's frame relative to a's, locked, limited or free; a gear ties the bodies' turn rates
/// about two axes, axis_a . omega_a + axis_b . omega_b = 0 (btGearConstraint: axis_b is b's
/// axis times the gear's ratio).
struct BodyJoint {
    enum class Kind { Ball, Hinge, Frame, Gear };
    Kind kind = Kind::Ball;
    RigidId a;                     ///< a movable body's proxy
    RigidId b;                     ///< the other body's proxy, or none: a frame only the host moves
    Vec3 pivot_a = Vec3::Zero();   ///< world, m: the joint's point on a, at the poses in the table
    Vec3 pivot_b = Vec3::Zero();   ///< world, m: its point on b (or the fixed frame)
    Vec3 axis_a = Vec3::UnitZ();   ///< world, unit: a hinge's axis on a (a gear's: any length)
    Vec3 axis_b = Vec3::UnitZ();   ///< world, unit: on b (a gear's: any length)
    /// A hinge's angle now, rad, in the host's convention, which turns by
    /// angle_sign * axis_a . (theta_a - theta_b) for small turns theta of the bodies; and its
    /// limits (lower <= angle <= upper; infinite: none).
    double angle = 0.0;
    double angle_sign = 1.0;
    double lower = -std::numeric_limits<double>::infinity();
    double upper = std::numeric_limits<double>::infinity();
    /// A hinge's motor: it drives the bodies' relative turn rate about the axis,
    /// (omega_a - omega_b) . axis_a, toward motor_velocity (rad/s) with an impulse of at
    /// most motor_impulse (N m s) a step, as btHingeConstraint's angular motor does.
    bool motor = false;
    double motor_velocity = 0.0;
    double motor_impulse = 0.0;
    /// A frame joint's coordinates: the linear ones, basis_a^T (pivot_b - pivot_a), where
    /// b's pivot is along the axes of a's frame (basis_a: its columns, unit, orthogonal,
    /// world); the angular ones, `angles` (rad, the host's convention: Euler angles of b's
    /// frame relative to a's, an angle about an axis), which turn by
    /// angle_rates (theta_a - theta_b) for small turns theta of the bodies. Each coordinate
    /// is locked at lower == upper, limited within lower < upper (an infinite bound: none on
    /// that side) or free (both infinite). The defaults lock all six: a weld. basis_a,
    /// angles, angle_rates and the bounds stay the host's when the solve turns the joint
    /// round (`swapped`): they describe the host's b relative to the host's a.
    Mat3 basis_a = Mat3::Identity();
    Vec3 angles = Vec3::Zero();
    Mat3 angle_rates = Mat3::Identity();
    Vec3 linear_lower = Vec3::Zero(), linear_upper = Vec3::Zero();    ///< m
    Vec3 angular_lower = Vec3::Zero(), angular_upper = Vec3::Zero();  ///< rad
    /// A frame joint's motors, per coordinate (linear x, y, z, then the angles): each drives
    /// its coordinate's rate to drive_velocity (m/s, rad/s) with at most drive_force (N,
    /// N m; 0: no motor), giving way beyond it as a hinge's motor does; not on a locked
    /// coordinate.
    std::array<double, 6> drive_velocity{}, drive_force{};
    /// A frame joint's servos, per coordinate: its motor (drive_velocity a speed, m/s or
    /// rad/s, its sign ignored; drive_force) drives the coordinate toward servo_target (m,
    /// rad; an angle's error taken within +-pi) and holds it there, at no more than the
    /// speed that reaches it within the step, as btGeneric6DofSpring2Constraint's servo does.
    std::array<bool, 6> servo{};
    std::array<double, 6> servo_target{};
    /// A frame joint's springs, per coordinate q (not a locked one): a force (N, N m) on q of
    /// -spring_stiffness (q - spring_rest) - spring_damping dq/dt (N/m or N m/rad; N s/m or
    /// N m s/rad), the elastic part read where the step starts and held over it, as
    /// btGeneric6DofSpring2Constraint applies its springs (stable where Bullet's solver
    /// is: sqrt(k / m) h < 2), the damping at the rate the step ends with; 0 stiffness and
    /// damping: none.
    std::array<double, 6> spring_stiffness{}, spring_damping{}, spring_rest{};
    std::size_t host_tag = 0;      ///< the host's own name for the joint, returned unchanged
    // Out (World::lastBodyJoints), world frame: what the joint gave each body over the step,
    // as impulses (its force times h): linear, N s, and angular about the body's centre of
    // mass, N m s (the pivot's lever arm, a hinge's alignment and its limits). Zero for a
    // fixed frame's side (its reaction is the other's, opposite, at its own pivot), and
    // for a joint whose bodies no island solved.
    Vec3 impulse_a = Vec3::Zero(), angular_impulse_a = Vec3::Zero();
    Vec3 impulse_b = Vec3::Zero(), angular_impulse_b = Vec3::Zero();
    /// The island solve turned the joint round (its a was the host's b: a fixed frame's
    /// joint is always held by a movable a); a and b, and the impulses, are as solved.
    bool swapped = false;
};

/// Positions a host's collision query sees: every live string's particles after the
/// prediction (where they would go), and where they were at the start of the step.
struct CollisionQuery {
    std::vector<StringId> strings;                 ///< live, unfrozen strings
    std::vector<const std::vector<Vec3>*> start;   ///< per string, positions at the step start
    std::vector<const std::vector<Vec3>*> predicted; ///< per string, predicted positions
    std::vector<const std::vector<double>*> radius;  ///< per string, per segment radius
    std::vector<const std::vector<std::uint8_t>*> broken;  ///< per string, per segment
    /// (string, body) for each movable body a string is glued to, ordered by string: the
    /// string does not collide with it (the glue couples them), so a host need not look.
    std::vector<std::pair<StringId, RigidId>> glued;
};

/// One island of the last step: strings coupled through the movable bodies they hold or
/// touch, solved as one system with those bodies (see README, "How it works"). The solve
/// converged where `residual` < 1: its last Newton iteration moved nothing by more than
/// WorldSettings::strain_tolerance of a segment.
struct IslandSummary {
    std::size_t strings = 0;
    std::size_t bodies = 0;
    int iterations = 0;     ///< Newton iterations, all friction passes
    double residual = 0.0;  ///< the last iteration's largest move over its tolerance
};

/// Vertices of meshes (paper sheets, cloths) for a host's collision query: each object's
/// vertices are spheres of the object's radius (its half thickness), swept from where they
/// were at the start of the step to where they are predicted to go.
///
/// An object that gives its triangles (paper sheets) is also a surface of that thickness:
/// a body may touch it inside a triangle, between the vertices (a small ball, a box's edge).
struct PointQuery {
    std::vector<const std::vector<Vec3>*> start;      ///< per object, vertex positions at the step start
    std::vector<const std::vector<Vec3>*> predicted;  ///< per object, predicted vertex positions
    std::vector<double> radius;                       ///< per object, m, > 0
    /// Per object, its triangles (vertex indices), or null: vertices only. May be shorter
    /// than `start` (missing entries are null).
    std::vector<const std::vector<std::array<std::uint32_t, 3>>*> triangles;
};

/// A mesh vertex, or a point inside a triangle, touching a rigid body (the answer to a
/// PointQuery).
struct PointContact {
    std::uint32_t object = 0;      ///< index into the PointQuery's arrays
    std::uint32_t vertex = 0;      ///< the vertex (a face contact: face[0])
    Vec3 normal = Vec3::UnitY();   ///< unit, from the body toward the vertex
    Vec3 point = Vec3::Zero();     ///< on the body's surface, world, m (where the body is now)
    RigidId body;                  ///< the body's proxy (inverse mass 0 = static)
    double friction = 0.5;         ///< Coulomb coefficient, >= 0
    /// A face contact: the touching point of the surface is sum_k weights[k] x[face[k]]
    /// (barycentric weights, >= 0, summing to 1). All zero for a vertex contact.
    std::array<std::uint32_t, 3> face{};
    Vec3 weights = Vec3::Zero();
    bool onFace() const { return weights.squaredNorm() > 0.0; }
};

/// Finds contacts of strings and of mesh objects (cloths, sheets) with rigid bodies;
/// implemented by the host (the Bullet plugin uses Bullet's broadphase and narrow phase).
/// In a step, findContacts is called once (the strings), findPointContacts once for the
/// live cloths and once for the live sheets.
class ContactProvider {
public:
    virtual ~ContactProvider() = default;
    /// Appends the contacts of the swept segments with rigid bodies to `out`.
    virtual void findContacts(const CollisionQuery& query, std::vector<RigidContact>& out) = 0;
    /// Appends the contacts of the swept mesh vertices with rigid bodies to `out`
    /// (speculative: a vertex within its radius plus its travel of a body is reported).
    /// A host without mesh collision reports none.
    virtual void findPointContacts(const PointQuery& query, std::vector<PointContact>& out) {
        (void)query;
        (void)out;
    }
    /// Appends the contacts between rigid bodies that the island solve is to keep (the
    /// bodies' poses are those of the table when the step starts). A host that solves its
    /// bodies' contacts itself reports none.
    virtual void findBodyContacts(std::vector<BodyContact>& out) { (void)out; }
    /// Appends the joints between bodies that the island solve is to keep (at the poses of
    /// the table when the step starts). A host that solves its joints itself reports none.
    virtual void findBodyJoints(std::vector<BodyJoint>& out) { (void)out; }
};

/// Read-only view of a string's state, valid until the next step or change.
struct StringView {
    const std::vector<Vec3>* positions = nullptr;     ///< per particle, m
    const std::vector<Vec3>* velocities = nullptr;    ///< per particle, m/s
    const std::vector<double>* masses = nullptr;      ///< per particle, kg
    const std::vector<double>* tension = nullptr;     ///< per segment, N (0 where broken)
    const std::vector<double>* twist = nullptr;       ///< per segment, rad
    const std::vector<double>* rest_length = nullptr; ///< per segment, m
    const std::vector<double>* max_length = nullptr;  ///< per segment strain limit L_max, m
    const std::vector<std::uint8_t>* broken = nullptr;///< per segment, 1 = torn
    double radius = 0.0;                              ///< m
    bool frozen = false;                              ///< stopped after a non-finite state
    /// Newton iterations of the last step's strain-limit solve (its own or its island's),
    /// all friction passes: what the step cost it.
    int newton_iterations = 0;
    std::size_t particleCount() const { return positions->size(); }
    std::size_t segmentCount() const { return rest_length->size(); }
};

/// Per-stage wall time of the last step and accumulated over all steps, seconds.
struct StageTimes {
    double predict = 0, shape_matching = 0, twist = 0, collision = 0, strain_limit = 0,
           tension = 0, material = 0, velocities = 0;
    double total() const {
        return predict + shape_matching + twist + collision + strain_limit + tension + material +
               velocities;
    }
    StageTimes& operator+=(const StageTimes& o);
};

/// The core simulation: strings, cloths and paper sheets coupled to the host's rigid
/// bodies. A step runs on the calling thread and on WorldSettings::threads workers;
/// deterministic for equal inputs, whatever the thread count.
class World {
public:
    explicit World(const WorldSettings& settings = {});
    ~World();
    World(const World&) = delete;
    World& operator=(const World&) = delete;

    /// Validates and creates a string. Throws InvalidInput naming the field; nothing is created then.
    StringId addString(const StringDesc& desc);
    /// Removes a string; its id becomes invalid.
    void removeString(StringId id);
    /// Strings that exist, in creation order.
    std::vector<StringId> strings() const;
    /// Bounds (lower, upper corner) of every live mesh object (paper sheet, cloth), grown
    /// by its radius and by what it can travel in a step of `h`: the host prepares the
    /// candidate bodies of the step's PointQuery from them.
    std::vector<std::pair<Vec3, Vec3>> meshBounds(double h) const;
    /// True when `id` names a string of this world.
    bool contains(StringId id) const;

    /// Pins a particle to a world point (m). A negative particle index counts from the end.
    void attachToPoint(StringId id, int particle, const Vec3& point);
    /// Glues a particle to a rigid body at a point given in the body's frame (m).
    void attachToRigid(StringId id, int particle, RigidId body, const Vec3& local_point);
    /// Moves a particle's world pin (kinematic driving); throws if it is not pinned to a point.
    void movePin(StringId id, int particle, const Vec3& point);
    /// Removes whatever holds the particle (a Release event is emitted); no-op when free.
    void detach(StringId id, int particle);
    /// Cuts a segment (negative counts from the end) as a tear would: it is broken from now
    /// on, its tension 0, and a Tear event (cause Request) is reported with the next step.
    /// Returns false and changes nothing when it is already broken. Throws InvalidInput
    /// ("string", "segment") for an unknown string or a segment out of range.
    bool cutSegment(StringId id, int segment);
    /// True when the particle is pinned or glued.
    bool isAttached(StringId id, int particle) const;
    /// The world pin of a particle, if it has one.
    bool pinTarget(StringId id, int particle, Vec3* point) const;

    /// Turns a clamped (pinned) end of a string about its segment's axis by `angle` rad
    /// (end 0 = first, -1 = last); the end then holds the angle reached.
    void turnEnd(StringId id, int end, double angle);
    /// The angle a clamped end holds, rad.
    double endTwist(StringId id, int end) const;

    /// Adds a force (N) on a particle for the next step only (cleared after it).
    void applyForce(StringId id, int particle, const Vec3& force);

    /// Registers a rigid body proxy; the host keeps it up to date. Throws InvalidInput
    /// ("body.position", "body.orientation", ...) for a non-finite state, a non-unit
    /// orientation or a negative inverse mass.
    RigidId addRigid(const RigidState& state);
    /// The proxy for the host to write before and read after a step.
    RigidState& rigid(RigidId id);
    const RigidState& rigid(RigidId id) const;
    /// Drops the proxy and every attachment to it (Release events with cause BodyRemoved).
    void removeRigid(RigidId id);
    /// True when some string, cloth or sheet is glued to this body.
    bool rigidInUse(RigidId id) const;
    /// The host's contact generation (nullptr: nothing collides with rigid bodies).
    /// The provider must outlive the world or be reset first.
    void setContactProvider(ContactProvider* provider);
    /// The host's string contacts of the last step as it reported them, for inspection and tests.
    const std::vector<RigidContact>& lastContacts() const;
    /// The islands of the last step, in the order of their first string (none where no
    /// string holds or touches a movable body).
    const std::vector<IslandSummary>& lastIslands() const;
    /// The host's body-body contacts of the last step (findBodyContacts), with the normal
    /// force each carried (`force`, N); those between bodies outside every island carry 0.
    const std::vector<BodyContact>& lastBodyContacts() const;
    /// The host's joints of the last step (findBodyJoints) that the island solve kept, with
    /// the impulses each gave its bodies (BodyJoint::impulse_a, ...).
    const std::vector<BodyJoint>& lastBodyJoints() const;

    /// Advances all strings, cloths and paper sheets by `h` seconds, [1e-7, 1]. Throws
    /// InvalidInput ("h", or the name of a setting made invalid through settings()) before
    /// changing anything; otherwise never throws: an object that goes non-finite is frozen
    /// with a Freeze event.
    void step(double h);

    /// Read-only state of a string.
    StringView view(StringId id) const;
    /// The descriptor a string was created from.
    const StringDesc& desc(StringId id) const;
    /// Events of the last step, in order.
    const std::vector<Event>& events() const;
    /// Wall time of the last step's stages, s: the strings' and the cloths' (the sheets'
    /// are in lastPaperTimes()).
    const StageTimes& lastStageTimes() const;
    /// Simulated time, s, and steps taken.
    double time() const;
    std::int64_t stepCount() const;

    WorldSettings& settings();
    const WorldSettings& settings() const;

    /// Resolves a particle index (negative counts from the end); throws InvalidInput("particle").
    int resolveParticle(StringId id, int particle) const;

    // --- cloths (cloth.hpp; src/cloth/) ----------------------------------------------------
    /// Validates and creates a cloth, its attachments held from the start (a glued vertex
    /// placed at its body's point). Throws InvalidInput naming the field (attachments[k].body:
    /// no such rigid body); nothing is created then.
    ClothId addCloth(const ClothDesc& desc);
    /// Removes a cloth; its id becomes invalid.
    void removeCloth(ClothId id);
    /// Cloths that exist, in slot order.
    std::vector<ClothId> cloths() const;
    /// True when `id` names a cloth of this world.
    bool contains(ClothId id) const;
    /// Read-only state of a cloth.
    ClothView viewCloth(ClothId id) const;
    /// The descriptor a cloth was created from.
    const ClothDesc& clothDesc(ClothId id) const;
    /// Pins a vertex (flat index, negative counts from the end) to a world point (m).
    void attachClothToPoint(ClothId id, int vertex, const Vec3& point);
    /// Glues a vertex to a rigid body at a point in the body's frame (m); two-way.
    void attachClothToRigid(ClothId id, int vertex, RigidId body, const Vec3& local_point);
    /// Moves a vertex's world pin (kinematic driving); throws if it is not pinned to a point.
    void moveClothPin(ClothId id, int vertex, const Vec3& point);
    /// Frees a vertex (a Release event is emitted); no-op when free.
    void detachCloth(ClothId id, int vertex);
    /// Adds a force (N) on a vertex for the next step only.
    void applyClothForce(ClothId id, int vertex, const Vec3& force);
    // --- paper sheets (paper.hpp; stepped after the strings, in src/paper/) ---
    /// Validates and creates a sheet. Throws InvalidInput naming the field; nothing is created then.
    PaperId addPaper(const PaperDesc& desc);
    /// Removes a sheet; its id becomes invalid.
    void removePaper(PaperId id);
    /// Sheets that exist, in slot order.
    std::vector<PaperId> papers() const;
    /// True when `id` names a sheet of this world.
    bool contains(PaperId id) const;
    /// Read-only state of a sheet (vertices, triangles, springs, damage counters).
    PaperView viewPaper(PaperId id) const;
    /// The descriptor a sheet was created from.
    const PaperDesc& paperDesc(PaperId id) const;
    /// Pins a vertex (flat index, negative counts from the end, as a cloth's) to a world point (m).
    void attachPaperToPoint(PaperId id, int vertex, const Vec3& point);
    /// Glues a vertex to a rigid body at a point in the body's frame (m); two-way.
    void attachPaperToRigid(PaperId id, int vertex, RigidId body, const Vec3& local_point);
    /// Moves a vertex's world pin (kinematic driving); throws if it is not pinned.
    void movePaperPin(PaperId id, int vertex, const Vec3& point);
    /// Frees a vertex (a Release event is emitted); no-op when free.
    void detachPaper(PaperId id, int vertex);
    /// Adds a force (N) on a vertex for the next step only.
    void applyPaperForce(PaperId id, int vertex, const Vec3& force);
    /// A sheet's vertex index, negative counting from the end, as an index in [0, count).
    /// Throws InvalidInput ("paper", "vertex").
    std::uint32_t paperVertex(PaperId id, int vertex) const;
    /// Wall time of the sheets' stages in the last step.
    const PaperTimes& lastPaperTimes() const;

private:
    detail::ClothSystem& clothSystem();
    const detail::ClothSystem& clothSystem() const;
    std::vector<Event>& pendingEvents();

    struct Impl;
    std::unique_ptr<Impl> impl_;
    friend struct detail::WorldAccess;
};

/// Throws InvalidInput naming the field when `settings` is not valid.
void validate(const WorldSettings& settings);

}  // namespace tearables
