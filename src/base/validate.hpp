// Checks shared by the descriptors' validation (string/desc.cpp, cloth/desc.cpp,
// sim/validate_material.hpp): each throws InvalidInput naming the field and the value it
// got. The field's name is a string_view, made a std::string only when it is thrown, so a
// check run every step (World::step's settings) never allocates.
#pragma once

#include "tearables/types.hpp"

#include <cmath>
#include <optional>
#include <sstream>
#include <string>
#include <string_view>

namespace tearables::detail {

/// A value as the messages print it (9 significant digits).
inline std::string num(double v) {
    std::ostringstream s;
    s.precision(9);
    s << v;
    return s.str();
}

/// An index into `count` items, negative counting from the end (-1 the last), as an index
/// in [0, count). Throws InvalidInput(field, "<kind> index i out of range (the <owner> has
/// n <plural>)").
inline std::size_t resolveSignedIndex(int index, std::size_t count, std::string_view field, const char* kind,
                                      const char* owner, const char* plural) {
    const int n = static_cast<int>(count);
    if (index < -n || index >= n)
        throw InvalidInput(std::string(field), std::string(kind) + " index " + std::to_string(index) + " out of range (the " +
                                                   owner + " has " + std::to_string(n) + " " + plural + ")");
    return static_cast<std::size_t>(index < 0 ? index + n : index);
}

/// Whether every coordinate of `v` is finite.
inline bool finite(const Vec3& v) { return std::isfinite(v.x()) && std::isfinite(v.y()) && std::isfinite(v.z()); }

inline void requireFinite(std::string_view field, double v) {
    if (!std::isfinite(v)) throw InvalidInput(std::string(field), "must be a finite number (got " + num(v) + ")");
}

inline void requirePositive(std::string_view field, double v) {
    requireFinite(field, v);
    if (!(v > 0.0)) throw InvalidInput(std::string(field), "must be greater than 0 (got " + num(v) + ")");
}

inline void requireRange(std::string_view field, double v, double lo, double hi) {
    requireFinite(field, v);
    if (v < lo || v > hi) throw InvalidInput(std::string(field), "must be in [" + num(lo) + ", " + num(hi) + "] (got " + num(v) + ")");
}

/// Positive and within [lo, hi]: the range where the solvers' derived quantities (masses,
/// stiffnesses, their inverses) stay normal double-precision numbers.
inline void requirePhysical(std::string_view field, double v, double lo, double hi) {
    requirePositive(field, v);
    requireRange(field, v, lo, hi);
}

/// Positions: within +-1e6 m along each axis, where Bullet's single precision still spaces
/// floats 0.06 m apart (coarse, but finite); the scene format holds positions to the same.
inline constexpr double kMaxCoordinate = 1e6;

inline void requirePosition(std::string_view field, const Vec3& v) {
    for (int k = 0; k < 3; ++k) requireRange(field, v[k], -kMaxCoordinate, kMaxCoordinate);
}

/// Every vertex of a sheet or cloth lies within `span` of its `anchor` (half the diagonal
/// from its centre, the whole diagonal from its corner), in any orientation: they all stay
/// within the position bound.
inline void requireExtentWithinBound(std::string_view field, const Vec3& anchor, double span) {
    const double reach = anchor.cwiseAbs().maxCoeff() + span;
    if (!(reach <= kMaxCoordinate))
        throw InvalidInput(std::string(field), "its vertices may reach " + num(reach) + " m along an axis, past the position bound of " +
                                                   num(kMaxCoordinate) + " m");
}

/// Where a rectangular sheet or cloth lies: `center` or `corner`, not both (neither: the
/// default centre). Checks the one given and that every vertex stays within the position
/// bound: `diagonal` is the rectangle's diagonal, m.
inline void requireSheetPlacement(const std::optional<Vec3>& center, const std::optional<Vec3>& corner, double diagonal) {
    if (center && corner) throw InvalidInput("corner", "give center or corner, not both");
    if (center) requirePosition("center", *center);
    if (corner) requirePosition("corner", *corner);
    if (corner) requireExtentWithinBound("size", *corner, diagonal);
    else requireExtentWithinBound("size", center ? *center : defaultSheetCenter(), 0.5 * diagonal);
}

}  // namespace tearables::detail
