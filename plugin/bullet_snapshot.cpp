// BulletWorld snapshots: the core's snapshot plus a "BULT" section that maps every rigid
// proxy to the index of its Bullet body in the list the user passes (bodies have no
// identity that survives a process: the order the user gives them is it).
#include "bullet_world_impl.hpp"
#include "tearables/snapshot.hpp"

#include <btBulletDynamicsCommon.h>

#include <algorithm>
#include <istream>
#include <ostream>

namespace tearables {

namespace {

constexpr const char* kTag = "BULT";

void putWord(std::string& out, std::uint64_t v) {
    for (int i = 0; i < 8; ++i) out.push_back(static_cast<char>((v >> (8 * i)) & 0xffu));
}

std::uint64_t getWord(const std::string& in, std::size_t& at) {
    if (in.size() - at < 8 || at > in.size()) throw SnapshotError(std::string("snapshot.") + kTag, "truncated section");
    std::uint64_t v = 0;
    for (int i = 0; i < 8; ++i) v |= static_cast<std::uint64_t>(static_cast<unsigned char>(in[at + i])) << (8 * i);
    at += 8;
    return v;
}

}  // namespace

void BulletWorld::saveSnapshot(std::ostream& out, const std::vector<const btRigidBody*>& bodies) const {
    std::string map;
    putWord(map, impl_->proxies_.size());
    for (const auto& [body, id] : impl_->proxies_) {
        const auto it = std::find(bodies.begin(), bodies.end(), body);
        if (it == bodies.end())
            throw InvalidInput("bodies", "a body the strings hold or touch (rigid proxy " + std::to_string(id.index) +
                                             ") is not in the list");
        putWord(map, id.index);
        putWord(map, static_cast<std::uint64_t>(it - bodies.begin()));
    }
    tearables::saveSnapshot(*impl_->core_, out, {{kTag, map}});
}

void BulletWorld::loadSnapshot(std::istream& in, const std::vector<btRigidBody*>& bodies) {
    const Snapshot snapshot = Snapshot::read(in);
    const std::string where = std::string("snapshot.") + kTag;
    const SnapshotSection* map = nullptr;
    for (const SnapshotSection& s : snapshot.hostSections()) {
        if (s.tag != kTag) throw SnapshotError("snapshot." + s.tag, "unknown section (written by a newer tearables?)");
        if (map) throw SnapshotError(where, "appears twice");
        map = &s;
    }
    if (!map) throw SnapshotError(where, "missing: the snapshot was not written by BulletWorld::saveSnapshot");
    std::size_t at = 0;
    const std::uint64_t count = getWord(map->payload, at);
    if (count > map->payload.size() / 16) throw SnapshotError(where, "damaged proxy count");
    std::map<const btRigidBody*, RigidId> proxies;
    for (std::uint64_t k = 0; k < count; ++k) {
        const std::uint64_t slot = getWord(map->payload, at);
        const std::uint64_t index = getWord(map->payload, at);
        const RigidId id{static_cast<std::uint32_t>(std::min<std::uint64_t>(slot, UINT32_MAX))};
        if (slot >= UINT32_MAX || !snapshot.hasRigid(id))
            throw SnapshotError(where, "maps rigid slot " + std::to_string(slot) + ", which the snapshot does not have");
        if (index >= bodies.size())
            throw InvalidInput("bodies", "the snapshot needs body " + std::to_string(index) + " but " +
                                             std::to_string(bodies.size()) + " were given");
        const std::string field = "bodies[" + std::to_string(index) + "]";
        btRigidBody* body = bodies[index];
        if (!body) throw InvalidInput(field, "is null");
        if (!body->getBroadphaseHandle()) throw InvalidInput(field, "is not in the Bullet world");
        for (const auto& [other, other_id] : proxies)
            if (other_id == id) throw SnapshotError(where, "maps rigid slot " + std::to_string(slot) + " twice");
        if (!proxies.emplace(body, id).second) throw InvalidInput(field, "stands for two rigid proxies");
    }
    if (at != map->payload.size()) throw SnapshotError(where, "bytes left over at the end of the section");
    snapshot.restore(*impl_->core_);
    impl_->proxies_ = std::move(proxies);
    impl_->named_.clear();  // the snapshot's ids name the bodies now: ask bodyId() again
    impl_->candidates_.clear();
    impl_->mesh_candidates_.clear();
    impl_->events_.clear();
    impl_->forces_.clear();  // what was given for the next stepSimulation belonged to the state replaced
    impl_->pins_.clear();
    impl_->turns_.clear();
    impl_->cloth_forces_.clear();
    impl_->paper_forces_.clear();
    impl_->peaks_.clear();
    impl_->syncRopeObjects();
}

}  // namespace tearables
