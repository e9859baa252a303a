// The strings of a world and their step, one method a stage (Strings, Yarn): shape
// matching, prediction, collision with rigid bodies (the host's narrow phase), strain
// limiting, string-string collision (string_pairs.cpp), twist, tension, material
// response, velocities. Strings that share nothing run on the pool; those coupled
// through a movable body are swept Gauss-Seidel on this thread.
#pragma once

#include "sim/host_contacts.hpp"
#include "sim/rigid_table.hpp"
#include "sim/step_context.hpp"
#include "string/string_island.hpp"
#include "string/string_pairs.hpp"
#include "string/string_state.hpp"
#include "tearables/world.hpp"

#include <cstdint>
#include <vector>

namespace tearables::detail {

/// One particle of a string of `count` particles, by a possibly negative index (from the
/// end); throws InvalidInput naming `field` when out of range.
int resolveIndex(int particle, std::size_t count, const char* field);

/// The strings of a world: created, stepped and viewed through World. The same shape as
/// ClothSystem and PaperSystem: add, remove, get, contains, ids; step(rigids, ctx, host,
/// events) and lastTimes(); usesBody, releaseBody, release.
class StringSystem {
public:
    /// Builds a string from a valid descriptor (throws InvalidInput otherwise) in the first free slot.
    StringId add(const StringDesc& desc);
    void remove(StringId id);
    StringState& get(StringId id);
    const StringState& get(StringId id) const;
    bool contains(StringId id) const;
    /// The id of the string in `slot` (its current generation).
    StringId idAt(std::size_t slot) const;
    std::vector<StringId> ids() const;

    /// One step of every live string (the first material of World::step).
    void step(RigidTable& rigids, const StepContext& ctx, const HostContacts& host, std::vector<Event>& events);
    /// Wall time of the strings' stages in the last step, s.
    const StageTimes& lastTimes() const { return times_; }
    /// The host's contacts of the last step, as it gave them.
    const std::vector<RigidContact>& lastContacts() const { return contacts_; }

    /// True when a particle is glued to `body`.
    bool usesBody(RigidId body) const;
    /// Drops every glue to `body` (Release events with cause BodyRemoved into `pending`).
    void releaseBody(RigidId body, double time, std::int64_t step, std::vector<Event>& pending);
    /// Releases a particle (Release event into `pending`); no-op when free.
    void release(StringId id, std::size_t particle, EventCause cause, double time, std::int64_t step,
                 std::vector<Event>& pending);

    /// The string-string contacts (tests switch their search's shortcuts and read its counters).
    StringPairs& pairs() { return pairs_; }
    const StringPairs& pairs() const { return pairs_; }

private:
    friend struct WorldAccess;  // snapshots read and replace the strings (src/world/snapshot.cpp)

    void listLive();
    void shapeMatch();
    void predict(const RigidTable& rigids, const StepContext& ctx);
    void collideBodies(RigidTable& rigids, const HostContacts& host, const StepContext& ctx, std::vector<Event>& events);
    void reportStartOverlaps(const StepContext& ctx, std::vector<Event>& events);
    void limitStrain(RigidTable& rigids, const StepContext& ctx);
    void solveCoupledClusters(RigidTable& rigids, const StepContext& ctx);
    void solveTwist(RigidTable& rigids, const StepContext& ctx);
    void estimateTension(const StepContext& ctx);
    void respondMaterial(const StepContext& ctx, std::vector<Event>& events);
    void updateVelocities(const StepContext& ctx, std::vector<Event>& events);
    template <class Fn>
    void eachLive(Fn&& fn);

    std::vector<StringState> strings_;       // by slot; dead slots are reused
    StringPairs pairs_;
    ThreadPool* pool_ = nullptr;             // this step's (StepContext::pool)
    std::vector<std::uint32_t> live_;        // this step's live strings
    std::vector<std::uint32_t> own_;         // those that neither hold nor touch a movable body
    std::vector<std::uint8_t> is_own_;       // per slot: in own_ this step
    std::vector<StringIslandMember> members_;  // the others that touch a movable body (kept: reused)
    std::size_t used_members_ = 0;             // of which this step's
    std::vector<IslandMember*> member_list_;
    std::vector<std::uint8_t> in_island_;     // per slot: a member of this step's islands
    std::vector<std::uint8_t> no_island_;     // couple's in_island without island_string_contacts (empty)
    std::vector<std::uint8_t> in_cluster_;    // per slot: solved in an island by its cluster's member
    std::vector<RigidState> island_start_;    // the bodies before the islands' solve
    // solveCoupledClusters: the first solve's outcome, put back where the solve again fails.
    std::vector<RigidState> first_bodies_;
    std::vector<std::uint8_t> kept_mark_;
    std::vector<std::pair<std::size_t, StringState>> kept_strings_;
    std::vector<std::uint8_t> bad_state_;    // per live string: non-finite after the step
    std::vector<std::vector<Event>> live_events_;  // per live string: its material events of this step
    CollisionQuery query_;
    std::vector<RigidContact> contacts_;
    StageTimes times_;
};

}  // namespace tearables::detail
