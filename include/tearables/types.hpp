// tearables: basic types shared by the core, the plugin and the scene loader.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <cstdint>
#include <stdexcept>
#include <string>

namespace tearables {

/// A 3-vector in SI units (m, m/s, N, ...). The core computes in double precision.
using Vec3 = Eigen::Vector3d;
/// A 3x3 matrix (inertia tensors, inverse mass matrices).
using Mat3 = Eigen::Matrix3d;
/// A unit quaternion (orientation).
using Quat = Eigen::Quaterniond;

/// The centre of a paper sheet or cloth that gives neither `center` nor `corner`, m.
inline Vec3 defaultSheetCenter() { return Vec3(0.0, 1.0, 0.0); }

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

/// Identifies a rigid body proxy in the core World (the Bullet plugin creates them).
struct RigidId {
    std::uint32_t index = UINT32_MAX;  ///< slot in the world; UINT32_MAX = none
    bool valid() const { return index != UINT32_MAX; }
    friend bool operator==(RigidId a, RigidId b) { return a.index == b.index; }
    friend bool operator!=(RigidId a, RigidId b) { return a.index != b.index; }
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
