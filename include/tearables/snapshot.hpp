// tearables: snapshots of the whole core state.
//
// A snapshot holds everything a World carries from one step to the next: every string's
// full state (positions, velocities, rest lengths, material state after variation,
// plasticity and damage, twist, attachments, its random generator), every cloth's and
// paper sheet's (below), the rigid body proxies by slot, the string-string warm start,
// pending events, time, step count and settings. Restored into a world, the run continues
// bit-identically to the uninterrupted one, provided the host's rigid bodies are in the
// same state (the Bullet plugin maps its bodies by the order the user passes them:
// BulletWorld::saveSnapshot / loadSnapshot).
//
// Format (little-endian, version kSnapshotVersion):
//   "TEARSNAP" (8 bytes), u32 version, u32 reserved (0),
//   sections: char tag[4], u64 payload length, payload  (one section per object or table),
//   "END " section of length 0,
//   u64 FNV-1a checksum of every byte before it.
// Integers are written as 64-bit words, doubles as their IEEE bits, strings and arrays
// with a length word first. Core tags, in this order:
//   "WRLD"  settings, time, steps, and the slot counts of strings, rigid bodies, cloths
//           and paper sheets;
//   "RIGD"  the rigid proxies by slot;
//   "STRG"  one per string slot (dead slots included: ids stay, with each slot's
//           generation, so that an id kept across a removal stays refused);
//   "CLTH"  one per cloth slot: descriptor, vertices (positions, velocities, forces, masses,
//           holds), yarn edges (lengths, tension, damage, material after variation), soft
//           springs, adjacency, the random generator; scratch and factors are rebuilt;
//   "PAPR"  one per paper sheet slot: descriptor, vertices, the mesh as it is now
//           (triangles, springs, adjacency in its order), per-spring damage, the crease,
//           hinge and tear counters, the random generator, the sheet's mass;
//   "SCOL"  string-string warm start;
//   "EVNT"  pending events.
// A host adds its own (the Bullet plugin: "BULT"). A reader refuses a file of another
// version, a truncated or corrupt file, and a section it does not know, with a
// SnapshotError; the world is then unchanged. A world that already has cloths or sheets
// takes only a snapshot of the same ones (same slots, same descriptors); strings, rigid
// proxies and everything else are replaced.
#pragma once

#include "tearables/types.hpp"
#include "tearables/world.hpp"

#include <cstdint>
#include <iosfwd>
#include <memory>
#include <string>
#include <vector>

namespace tearables {

/// The version this build writes and the only one it reads.
constexpr std::uint32_t kSnapshotVersion = 15;

/// A snapshot was refused: field() is "snapshot" or "snapshot.<section>", problem() says
/// what is wrong (wrong magic, version, checksum, truncated, inconsistent section).
class SnapshotError : public InvalidInput {
public:
    using InvalidInput::InvalidInput;
};

/// A section added by a host (4-character tag, not one of the core's) and its bytes.
struct SnapshotSection {
    std::string tag;
    std::string payload;
};

/// A snapshot read and checked, not yet applied.
class Snapshot {
public:
    /// Reads and checks a whole snapshot; throws SnapshotError (nothing is changed).
    static Snapshot read(std::istream& in);
    /// Replaces the whole state of `world` by the snapshot's (its strings, cloths, paper
    /// sheets, proxies, time, settings). Throws SnapshotError ("snapshot.CLTH" or
    /// "snapshot.PAPR", naming the first difference) when the world has cloths or sheets
    /// that are not the snapshot's: other slots, names or descriptors (a world without
    /// any takes the snapshot's); nothing is changed then. Cannot fail otherwise.
    void restore(World& world) const;
    /// Sections a host added, in file order.
    const std::vector<SnapshotSection>& hostSections() const;
    /// True when the snapshot has a rigid proxy in slot `id` (for a host's mapping).
    bool hasRigid(RigidId id) const;

    Snapshot(Snapshot&&) noexcept;
    Snapshot& operator=(Snapshot&&) noexcept;
    ~Snapshot();

private:
    struct Data;
    explicit Snapshot(std::unique_ptr<Data> data);
    std::unique_ptr<Data> data_;
};

/// Writes the whole core state of `world` (and a host's sections) to `out`. Throws
/// std::runtime_error when the stream fails, InvalidInput for a bad host section tag.
void saveSnapshot(const World& world, std::ostream& out, const std::vector<SnapshotSection>& host = {});

/// Reads a snapshot written by saveSnapshot and restores it into `world` (Snapshot::restore).
/// A snapshot with host sections (written by BulletWorld::saveSnapshot) is refused: load
/// it through its host. Throws SnapshotError; the world is unchanged then.
void loadSnapshot(World& world, std::istream& in);

}  // namespace tearables
