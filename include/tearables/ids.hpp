// tearables: the ids of objects in a world, the error every call throws on bad input, and
// the small enums that the Bullet plugin's header shares with the core. No Eigen: this is
// what tearables/bullet.hpp includes of the core.
#pragma once

#include <cstdint>
#include <stdexcept>
#include <string>
#include <utility>

namespace tearables {

/// Identifies a string (rope, thread) in a World; stays valid until the string is removed.
struct StringId {
    std::uint32_t index = UINT32_MAX;  ///< slot in the world; UINT32_MAX = none
    /// Which object that slot held: a slot's generation grows by one when its string is
    /// removed, so an id kept after the removal is refused (InvalidInput naming the
    /// argument) instead of naming the next string put in the slot.
    std::uint32_t generation = 0;
    bool valid() const { return index != UINT32_MAX; }
    friend bool operator==(StringId a, StringId b) { return a.index == b.index && a.generation == b.generation; }
    friend bool operator!=(StringId a, StringId b) { return !(a == b); }
    /// By slot, then generation (for ordered containers).
    friend bool operator<(StringId a, StringId b) {
        return a.index != b.index ? a.index < b.index : a.generation < b.generation;
    }
};

/// Identifies a cloth in a World; stays valid until the cloth is removed.
struct ClothId {
    std::uint32_t index = UINT32_MAX;  ///< slot in the world; UINT32_MAX = none
    /// Which object that slot held: a slot's generation grows by one when its cloth is
    /// removed, so an id kept after the removal is refused (InvalidInput naming the
    /// argument) instead of naming the next cloth put in the slot.
    std::uint32_t generation = 0;
    bool valid() const { return index != UINT32_MAX; }
    friend bool operator==(ClothId a, ClothId b) { return a.index == b.index && a.generation == b.generation; }
    friend bool operator!=(ClothId a, ClothId b) { return !(a == b); }
    /// By slot, then generation (for ordered containers).
    friend bool operator<(ClothId a, ClothId b) {
        return a.index != b.index ? a.index < b.index : a.generation < b.generation;
    }
};

/// Identifies a paper sheet in a World; stays valid until the sheet is removed.
struct PaperId {
    std::uint32_t index = UINT32_MAX;  ///< slot in the world; UINT32_MAX = none
    /// Which object that slot held: a slot's generation grows by one when its paper sheet is
    /// removed, so an id kept after the removal is refused (InvalidInput naming the
    /// argument) instead of naming the next paper sheet put in the slot.
    std::uint32_t generation = 0;
    bool valid() const { return index != UINT32_MAX; }
    friend bool operator==(PaperId a, PaperId b) { return a.index == b.index && a.generation == b.generation; }
    friend bool operator!=(PaperId a, PaperId b) { return !(a == b); }
    /// By slot, then generation (for ordered containers).
    friend bool operator<(PaperId a, PaperId b) {
        return a.index != b.index ? a.index < b.index : a.generation < b.generation;
    }
};

/// Identifies a rigid body proxy in the core World (the Bullet plugin creates them).
struct RigidId {
    std::uint32_t index = UINT32_MAX;  ///< slot in the world; UINT32_MAX = none
    bool valid() const { return index != UINT32_MAX; }
    friend bool operator==(RigidId a, RigidId b) { return a.index == b.index; }
    friend bool operator!=(RigidId a, RigidId b) { return a.index != b.index; }
};

/// What a change of rest length does to a string's mass.
enum class RestMass {
    Conserve,  ///< the particles keep their masses: the string's mass stays, its mass per length changes
    Add,       ///< mass density * pi r^2 * (change) is added (removed), half to each end of the segment
};

/// Thrown when a descriptor, argument or scene field is invalid. `field()` names the
/// offending field ("radius", "strings[0].material.tensile.rupture"); what() is
/// "<field>: <problem>". Nothing is created or changed when it is thrown.
class InvalidInput : public std::invalid_argument {
public:
    InvalidInput(std::string field, const std::string& problem)
        : std::invalid_argument(field.empty() ? problem : field + ": " + problem),
          field_(std::move(field)), problem_(problem) {}
    /// The field's name or path.
    const std::string& field() const { return field_; }
    /// The problem without the field name.
    const std::string& problem() const { return problem_; }

private:
    std::string field_;
    std::string problem_;
};

}  // namespace tearables
