// tearables: the Bullet plugin. Attach a tearables world to your btDiscreteDynamicsWorld;
// it then steps inside stepSimulation, at Bullet's fixed internal time step, after Bullet
// has integrated the rigid bodies (a btActionInterface).
//
//   btDiscreteDynamicsWorld world(...);
//   tearables::BulletWorld ropes(world);
//   // 1.2 m of nylon rope hanging between two points 1 m apart (the catenary, at rest)
//   auto rope = ropes.addRope(btVector3(0, 2, 0), btVector3(1, 2, 0), 1.2, 40, "nylon_rope");
//   ropes.attach(rope, 0, btVector3(0, 2, 0));          // pinned in the world
//   ropes.attach(rope, -1, *crate, btVector3(0, 0.2f, 0)); // glued to a body, two-way
//   world.stepSimulation(1.0f / 60.0f);
//   double top = ropes.tensions(rope).front();           // newtons
//   std::vector<btVector3> x = ropes.positions(rope);     // m
//
// This header includes no Eigen and none of the core's headers: the descriptors
// (StringDesc, ClothDesc, PaperDesc) and the core World are declared only. A program that
// fills a descriptor includes its header (tearables/string.hpp, cloth.hpp, paper.hpp); one
// that works on the core (ropes.core(), Eigen vectors) includes tearables/bullet_core.hpp.
//
// Sub-steps: stepSimulation(dt, maxSubSteps, fixedTimeStep) takes n internal steps. As with
// Bullet's own bodies, applyForce() acts on every one of them (then is cleared), movePin()
// is reached at the end of the last one (followed linearly), a kinematic body a string is
// glued to moves by its velocity on each, and peakTension()/events() keep what every
// internal step saw until the user clears them.
//
// Threads: a BulletWorld (and its core World) is used from one thread at a time, the one
// that steps the Bullet world; WorldSettings::threads only sets the workers its own step
// uses inside, and the tear and contact callbacks run on the stepping thread. Separate
// worlds may be stepped on separate threads.
//
// Ray tests: every string is also a btCollisionObject of the Bullet world (a compound of
// one capsule per intact segment, following the particles), so world.rayTest hits ropes as
// it hits bodies; ropeHit() names the rope and segment hit. It makes no Bullet contact
// (setRopesRayTestable turns it off).
//
// Lifetime: destroying the BulletWorld detaches it from Bullet (its collision objects
// leave the world); destroying the Bullet world first is safe too (the plugin notices and
// never touches it again). A body that strings are glued to may be removed from the Bullet
// world at any time: at the next step its attachments are dropped with Release events
// (cause body_removed). Before you *delete* such a body, remove it from the world and
// step, or call forgetBody().
#pragma once

#include "tearables/events.hpp"
#include "tearables/ids.hpp"

#include "tearables/bullet_precision.hpp"

#include <LinearMath/btScalar.h>
#include <LinearMath/btVector3.h>

#include <array>
#include <cstddef>
#include <functional>
#include <iosfwd>
#include <memory>
#include <optional>
#include <string>
#include <vector>

class btCollisionObject;
class btDiscreteDynamicsWorld;
class btIDebugDraw;
class btRigidBody;

// Bullet's single and double builds have different symbols (btCapsuleShape(float, float) or
// (double, double)): the application must use the precision the plugin was built with.
static_assert(sizeof(btScalar) == (TEARABLES_BULLET_DOUBLE ? sizeof(double) : sizeof(float)),
              "tearables' Bullet plugin was built against Bullet in the other precision: define (or not) "
              "BT_USE_DOUBLE_PRECISION as it was, or rebuild tearables with -DTEARABLES_BULLET_DOUBLE=ON/OFF");

namespace tearables {

// Declared here, defined in the core's headers: include tearables/string.hpp (cloth.hpp,
// paper.hpp) to fill a descriptor, tearables/bullet_core.hpp to use the core World.
struct StringDesc;
struct ClothDesc;
struct PaperDesc;
struct WorldSettings;
struct StageTimes;
class World;

/// A string's contact with a Bullet body in the last internal step (what a btManifoldPoint
/// gives for two bodies), with the force the step's solve put through it.
struct BulletContact {
    btRigidBody* body = nullptr;  ///< the body touched (static, kinematic or dynamic)
    StringId string;              ///< the string
    int segment = 0;              ///< its segment
    double s = 0.0;               ///< fraction along the segment, [0, 1] (0 = its first particle)
    btVector3 position{0, 0, 0};  ///< world, m: the string's surface point facing the body
    btVector3 normal{0, 1, 0};    ///< unit, from the body toward the string (Bullet's normalWorldOnB, B the body)
    double normal_force = 0.0;    ///< N, > 0: the push along the normal
    btVector3 force{0, 0, 0};     ///< N: the whole force on the body (push and friction) = -(force on the string)
    btVector3 impulse{0, 0, 0};   ///< N s: `force` times the internal step
};

/// An event as a Bullet user reads it: the core's Event (type, cause, string, segment,
/// stress, time, step) and where and on what it happened.
struct BulletEvent : Event {
    /// World, m: the middle of a string's torn or yielded segment, a released particle;
    /// (0, 0, 0) for cloth and sheet events.
    btVector3 position{0, 0, 0};
    /// N: for a string's tear or yield by tension, the load (stress over the original
    /// section, pi r^2; a tear's is at or above the rupture load); else 0.
    double force = 0.0;
    /// A string's tear: the body the torn segment touched in that internal step (the one
    /// it pressed hardest), else the body its piece hung from (the glued particle nearest
    /// the segment, along the intact segments on either side). An overlap: the body the
    /// string was made inside. Else null.
    btRigidBody* body = nullptr;
    /// A yield: how many segments of the string first yielded in that internal step. They
    /// are one event; its segment, stress, position and force are the worst one's.
    int count = 1;
};

/// A cloth's intact yarn edge, for drawing: its vertices and the tension it carries.
struct BulletYarn {
    int a = 0;             ///< first vertex (flat index j * resolution[0] + i)
    int b = 0;             ///< second vertex: (i + 1, j) for a warp yarn, (i, j + 1) for a weft yarn
    int edge = 0;          ///< the edge's index (a Tear event's `segment`)
    double tension = 0.0;  ///< N, of the last internal step (least squares: may be slightly negative)
};

/// What a Bullet query (world.rayTest, convexSweepTest, contactTest) met on a rope: the
/// string and its segment (BulletWorld::ropeHit).
struct RopeHit {
    StringId string;   ///< the rope
    int segment = -1;  ///< its segment: the capsule from particle `segment` to `segment` + 1
};

/// A tearables world living inside a Bullet dynamics world.
class BulletWorld {
public:
    /// Attaches to `world` with the default WorldSettings; strings use the world's gravity
    /// at every step.
    explicit BulletWorld(btDiscreteDynamicsWorld& world);
    /// The same with the core's settings (tearables/world.hpp: iterations, tolerances,
    /// threads; its gravity is replaced by the Bullet world's at every step).
    BulletWorld(btDiscreteDynamicsWorld& world, const WorldSettings& settings);
    /// Detaches from Bullet (if the Bullet world still exists).
    ~BulletWorld();
    BulletWorld(const BulletWorld&) = delete;
    BulletWorld& operator=(const BulletWorld&) = delete;

    /// The core world, for power users (include tearables/bullet_core.hpp): its views
    /// (Eigen vectors), settings, cloths' and sheets' state, islands, raw contacts. The
    /// everyday calls below cover strings without it. After the Bullet world was destroyed,
    /// the first call drops every body the plugin knew (their attachments are released at
    /// the core's next step); stepping the core then touches nothing of Bullet.
    World& core();
    const World& core() const;

    // --- building ropes -----------------------------------------------------------------
    /// A string of `length` (m) from `a` to `b` in `segments` segments, hanging as a uniform
    /// rope does under gravity along -y (StringDesc::between: the catenary through a and b,
    /// particles at equal arc lengths; straight when `length` is |b - a|). The descriptor's
    /// other fields are its defaults: set them before addString (needs tearables/string.hpp).
    /// Throws InvalidInput ("a", "b", "length", "segments") as StringDesc::between.
    static StringDesc ropeBetween(const btVector3& a, const btVector3& b, double length, int segments);
    /// Creates ropeBetween(a, b, length, segments) made of the material preset `preset`
    /// (presets.hpp: "thread", "rubber_cord", "nylon_rope", "braided_rope", "spaghetti",
    /// "steel_wire", "fishing_line") at the preset's radius and density, with Bullet's default
    /// collision filter. Its ends are free: pin or glue them with attach(). Throws
    /// InvalidInput ("a", "b", "length", "segments"; "preset": unknown name) and creates
    /// nothing then.
    StringId addRope(const btVector3& a, const btVector3& b, double length, int segments,
                     const std::string& preset = "nylon_rope");

    /// Validates and creates a string (throws InvalidInput naming the field), with Bullet's
    /// default collision filter (group btBroadphaseProxy::DefaultFilter, mask AllFilter).
    StringId addString(const StringDesc& desc);
    /// The same with a collision filter, as btDiscreteDynamicsWorld::addSoftBody(body, group,
    /// mask): the string touches a body only when (group & the body's mask) and (the body's
    /// group & mask) are both non-zero (Bullet's needsCollision rule, on the body's broadphase
    /// proxy). Bodies it is glued to hold it whatever the filter.
    StringId addString(const StringDesc& desc, int group, int mask);
    /// Removes a string; its id becomes stale: every call given it afterwards throws
    /// InvalidInput("string", "stale id: ...") and changes nothing, also once the slot holds
    /// a new string (ids carry the slot's generation).
    void removeString(StringId id);
    /// Pins a particle (negative index counts from the end) to a world point.
    void attach(StringId id, int particle, const btVector3& world_point);
    /// Glues a particle to a rigid body at a point in the body's frame (relative to its
    /// centre of mass). The body must be in this Bullet world. Two-way: the string holds
    /// the body with the body's mass and inertia, and the body pulls the string.
    void attach(StringId id, int particle, btRigidBody& body, const btVector3& local_point);
    /// Frees a particle (a Release event is reported).
    void detach(StringId id, int particle);
    /// Sets the particles' velocities, m/s: one for all or one per particle; held particles
    /// keep moving with what holds them (tearables::setVelocities, controls.hpp). Throws
    /// InvalidInput ("string", "velocities", "velocities[i]") and changes nothing then.
    void setVelocities(StringId id, const std::vector<btVector3>& velocities);
    /// A winch at a pinned end (0 or -1): from the next internal step on, every internal
    /// step of h takes in (`speed` < 0) or pays out (`speed` > 0) |speed| h of rope
    /// (tearables::reel, controls.hpp), until reel(id, end, 0) or the end is unpinned.
    /// Throws InvalidInput ("string"; "end": not 0 or -1, or not pinned; "speed": not
    /// finite or over 1000 m/s; "mode") and changes nothing then.
    void reel(StringId id, int end, double speed, RestMass mode = RestMass::Conserve);
    /// Validates and creates a cloth (throws InvalidInput naming the field). Cloths collide
    /// with the Bullet bodies near them (spheres of the yarn radius at the vertices).
    ClothId addCloth(const ClothDesc& desc);
    /// The same with a collision filter (as addString(desc, group, mask)).
    ClothId addCloth(const ClothDesc& desc, int group, int mask);
    /// Removes a cloth; its id becomes stale (as removeString).
    void removeCloth(ClothId id);
    /// Pins a cloth vertex (flat index j * resolution[0] + i; negative counts from the end) to a world point.
    void attachCloth(ClothId id, int vertex, const btVector3& world_point);
    /// Glues a cloth vertex to a rigid body at a point in the body's frame; two-way.
    void attachCloth(ClothId id, int vertex, btRigidBody& body, const btVector3& local_point);
    /// The id that names `body` in a descriptor's attachments (ClothDesc::attachments,
    /// PaperDesc::attachments: SheetAttachment::body), so that a cloth or sheet is glued to it
    /// at creation, two-way, as attachCloth()/attachPaper() glue a vertex later. The same id
    /// while the body stays in this Bullet world, until forgetBody() or loadSnapshot(). Throws
    /// InvalidInput("body") when the body is not in the Bullet world.
    RigidId bodyId(btRigidBody& body);
    /// Drops every attachment to `body` now (call before deleting a body strings hold).
    void forgetBody(const btRigidBody& body);

    /// A pointer of the user's (a game object, an entity) kept with a string, cloth or
    /// sheet, as btCollisionObject::setUserPointer: null until set, never dereferenced by
    /// the plugin, dropped when the object is removed. A tear makes no new object (a torn
    /// rope stays one StringId, its pieces the runs of intact segments between the broken
    /// ones; a torn cloth or sheet stays one id), so every piece keeps the pointer. Not part
    /// of snapshots: loadSnapshot leaves the pointers as they were. Throws
    /// InvalidInput("string"/"cloth"/"paper") for an unknown or stale id; nothing changes then.
    void setUserPointer(StringId id, void* user);
    void setUserPointer(ClothId id, void* user);
    void setUserPointer(PaperId id, void* user);
    /// The pointer set with setUserPointer (null if none). Throws as setUserPointer.
    void* userPointer(StringId id) const;
    void* userPointer(ClothId id) const;
    void* userPointer(PaperId id) const;

    /// Validates and creates a paper sheet (throws InvalidInput naming the field). Its
    /// vertices collide with the world's rigid bodies, two ways.
    PaperId addPaper(const PaperDesc& desc);
    /// The same with a collision filter (as addString(desc, group, mask)).
    PaperId addPaper(const PaperDesc& desc, int group, int mask);
    /// Removes a sheet; its id becomes stale.
    void removePaper(PaperId id);
    /// Pins a vertex of a sheet (flat index, negative counts from the end) to a world point.
    void attachPaper(PaperId id, int vertex, const btVector3& world_point);
    /// Glues a vertex of a sheet to a rigid body at a point in the body's frame (relative
    /// to its centre of mass); the body must be in this Bullet world. Two-way.
    void attachPaper(PaperId id, int vertex, btRigidBody& body, const btVector3& local_point);

    /// Adds a force (N) on a particle for every internal step of the next stepSimulation
    /// that steps, then clears it, as btRigidBody::applyCentralForce and clearForces do: a
    /// force given once a frame gives the impulse F dt_frame whatever the sub-step count.
    /// (A stepSimulation that takes no internal step keeps it for the next.) Throws
    /// InvalidInput ("string", "particle", "force") and changes nothing on bad input.
    void applyForce(StringId id, int particle, const btVector3& force);
    /// As applyForce, on a cloth's or a sheet's vertex (flat index, negative counts from the
    /// end). Throws InvalidInput ("cloth"/"paper", "vertex", "force").
    void applyClothForce(ClothId id, int vertex, const btVector3& force);
    void applyPaperForce(PaperId id, int vertex, const btVector3& force);
    /// Moves a particle's world pin to `point`, reached at the end of the next stepSimulation
    /// and followed linearly over its internal steps. Throws InvalidInput ("string",
    /// "particle": not pinned to a world point, "point") and changes nothing on bad input.
    void movePin(StringId id, int particle, const btVector3& point);
    /// Cuts a segment (negative counts from the end) as a tear would: broken from now on, a
    /// Tear event (cause request) with the next internal step. False, and nothing changed,
    /// when it is already broken. Throws InvalidInput ("string", "segment").
    bool cut(StringId id, int segment);
    /// Turns a pinned end (0 = first particle, -1 = last) about its segment's axis by
    /// `angle` (rad, right-handed about the direction from the rope's inside to the end),
    /// spread evenly over the internal steps of the next stepSimulation that steps (as
    /// movePin); the end then holds the angle reached (endTwist). Throws InvalidInput
    /// ("string"; "end": not 0 or -1, or not pinned to a world point; "angle": not finite)
    /// and changes nothing then.
    void turnEnd(StringId id, int end, double angle);
    /// The angle a pinned end holds, rad: every turnEnd reached so far (a turn given for the
    /// next stepSimulation is not in it yet). Throws InvalidInput ("string", "end").
    double endTwist(StringId id, int end) const;

    // --- reading a cloth or a sheet (the state after the last internal step) --------------
    /// Vertices of a cloth, or of a sheet (a sheet gains vertices where it creases or
    /// tears; indices never change). Throws InvalidInput("cloth"/"paper") for an unknown or
    /// stale id, as every read below.
    std::size_t vertexCount(ClothId id) const;
    std::size_t vertexCount(PaperId id) const;
    /// Every vertex's position, m.
    std::vector<btVector3> positions(ClothId id) const;
    std::vector<btVector3> positions(PaperId id) const;
    /// Every vertex's velocity, m/s.
    std::vector<btVector3> velocities(ClothId id) const;
    std::vector<btVector3> velocities(PaperId id) const;
    /// A cloth's intact yarn edges (torn ones left out), in edge order, with their tensions.
    std::vector<BulletYarn> yarns(ClothId id) const;
    /// The triangles to draw, as vertex indices, counter-clockwise seen from the front (the
    /// local +y side): a cloth's cells whose four yarns are intact, two triangles each
    /// (clothFaces, cloth.hpp: a cell with a torn yarn lets the air through); a sheet's
    /// current triangles (split where it creased, parted where it tore).
    std::vector<std::array<int, 3>> triangles(ClothId id) const;
    std::vector<std::array<int, 3>> triangles(PaperId id) const;
    /// Torn so far: a cloth's broken yarn edges; a sheet's tears (vertices split by tearing).
    std::size_t tornCount(ClothId id) const;
    std::size_t tornCount(PaperId id) const;

    // --- reading a string (the state after the last internal step) -----------------------
    /// Particles and segments (a segment joins particles j and j + 1; a tear breaks a
    /// segment and keeps every particle). Throws InvalidInput("string") for an unknown or
    /// stale id, as every read below.
    std::size_t particleCount(StringId id) const;
    std::size_t segmentCount(StringId id) const;
    /// Every particle's position, m.
    std::vector<btVector3> positions(StringId id) const;
    /// One particle's position, m (negative counts from the end; InvalidInput("particle")).
    btVector3 position(StringId id, int particle) const;
    /// Every particle's velocity, m/s.
    std::vector<btVector3> velocities(StringId id) const;
    /// Per segment, the tension of the last internal step, N (0 where broken or slack).
    /// (peakTension() keeps the largest of every internal step.)
    std::vector<double> tensions(StringId id) const;
    /// Per segment, true where it is torn.
    std::vector<bool> brokenSegments(StringId id) const;
    /// A piece of a string: particles first..last joined by intact segments.
    struct Piece {
        int first = 0;  ///< its first particle
        int last = 0;   ///< its last particle (== first for a lone particle between two tears)
    };
    /// The pieces in particle order: one for an intact string, one more for each tear.
    std::vector<Piece> pieces(StringId id) const;
    /// The length of the centreline now, m: the distances between neighbouring particles
    /// summed over the intact segments (a torn rope's pieces together).
    double length(StringId id) const;
    /// The sum of the intact segments' rest lengths, m (changed by reel and yielding).
    double restLength(StringId id) const;
    /// The mass of every particle together, kg (a torn rope's pieces keep theirs).
    double mass(StringId id) const;
    /// True when the particle is pinned or glued (negative counts from the end).
    bool isAttached(StringId id, int particle) const;

    /// Per segment, the largest tension (N) any internal step reached since the string was
    /// added or clearPeakTension() was called, including the tension a segment tore at.
    /// Throws InvalidInput("string") for an unknown string.
    std::vector<double> peakTension(StringId id) const;
    /// Starts a new peak for every segment of `id` (throws InvalidInput("string")).
    void clearPeakTension(StringId id);

    /// Events since the last clearEvents(), over every internal step Bullet took, in
    /// order; a string's yields in one internal step are one event (BulletEvent::count).
    const std::vector<BulletEvent>& events() const;
    void clearEvents();
    /// The contacts of strings with Bullet bodies in the last internal step that pressed
    /// (normal force > 0), by string, then as found; replaced at every internal step.
    const std::vector<BulletContact>& contacts() const;
    /// Called for every tear (a string's, a cloth's yarn, a sheet's), in the order of
    /// events(), at the end of the internal step in which it happened; empty = none.
    /// Called inside stepSimulation, after tearables' step: read anything, but add, remove
    /// or attach nothing (tearables' or Bullet's) there. What it throws is caught and
    /// reported by lastError().
    void setTearCallback(std::function<void(const BulletEvent&)> callback);
    /// Called for every entry of contacts() at the end of each internal step (as
    /// setTearCallback, and with its rules).
    void setContactCallback(std::function<void(const BulletContact&)> callback);
    /// Stage times summed over all steps so far, s.
    const StageTimes& totalStageTimes() const;
    /// False once the Bullet world was destroyed (or this plugin was removed from it).
    bool attachedToBullet() const;
    /// Draws every string, cloth and paper sheet through Bullet's debug drawer, for users who
    /// render with their own engine: one line per intact string segment, coloured by its
    /// load (tension over the rupture tension of the string's material, tensionColor() in
    /// colormap.hpp: blue slack, yellow about to tear), and a magenta sphere (drawSphere) at
    /// the middle of each broken segment; one line per intact cloth yarn edge coloured the
    /// same way (torn yarns left out); each sheet's triangle edges in paperColor() and its
    /// creases and folds (paperCreaseLines) in creaseColor(). Bullet's
    /// btDiscreteDynamicsWorld::debugDrawWorld() calls it too (through the action).
    void debugDraw(btIDebugDraw& drawer) const;
    /// The colour of torn-segment markers in debugDraw().
    static btVector3 brokenMarkerColor() { return btVector3(1, 0, 1); }
    /// The colours of a sheet's edges and of its creases in debugDraw().
    static btVector3 paperColor() { return btVector3(0.85f, 0.83f, 0.76f); }
    static btVector3 creaseColor() { return btVector3(0.35f, 0.22f, 0.10f); }

    /// The error caught inside the last internal step (the step never throws into Bullet),
    /// or "" once a later step succeeds. Read it after each stepSimulation.
    const std::string& lastError() const;

    /// Writes the whole tearables state (tearables/snapshot.hpp) and which Bullet body each
    /// rigid proxy stands for, as an index into `bodies`: list every body the strings may
    /// hold or touch (all of them, simplest), in an order you can repeat. Throws
    /// InvalidInput("bodies") when a body the strings use is missing from the list.
    void saveSnapshot(std::ostream& out, const std::vector<const btRigidBody*>& bodies) const;
    /// Restores a snapshot written by saveSnapshot into this plugin, mapping the proxies to
    /// `bodies` by the same order (the bodies must be in this Bullet world, in the state
    /// they had when it was written: Bullet's own state is the user's to restore). Forces and
    /// pin moves given for the next stepSimulation, events and peak tensions are dropped.
    /// Throws SnapshotError or InvalidInput("bodies[i]"); nothing changes then.
    void loadSnapshot(std::istream& in, const std::vector<btRigidBody*>& bodies);

    // --- ropes in Bullet's queries ----------------------------------------------------------
    /// On (the default): every string is also one btCollisionObject in the Bullet world, a
    /// btCompoundShape of one capsule per intact segment (the string's radius, between the
    /// segment's two particles), moved to the particles at the end of each stepSimulation
    /// (its last internal step: inside a frame, in an internal tick callback, they are where
    /// the frame began), rebuilt when a segment tears or is cut; added with the string (with its collision filter:
    /// group and mask of addString) and removed with it. So Bullet's own world.rayTest (and
    /// convexSweepTest, contactTest) meets ropes as it meets bodies, closest hit first, and a
    /// ray's filter selects ropes by their group. Rays meet the capsules exactly (each
    /// answers Bullet's ray with the ray-capsule entry, as tearables::rayTest does); sweeps
    /// and contact tests meet an 8-sided prism around each. The object takes no part in the
    /// simulation: static and without contact response, it pairs with no body (the
    /// plugin sets a btOverlapFilterCallback on the world's pair cache that refuses rope
    /// objects' pairs and applies Bullet's rule to the rest, unless the cache has one
    /// already; it stays after the plugin), makes no manifold or contact, joins no island
    /// and never sleeps; tearables' own collisions are unchanged. (Bodies that touch each
    /// other may meet in another order in Bullet's broadphase, whose tree holds the rope
    /// objects too: the same physics, other rounding; turn the objects off where runs must
    /// match earlier ones bit for bit.) Its getUserPointer() is the string's setUserPointer()
    /// (null until set), getUserIndex() and getUserIndex2() the StringId's index and
    /// generation; do not change them, nor its shape's user pointer (the plugin's mark of a
    /// rope object), nor remove the object from the world yourself.
    /// Off: the objects leave the world (and come back, following the strings, when turned
    /// on). Changes made through core() (strings added, removed or cut there) reach the
    /// objects at the end of the next stepSimulation.
    void setRopesRayTestable(bool on);
    bool ropesRayTestable() const;
    /// The collision object of a string (null while ropesRayTestable() is off). Throws
    /// InvalidInput("string") for an unknown or stale id.
    const btCollisionObject* rayObject(StringId id) const;
    /// The rope and segment of a hit on `object` at compound child `child`: for a ray test,
    /// LocalRayResult::m_localShapeInfo->m_triangleIndex (Bullet's rayTest puts the child
    /// index there for compounds; keep it in your RayResultCallback's addSingleResult).
    /// Nothing when `object` is not one of this world's rope objects (a body: test it
    /// first), the child is out of range, or its segment has torn since the last step.
    std::optional<RopeHit> ropeHit(const btCollisionObject* object, int child) const;
    /// The same from a hit point (world, m), for callbacks that keep only the point, as
    /// btCollisionWorld::ClosestRayResultCallback does (m_hitPointWorld): the intact segment
    /// whose capsule's surface is nearest `point`. Throws InvalidInput("point") if it is
    /// not finite.
    std::optional<RopeHit> ropeHit(const btCollisionObject* object, const btVector3& point) const;

private:
    /// Everything else: the core world, the proxies of Bullet bodies, what the user gave for
    /// the next stepSimulation (plugin/bullet_world_impl.hpp).
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

}  // namespace tearables
