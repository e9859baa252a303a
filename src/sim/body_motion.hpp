// How a rigid body moves in a position-level solve: its generalised mass, and its pose
// displaced by a translation and a rotation vector.
#pragma once

#include "sim/rigid_table.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace tearables::detail {

using Vec6 = Eigen::Matrix<double, 6, 1>;
using Mat6 = Eigen::Matrix<double, 6, 6>;
using Mat36 = Eigen::Matrix<double, 3, 6>;

/// The cross-product matrix [r]x.
inline Mat3 cross(const Vec3& r) {
    Mat3 m;
    m << 0.0, -r.z(), r.y(), r.z(), 0.0, -r.x(), -r.y(), r.x(), 0.0;
    return m;
}

/// d(u + theta x r) / d(u, theta) = [I, -[r]x]: how a point at arm r from a body's centre
/// moves with the body's translation u and small turn theta.
inline Mat36 pointJacobian(const Vec3& r) {
    Mat36 j;
    j.leftCols<3>() = Mat3::Identity();
    j.rightCols<3>() = -cross(r);
    return j;
}

/// Generalised mass of a body (translation, rotation about its centre), world frame.
inline Mat6 bodyMass(const RigidState& b) {
    Mat6 m = Mat6::Zero();
    m.topLeftCorner<3, 3>() = Mat3::Identity() / b.inverse_mass;
    m.bottomRightCorner<3, 3>() = b.inverseInertiaWorld().inverse();
    return m;
}

/// The rotation by a rotation vector.
inline Quat rotationBy(const Vec3& v) {
    const double angle = v.norm();
    return angle > 0.0 ? Quat(Eigen::AngleAxisd(angle, v / angle)) : Quat::Identity();
}

/// Moves a body whose displacement in the solve goes from `before` to `after`
/// (translation, rotation vector; from where its planes were linearised). The rotation is
/// set from the total, not composed from the iterations' steps: rotations do not commute,
/// and iterates that turn a body and back must leave it where it was.
inline void displaceBody(RigidState& b, const Vec6& before, const Vec6& after) {
    b.position += after.head<3>() - before.head<3>();
    b.orientation = (rotationBy(after.tail<3>()) * rotationBy(before.tail<3>()).conjugate() * b.orientation).normalized();
}

}  // namespace tearables::detail
