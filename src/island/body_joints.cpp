// Joints between bodies in an island (body_joints.hpp).
//
// A joint adds to the island's energy stiff penalties on its residuals, linearised where the
// solve started as the body contacts' gaps are (body_contacts.cpp):
//     pivots:  e(d) = (1 - beta) e0 + (u_a + theta_a x r_a) - (u_b + theta_b x r_b),
//     hinge:   c(d) = (1 - beta) (a x b) + [b]x [a]x theta_a - [a]x [b]x theta_b,
//     limits:  phi(d) = phi0 + sign a . (theta_a - theta_b)   (a hinge's angle),
// k/2 |e|^2 + k_theta/2 |c|^2 + k_theta/2 (phi - clamp(phi, lower, upper))^2 (a one-sided
// penalty past either limit, held as a contact's: where it is past it, or where the step
// runs past it), with e0 the pivots' separation and a x b the axes'
// misalignment where the step starts (a turned by theta: a + theta x a = a - [a]x theta, and
// (v) x b = -[b]x v). A quadratic in the bodies' displacements d, convex, so the island's
// Newton iteration with its line search converges as with contacts. beta: the share of a
// separation found at the start (the linearisation's second order, left by the last step)
// that the step takes back, as Bullet's joints' ERP (0.2) does; all of it at once would
// throw the bodies apart at e0 / h.
#include "island/body_joints.hpp"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <limits>

namespace tearables::detail {

namespace {

/// The share of the start's separation a step takes back (Bullet's joint ERP).
constexpr double kSeparationRecovery = 0.2;
/// A motor's stiffness over the limits': under a load torque L it turns slower than its
/// rate by L / (k h), 1/kMotorStiffnessFactor of what the limits' stiffness would give (a
/// 5 kg boom lifting 2 kg at 1 m: 0.2% of 0.5 rad/s instead of 2%).
constexpr double kMotorStiffnessFactor = 10.0;

/// The body's largest principal moment of inertia, kg m^2 (its mass times a square metre
/// where the inertia is not finite: a body that does not turn).
double largestMoment(const RigidState& b) {
    const double smallest = Eigen::SelfAdjointEigenSolver<Mat3>(b.inverseInertiaWorld(), Eigen::EigenvaluesOnly).eigenvalues().minCoeff();
    return smallest > 0.0 && std::isfinite(1.0 / smallest) ? 1.0 / smallest : 1.0 / b.inverse_mass;
}

}  // namespace

void prepareBodyJoints(std::vector<BodyJoint>& joints, const RigidTable& rigids) {
    auto keep = [&](BodyJoint& j) {
        const PairOrder order = orderPair(j.a, j.b, rigids);
        if (order == PairOrder::Drop) return false;
        if (order == PairOrder::Swap) {
            std::swap(j.a, j.b);
            std::swap(j.pivot_a, j.pivot_b);
            std::swap(j.axis_a, j.axis_b);
            j.angle_sign = -j.angle_sign;  // the angle turns with theta_old_a - theta_old_b
            j.motor_velocity = -j.motor_velocity;  // and the motor's rate with omega_old_a - omega_old_b
            j.swapped = !j.swapped;
        }
        if (!j.pivot_a.allFinite() || !j.pivot_b.allFinite()) return false;
        if (j.kind == BodyJoint::Kind::Hinge) {
            for (Vec3* axis : {&j.axis_a, &j.axis_b}) {
                const double n = axis->norm();
                if (!(std::abs(n - 1.0) < 1e-3)) return false;
                *axis /= n;
            }
            // Limits only with a finite angle, a sign of +-1 and lower <= upper (else none).
            const bool limits = std::isfinite(j.angle) && std::abs(std::abs(j.angle_sign) - 1.0) < 1e-9 &&
                                !std::isnan(j.lower) && !std::isnan(j.upper) && j.lower <= j.upper;
            if (!limits) {
                j.lower = -std::numeric_limits<double>::infinity();
                j.upper = std::numeric_limits<double>::infinity();
            }
            // A motor only with a finite rate and a positive, finite impulse.
            j.motor = j.motor && std::isfinite(j.motor_velocity) && j.motor_impulse > 0.0 && std::isfinite(j.motor_impulse);
        }
        return true;
    };
    joints.erase(std::remove_if(joints.begin(), joints.end(), [&](BodyJoint& j) { return !keep(j); }), joints.end());
}

void BodyJointMember::start(BodyJoint& joint, const RigidTable& rigids, const StepContext& ctx) {
    joint_ = &joint;
    h_ = ctx.h;
    joint.impulse_a.setZero();
    joint.angular_impulse_a.setZero();
    joint.impulse_b.setZero();
    joint.angular_impulse_b.setZero();
    const RigidState& a = rigids.bodies[joint.a.index];
    startPair(joint.a, joint.b, rigids);
    double mass = 1.0 / a.inverse_mass, moment = largestMoment(a);
    if (b_moves_) {
        const RigidState& b = rigids.bodies[joint.b.index];
        mass = std::max(mass, 1.0 / b.inverse_mass);
        moment = std::max(moment, largestMoment(b));
    }
    const double inv_h2 = ctx.inv_h * ctx.inv_h;
    ja_.setZero();
    jb_.setZero();
    r0_.setZero();
    weight_.setZero();
    r0_.head<3>() = (1.0 - kSeparationRecovery) * (joint.pivot_a - joint.pivot_b);
    ja_.topRows<3>() = pointJacobian(joint.pivot_a - a.position);
    if (b_moves_) jb_.topRows<3>() = -pointJacobian(joint.pivot_b - rigids.bodies[joint.b.index].position);
    weight_.head<3>().setConstant(kPairStiffnessFactor * mass * inv_h2);
    if (joint.kind == BodyJoint::Kind::Hinge) {
        const Vec3& ax = joint.axis_a;
        const Vec3& bx = joint.axis_b;
        r0_.tail<3>() = (1.0 - kSeparationRecovery) * ax.cross(bx);
        ja_.bottomRightCorner<3, 3>() = cross(bx) * cross(ax);
        if (b_moves_) jb_.bottomRightCorner<3, 3>() = -cross(ax) * cross(bx);
        weight_.tail<3>().setConstant(kPairStiffnessFactor * moment * inv_h2);
        limited_ = std::isfinite(joint.lower) || std::isfinite(joint.upper);
        angle0_ = joint.angle;
        lower_ = joint.lower;
        upper_ = joint.upper;
        limit_weight_ = kPairStiffnessFactor * moment * inv_h2;
        ga_.setZero();
        gb_.setZero();
        ga_.tail<3>() = joint.angle_sign * ax;
        if (b_moves_) gb_.tail<3>() = -joint.angle_sign * ax;
        motor_ = joint.motor;
        if (motor_) {
            // The relative turn about the axis over the step: the free motion's (the bodies'
            // angular velocities now) and the solve's, against the motor's rate times h.
            const Vec3 spin_b = joint.b.valid() ? rigids.bodies[joint.b.index].angular_velocity : Vec3::Zero();
            motor_a_.setZero();
            motor_b_.setZero();
            motor_a_.tail<3>() = ax;
            if (b_moves_) motor_b_.tail<3>() = -ax;
            motor_offset_ = (ax.dot(a.angular_velocity - spin_b) - joint.motor_velocity) * ctx.h;
            motor_torque_ = joint.motor_impulse * ctx.inv_h;
            motor_weight_ = kMotorStiffnessFactor * limit_weight_;
        }
    } else {
        limited_ = false;
        motor_ = false;
    }
    limit_held_ = false;
}

void BodyJointMember::condense(bool fresh) {
    Eigen::Matrix<double, 6, 12> j;
    j << ja_, jb_;
    const Eigen::Matrix<double, 6, 1> r = residual(disp_a_, disp_b_);
    hessian_ = j.transpose() * weight_.asDiagonal() * j;
    gradient_ = j.transpose() * weight_.cwiseProduct(r);
    if (motor_) {
        Eigen::Matrix<double, 12, 1> g;
        g << motor_a_, motor_b_;
        // Beyond its torque the term is linear in |s|: its Hessian there is T / |s| (the
        // quadratic through the point that lies above the term, as friction's lagged weight
        // does), not zero, so that a step from a saturated motor stops near its rate instead
        // of running on under constant torque against the bodies' inertia alone.
        const double slip = motorSlip(disp_a_, disp_b_);
        gradient_ += motorTorque(slip) * g;
        const double stiffness = std::abs(slip) * motor_weight_ < motor_torque_ ? motor_weight_ : motor_torque_ / std::abs(slip);
        hessian_ += stiffness * g * g.transpose();
    }
    if (!limited_) return;
    const double angle = angleAt(disp_a_, disp_b_);
    if (fresh) limit_held_ = pastLimit(angle) != 0.0;
    if (!limit_held_) return;
    // Held inside the limits (the step runs past one), the model carries the way to it:
    // k (phi + g . dd - limit)^2 / 2 with the limit the step runs past.
    Eigen::Matrix<double, 12, 1> g;
    g << ga_, gb_;
    const Vec6 full_a = disp_a_ + du_a_, full_b = disp_b_ + du_b_;
    const double past = pastLimit(angle) != 0.0 ? pastLimit(angle) : angle - (angleAt(full_a, full_b) < lower_ ? lower_ : upper_);
    hessian_ += limit_weight_ * g * g.transpose();
    gradient_ += limit_weight_ * past * g;
}

// The limit's active set, as the contacts' (BodyContactMember::addPredictedContacts).
bool BodyJointMember::addPredictedContacts() {
    if (!limited_) return false;
    const double after = pastLimit(angleAt(disp_a_ + du_a_, disp_b_ + du_b_));
    const double now = pastLimit(angleAt(disp_a_, disp_b_));
    if (!limit_held_ && after != 0.0) {
        limit_held_ = true;
        return true;
    }
    if (limit_held_ && after == 0.0 && now == 0.0) {
        limit_held_ = false;
        return true;
    }
    return false;
}

double BodyJointMember::energy(double alpha) const {
    const Vec6 da = disp_a_ + alpha * du_a_, db = disp_b_ + alpha * du_b_;
    const Eigen::Matrix<double, 6, 1> r = residual(da, db);
    double e = 0.5 * r.dot(weight_.cwiseProduct(r));
    if (limited_) {
        const double past = pastLimit(angleAt(da, db));
        e += 0.5 * limit_weight_ * past * past;
    }
    if (motor_) {
        // Huber's function of the slip: k s^2 / 2 within the torque's reach, then linear.
        const double slip = std::abs(motorSlip(da, db)), reach = motor_torque_ / motor_weight_;
        e += slip < reach ? 0.5 * motor_weight_ * slip * slip : motor_torque_ * (slip - 0.5 * reach);
    }
    return e;
}

// The joint's forces at the solution: minus the energy's gradient in each body's
// displacement (u, theta), the force and the torque about its centre of mass; times h.
void BodyJointMember::finish(int) {
    const Eigen::Matrix<double, 6, 1> f = weight_.cwiseProduct(residual(disp_a_, disp_b_));
    Vec6 on_a = -(ja_.transpose() * f), on_b = -(jb_.transpose() * f);
    if (limited_) {
        const double past = pastLimit(angleAt(disp_a_, disp_b_));
        on_a -= limit_weight_ * past * ga_;
        on_b -= limit_weight_ * past * gb_;
    }
    if (motor_) {
        const double torque = motorTorque(motorSlip(disp_a_, disp_b_));
        on_a -= torque * motor_a_;
        on_b -= torque * motor_b_;
    }
    joint_->impulse_a = h_ * on_a.head<3>();
    joint_->angular_impulse_a = h_ * on_a.tail<3>();
    if (b_moves_) {
        joint_->impulse_b = h_ * on_b.head<3>();
        joint_->angular_impulse_b = h_ * on_b.tail<3>();
    }
}

double BodyJointMember::apply(double alpha, const std::vector<int>& slot, const Eigen::VectorXd& displacement) {
    const double move = alpha * (ja_.topRows<3>() * du_a_ + jb_.topRows<3>() * du_b_).norm();
    takeDisplacements(slot, displacement);
    return move / kPairMoveTolerance;
}

}  // namespace tearables::detail
