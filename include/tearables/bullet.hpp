// tearables: the Bullet plugin. Attach a tearables world to your btDiscreteDynamicsWorld;
// it then steps inside stepSimulation, at Bullet's fixed internal time step, after Bullet
// has integrated the rigid bodies (a btActionInterface).
//
//   btDiscreteDynamicsWorld world(...);
//   tearables::BulletWorld ropes(world);
//   auto rope = ropes.addString(tearables::StringDesc::straight({0, 2, 0}, {0, 1, 0}, 50));
//   ropes.attach(rope, 0, btVector3(0, 2, 0));          // pinned in the world
//   ropes.attach(rope, -1, *crate, btVector3(0, 0.2f, 0)); // glued to a body, two-way
//   world.stepSimulation(1.0f / 60.0f);
//   double t = ropes.core().view(rope).tension->front();   // newtons
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
// Lifetime: destroying the BulletWorld detaches it from Bullet; destroying the Bullet
// world first is safe too (the plugin notices and never touches it again). A body that
// strings are glued to may be removed from the Bullet world at any time: at the next
// step its attachments are dropped with Release events (cause body_removed). Before you
// *delete* such a body, remove it from the world and step, or call forgetBody().
#pragma once

#include "tearables/controls.hpp"
#include "tearables/events.hpp"
#include "tearables/paper.hpp"
#include "tearables/presets.hpp"
#include "tearables/queries.hpp"
#include "tearables/string.hpp"
#include "tearables/world.hpp"

#include "tearables/bullet_precision.hpp"

#include <LinearMath/btScalar.h>
#include <LinearMath/btVector3.h>

#include <cstdint>
#include <functional>
#include <iosfwd>
#include <map>
#include <memory>
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

class IslandClaimSolver;

/// Converts between Bullet and the core (the only place that does).
inline Vec3 toCore(const btVector3& v) { return Vec3(v.x(), v.y(), v.z()); }
inline btVector3 toBullet(const Vec3& v) {
    return btVector3(static_cast<btScalar>(v.x()), static_cast<btScalar>(v.y()), static_cast<btScalar>(v.z()));
}

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

/// A tearables world living inside a Bullet dynamics world.
class BulletWorld {
public:
    /// Attaches to `world`; strings use the world's gravity at every step.
    explicit BulletWorld(btDiscreteDynamicsWorld& world, const WorldSettings& settings = {});
    /// Detaches from Bullet (if the Bullet world still exists).
    ~BulletWorld();
    BulletWorld(const BulletWorld&) = delete;
    BulletWorld& operator=(const BulletWorld&) = delete;

    /// The core world: views, events, settings, forces. After the Bullet world was
    /// destroyed, the first call drops every body the plugin knew (their attachments are
    /// released at the core's next step); stepping the core then touches nothing of Bullet.
    World& core();
    const World& core() const;

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

private:
    class Action;
    class Contacts;
    void dropBodiesIfDetached();
    /// Internal step `tick` (1-based) of the `ticks` that the current stepSimulation takes.
    void substep(double h, int tick, int ticks);
    void drive(int tick, int ticks);
    void recordPeaks();
    /// The winches' rope for an internal step of h (bullet_api.cpp).
    void turnWinches(double h);
    /// The last internal step's contacts and events as Bullet users read them, then the
    /// callbacks (bullet_api.cpp).
    void reportStep(double h);
    void describe(BulletEvent& e) const;
    btRigidBody* bodyOf(RigidId id) const;
    btRigidBody* hangingBody(StringId id, int segment) const;
    /// Bodies out: the core's corrections written back; only bodies that a string, sheet or
    /// cloth holds or touched are woken.
    void writeBodies();
    struct Filter {
        int group = 1, mask = -1;  // btBroadphaseProxy::DefaultFilter, AllFilter
        bool passes(const btRigidBody& body) const;
    };
    /// The filter of the i-th object of a mesh PointQuery (a sheet's or a cloth's).
    Filter meshFilter(const PointQuery& query, std::size_t i) const;
    RigidId proxyFor(btRigidBody& body);
    void findCandidates(double h);
    bool isCandidate(const btRigidBody* body) const;
    /// Rigid bodies (with contact response) whose broadphase bounds overlap [lo, hi],
    /// in a deterministic order.
    std::vector<btRigidBody*> bodiesIn(const Vec3& lo, const Vec3& hi) const;

    /// Bodies that ropes hold or touch are taken from Bullet's solver with their Bullet
    /// islands (plugin/island_claim.hpp) and solved in the core's islands, contacts and
    /// all. `claim_` is null where the world's solver cannot be wrapped (multibody).
    void startClaimedBodies(double h);
    void claimIslandBodies();

    btDiscreteDynamicsWorld* world_;
    std::unique_ptr<IslandClaimSolver> claim_;
    std::vector<const btRigidBody*> claimed_;  // this step's claimed bodies, sorted
    std::unique_ptr<World> core_;
    std::unique_ptr<Action> action_;
    std::unique_ptr<Contacts> contacts_;
    std::map<const btRigidBody*, RigidId> proxies_;  // ordered: deterministic iteration
    std::map<std::uint32_t, std::vector<btRigidBody*>> candidates_;  // per string: bodies near it this step
    std::vector<btRigidBody*> mesh_candidates_;  // bodies near some mesh object this step (sorted)
    std::vector<std::pair<const btRigidBody*, RigidId>> proxy_order_;  // scratch
    std::vector<const btCollisionObject*> in_world_;  // scratch: the Bullet world's objects, sorted
    std::vector<BulletEvent> events_;
    std::vector<BulletContact> contact_list_;
    std::vector<ContactForce> contact_forces_;                     // scratch: the core's
    std::vector<std::pair<std::uint32_t, btRigidBody*>> body_of_;  // scratch: proxy -> body, sorted
    std::function<void(const BulletEvent&)> on_tear_;
    std::function<void(const BulletContact&)> on_contact_;
    StageTimes total_;
    std::string last_error_;
    double step_ = 0.0;  // the internal step Bullet is taking
    int tick_ = 1, ticks_ = 1;  // which of how many internal steps of the current stepSimulation
    struct PendingPin {
        Vec3 from, to;  // m
    };
    // Keyed by (object, particle or vertex): deterministic order.
    std::map<std::pair<StringId, int>, Vec3> forces_;     // N, until the end of the next stepSimulation
    std::map<std::pair<ClothId, int>, Vec3> cloth_forces_;
    std::map<std::pair<PaperId, std::uint32_t>, Vec3> paper_forces_;
    std::map<std::pair<StringId, int>, PendingPin> pins_;
    std::map<StringId, std::vector<double>> peaks_;       // per string, per segment, N
    struct Winch {
        double speed = 0.0;  // m/s, > 0 pays out
        RestMass mode = RestMass::Conserve;
    };
    std::map<std::pair<StringId, int>, Winch> winches_;  // by (string, end)
    // setUserPointer's, per object.
    std::map<StringId, void*> string_users_;
    std::map<ClothId, void*> cloth_users_;
    std::map<PaperId, void*> paper_users_;
    // Collision filters other than Bullet's default, per slot.
    std::map<std::uint32_t, Filter> string_filters_, cloth_filters_, paper_filters_;

    friend class Action;
};

}  // namespace tearables
