// tearables: basic types shared by the core, the plugin and the scene loader (the ids and
// InvalidInput are in ids.hpp, which has no Eigen).
#pragma once

#include "tearables/ids.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace tearables {

/// A 3-vector in SI units (m, m/s, N, ...). The core computes in double precision.
using Vec3 = Eigen::Vector3d;
/// A 3x3 matrix (inertia tensors, inverse mass matrices).
using Mat3 = Eigen::Matrix3d;
/// A unit quaternion (orientation).
using Quat = Eigen::Quaterniond;

/// The centre of a paper sheet or cloth that gives neither `center` nor `corner`, m.
inline Vec3 defaultSheetCenter() { return Vec3(0.0, 1.0, 0.0); }

}  // namespace tearables
