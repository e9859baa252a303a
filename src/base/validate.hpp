// Checks shared by the descriptors' validation (src/string/desc.cpp, src/cloth/desc.cpp):
// each throws InvalidInput naming the field and the value it got. The field's name is a
// string_view, made a std::string only when it is thrown: World::step checks its settings
// every step, and a name past the small-string buffer ("strain_tolerance") was a heap
// allocation per step (issue 9).
#pragma once

#include "tearables/types.hpp"

#include <cmath>
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

}  // namespace tearables::detail
