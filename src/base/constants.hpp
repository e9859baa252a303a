// Mathematical constants shared by the solvers.
#pragma once

namespace tearables::detail {

inline constexpr double kPi = 3.14159265358979323846;

}  // namespace tearables::detail
