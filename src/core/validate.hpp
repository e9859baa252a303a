// Checks shared by the descriptors' validation (src/string/desc.cpp, src/cloth/desc.cpp):
// each throws InvalidInput naming the field and the value it got.
#pragma once

#include "tearables/types.hpp"

#include <cmath>
#include <sstream>
#include <string>

namespace tearables::detail {

/// A value as the messages print it (9 significant digits).
inline std::string num(double v) {
    std::ostringstream s;
    s.precision(9);
    s << v;
    return s.str();
}

inline void requireFinite(const std::string& field, double v) {
    if (!std::isfinite(v)) throw InvalidInput(field, "must be a finite number (got " + num(v) + ")");
}

inline void requirePositive(const std::string& field, double v) {
    requireFinite(field, v);
    if (!(v > 0.0)) throw InvalidInput(field, "must be greater than 0 (got " + num(v) + ")");
}

inline void requireRange(const std::string& field, double v, double lo, double hi) {
    requireFinite(field, v);
    if (v < lo || v > hi) throw InvalidInput(field, "must be in [" + num(lo) + ", " + num(hi) + "] (got " + num(v) + ")");
}

}  // namespace tearables::detail
