// The state behind tearables::BulletWorld (tearables/bullet.hpp keeps only a pointer to it,
// so that its users compile without Eigen, the core's headers or these containers), and
// the step's private helpers. BulletWorld's public calls are defined once, as BulletWorld's
// members, beside the code they use: the step's adapter and the building calls in
// bullet_world.cpp, the Bullet-facing reports bullet_api.cpp, ray objects bullet_rays.cpp,
// snapshots bullet_snapshot.cpp, the reads bullet_facade.cpp.
#pragma once

#include "tearables/bullet_core.hpp"

#include "island_claim.hpp"

#include <cstdint>
#include <functional>
#include <iosfwd>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <utility>
#include <vector>

class btCollisionObject;

namespace tearables {

struct BulletWorld::Impl {
    Impl(btDiscreteDynamicsWorld& world, const WorldSettings& settings);
    ~Impl();
    Impl(const Impl&) = delete;
    Impl& operator=(const Impl&) = delete;

    // BulletWorld's calls are its own (bullet_world.cpp, bullet_api.cpp, bullet_rays.cpp,
    // bullet_snapshot.cpp, bullet_facade.cpp); these two are the step's too.
    /// False once the Bullet world was destroyed (or the plugin's action removed from it).
    bool attachedToBullet() const;
    /// BulletWorld::debugDraw, also called by Bullet's debugDrawWorld through the action.
    void debugDraw(btIDebugDraw& drawer) const;

    // --- ropes in Bullet's queries (bullet_rays.cpp) ----------------------------------------
    /// A string's collision object: a compound of one capsule per intact segment.
    class RopeObject;
    struct RopeObjectSlot {
        RopeObjectSlot();
        RopeObjectSlot(RopeObjectSlot&&) noexcept;
        RopeObjectSlot& operator=(RopeObjectSlot&&) noexcept;
        ~RopeObjectSlot();
        std::unique_ptr<RopeObject> object;
    };
    /// Creates (and adds to the Bullet world) or moves the object of string `id`.
    void syncRopeObject(StringId id);
    /// Removes the object of string `id` from the Bullet world and frees it.
    void dropRopeObject(StringId id);
    /// Every string's object made to follow it; those of strings that are gone dropped.
    void syncRopeObjects();
    /// ~Impl: takes every object out of the Bullet world, if it still exists.
    void removeRopeObjectsFromWorld();
    /// The string's user pointer copied to its object.
    void userPointerChanged(StringId id);
    /// Keeps rope objects out of the world's broadphase pairs (unless it has a filter).
    struct RopePairFilter;
    void installPairFilter();

    // --- the step's adapter ---------------------------------------------------------------
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
    std::set<const btRigidBody*> named_;  // bodies given to bodyId(): their proxies stay while they are in the world
    std::map<std::uint32_t, std::vector<btRigidBody*>> candidates_;  // per string: bodies near it this step
    std::vector<btRigidBody*> mesh_candidates_;  // bodies near some mesh object this step (sorted)
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
    /// A turn of a pinned end given for the next stepSimulation: `angle` (rad) in all,
    /// `done` of it turned by the internal steps so far.
    struct PendingTurn {
        double angle = 0.0, done = 0.0;
    };
    // Keyed by (object, particle or vertex): deterministic order.
    std::map<std::pair<StringId, int>, Vec3> forces_;     // N, until the end of the next stepSimulation
    std::map<std::pair<ClothId, int>, Vec3> cloth_forces_;
    std::map<std::pair<PaperId, std::uint32_t>, Vec3> paper_forces_;
    std::map<std::pair<StringId, int>, PendingPin> pins_;
    std::map<std::pair<StringId, int>, PendingTurn> turns_;  // by (string, end 0 or -1)
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
    bool rope_objects_on_ = true;                    // setRopesRayTestable
    std::map<StringId, RopeObjectSlot> rope_objects_;  // per string, while on
};

}  // namespace tearables
