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
// (v) x b = -[b]x v). A frame joint's coordinates, each locked (a penalty on its distance
// from its value) or limited (a one-sided one, as a hinge's angle):
//     linear:  q_i(d) = q_i0 + e_i . ((u_b + theta_b x r_b) - (u_a + theta_a x r_a))
//                     + (theta_a x e_i) . (p_b - p_a),
//     angular: phi(d) = phi0 + R (theta_a - theta_b),
// with e_i the axes of a's frame (they turn with a), p the pivots, r their arms from the
// centres of mass, and R the host's rates of its angles. The linear rows' forces, e_i f on
// a at p_b's line and -e_i f on b at p_b, have no net moment: the rows keep momentum.
// A quadratic in the bodies' displacements d, convex, so the island's
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
constexpr double kPi = 3.14159265358979323846;

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
            // A frame joint's coordinates stay the host's (startFrame turns their rows round).
            j.angle_sign = -j.angle_sign;  // the angle turns with theta_old_a - theta_old_b
            j.motor_velocity = -j.motor_velocity;  // and the motor's rate with omega_old_a - omega_old_b
            j.swapped = !j.swapped;
        }
        if (!j.pivot_a.allFinite() || !j.pivot_b.allFinite()) return false;
        if (j.kind == BodyJoint::Kind::Frame) {
            // An orthonormal frame, finite rates; a coordinate whose bounds are not
            // lower <= upper (or lock it at an infinite value) is free, as is an angle that is
            // not finite.
            if (!j.basis_a.allFinite() || !((j.basis_a.transpose() * j.basis_a - Mat3::Identity()).cwiseAbs().maxCoeff() < 1e-3) ||
                !j.angle_rates.allFinite())
                return false;
            const double inf = std::numeric_limits<double>::infinity();
            const auto bounded = [](double lower, double upper) { return lower <= upper && (lower < upper || std::isfinite(lower)); };
            for (int i = 0; i < 3; ++i) {
                if (!bounded(j.linear_lower[i], j.linear_upper[i])) j.linear_lower[i] = -inf, j.linear_upper[i] = inf;
                if (!bounded(j.angular_lower[i], j.angular_upper[i]) || !std::isfinite(j.angles[i]))
                    j.angular_lower[i] = -inf, j.angular_upper[i] = inf;
            }
            // A motor only with a finite rate and a positive, finite force (a servo with a
            // finite target too); a spring only with a finite rest, finite and non-negative
            // stiffness and damping.
            for (int k = 0; k < 6; ++k) {
                if (!(j.drive_force[k] > 0.0 && std::isfinite(j.drive_force[k]) && std::isfinite(j.drive_velocity[k]) &&
                      (!j.servo[k] || std::isfinite(j.servo_target[k]))))
                    j.drive_force[k] = 0.0;
                if (!(j.spring_stiffness[k] >= 0.0 && std::isfinite(j.spring_stiffness[k]) && j.spring_damping[k] >= 0.0 &&
                      std::isfinite(j.spring_damping[k]) && std::isfinite(j.spring_rest[k])))
                    j.spring_stiffness[k] = j.spring_damping[k] = 0.0;
            }
        }
        if (j.kind == BodyJoint::Kind::Gear && !(j.axis_a.allFinite() && j.axis_b.allFinite())) return false;
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
    const double linear_weight = kPairStiffnessFactor * mass * inv_h2, angular_weight = kPairStiffnessFactor * moment * inv_h2;
    ja_.setZero();
    jb_.setZero();
    r0_.setZero();
    weight_.setZero();
    limit_count_ = 0;
    motor_count_ = 0;
    spring_count_ = 0;
    move_a_ = pointJacobian(joint.pivot_a - a.position);
    move_b_ = b_moves_ ? Mat36(-pointJacobian(joint.pivot_b - rigids.bodies[joint.b.index].position)) : Mat36::Zero();
    if (joint.kind == BodyJoint::Kind::Frame) {
        startFrame(joint, rigids, linear_weight, angular_weight);
        return;
    }
    if (joint.kind == BodyJoint::Kind::Gear) {
        // The bodies' turns over the step about their axes, the free motion's (their
        // angular velocities now) and the solve's, held to a . theta_a + b . theta_b = 0: a
        // motor at rate 0 without a largest torque (Bullet's gear row is a velocity
        // constraint; it keeps no angle either).
        const Vec3 spin_b = joint.b.valid() ? rigids.bodies[joint.b.index].angular_velocity : Vec3::Zero();
        Motor& gear = motors_[motor_count_++];
        gear = Motor{};
        gear.ga.tail<3>() = joint.axis_a;
        if (b_moves_) gear.gb.tail<3>() = joint.axis_b;
        gear.offset = (joint.axis_a.dot(a.angular_velocity) + joint.axis_b.dot(spin_b)) * ctx.h;
        gear.force = std::numeric_limits<double>::infinity();
        gear.weight = kMotorStiffnessFactor * angular_weight;
        return;
    }
    r0_.head<3>() = (1.0 - kSeparationRecovery) * (joint.pivot_a - joint.pivot_b);
    ja_.topRows<3>() = move_a_;
    jb_.topRows<3>() = move_b_;
    weight_.head<3>().setConstant(linear_weight);
    if (joint.kind == BodyJoint::Kind::Hinge) {
        const Vec3& ax = joint.axis_a;
        const Vec3& bx = joint.axis_b;
        r0_.tail<3>() = (1.0 - kSeparationRecovery) * ax.cross(bx);
        ja_.bottomRightCorner<3, 3>() = cross(bx) * cross(ax);
        if (b_moves_) jb_.bottomRightCorner<3, 3>() = -cross(ax) * cross(bx);
        weight_.tail<3>().setConstant(angular_weight);
        if (std::isfinite(joint.lower) || std::isfinite(joint.upper)) {
            Limit& limit = limits_[limit_count_++];
            limit = Limit{};
            limit.value0 = joint.angle;
            limit.lower = joint.lower;
            limit.upper = joint.upper;
            limit.weight = angular_weight;
            limit.ga.tail<3>() = joint.angle_sign * ax;
            if (b_moves_) limit.gb.tail<3>() = -joint.angle_sign * ax;
        }
        if (joint.motor) {
            // The relative turn about the axis over the step: the free motion's (the bodies'
            // angular velocities now) and the solve's, against the motor's rate times h.
            const Vec3 spin_b = joint.b.valid() ? rigids.bodies[joint.b.index].angular_velocity : Vec3::Zero();
            Motor& motor = motors_[motor_count_++];
            motor = Motor{};
            motor.ga.tail<3>() = ax;
            if (b_moves_) motor.gb.tail<3>() = -ax;
            motor.offset = (ax.dot(a.angular_velocity - spin_b) - joint.motor_velocity) * ctx.h;
            motor.force = joint.motor_impulse * ctx.inv_h;
            motor.weight = kMotorStiffnessFactor * angular_weight;
        }
    }
}

// A frame joint's rows. Its coordinates are the host's (b relative to a), whose sides the
// solve may have turned round: each row's gradient is formed in the host's a and b and
// given to the solve's sides.
void BodyJointMember::startFrame(const BodyJoint& joint, const RigidTable& rigids, double linear_weight, double angular_weight) {
    const bool swapped = joint.swapped;
    const Vec3& pivot_a = swapped ? joint.pivot_b : joint.pivot_a;  // the host's
    const Vec3& pivot_b = swapped ? joint.pivot_a : joint.pivot_b;
    const RigidId host_a = swapped ? joint.b : joint.a, host_b = swapped ? joint.a : joint.b;
    const Vec3 centre_a = host_a.valid() ? rigids.bodies[host_a.index].position : pivot_a;
    const Vec3 centre_b = host_b.valid() ? rigids.bodies[host_b.index].position : pivot_b;
    const Vec3 offset = pivot_b - pivot_a;
    // The bodies' velocities (u, theta rates) for a motor's free motion; none for a fixed frame.
    const auto velocity = [&](RigidId id) {
        Vec6 v = Vec6::Zero();
        if (id.valid()) v << rigids.bodies[id.index].linear_velocity, rigids.bodies[id.index].angular_velocity;
        return v;
    };
    int locked = 0;
    for (int row = 0; row < 6; ++row) {
        const bool linear = row < 3;
        const int i = row % 3;
        const double lower = linear ? joint.linear_lower[i] : joint.angular_lower[i];
        const double upper = linear ? joint.linear_upper[i] : joint.angular_upper[i];
        const bool driven = joint.drive_force[row] > 0.0 && lower != upper;
        const bool sprung = (joint.spring_stiffness[row] > 0.0 || joint.spring_damping[row] > 0.0) && lower != upper;
        const double weight = linear ? linear_weight : angular_weight;
        if (!std::isfinite(lower) && !std::isfinite(upper) && !driven && !sprung) continue;  // free
        // The coordinate's gradient in the host's a and b (u, theta).
        Vec6 host_ga = Vec6::Zero(), host_gb = Vec6::Zero();
        double value;
        if (linear) {
            const Vec3 e = joint.basis_a.col(i);
            value = e.dot(offset);
            host_ga << -e, e.cross(pivot_b - centre_a);
            host_gb << e, (pivot_b - centre_b).cross(e);
        } else {
            value = joint.angles[i];
            host_ga.tail<3>() = joint.angle_rates.row(i).transpose();
            host_gb.tail<3>() = -joint.angle_rates.row(i).transpose();
        }
        Vec6 ga = swapped ? host_gb : host_ga, gb = swapped ? host_ga : host_gb;
        // The coordinate's rate now and its value where the step starts (the poses are the
        // free motion's, a step of h at these velocities on).
        const double rate = ga.dot(velocity(joint.a)) + gb.dot(velocity(joint.b));
        const double start = value - rate * h_;
        if (driven) {
            // The coordinate's change over the step: the free motion's (the bodies'
            // velocities now) and the solve's, against the motor's rate times h. A servo's
            // rate: toward its target at the motor's speed, the rest of the way where that
            // would pass it.
            double target_rate = joint.drive_velocity[row];
            if (joint.servo[row]) {
                double error = joint.servo_target[row] - start;
                if (!linear) error = std::remainder(error, 2.0 * kPi);
                const double speed = std::abs(joint.drive_velocity[row]);
                target_rate = std::clamp(error / h_, -speed, speed);
            }
            Motor& motor = motors_[motor_count_++];
            motor = Motor{};
            motor.ga = ga;
            motor.gb = b_moves_ ? gb : Vec6::Zero();
            motor.offset = (rate - target_rate) * h_;
            motor.force = joint.drive_force[row];
            motor.weight = kMotorStiffnessFactor * weight;
        }
        if (sprung) {
            // The elastic force -k (q - rest) where the step starts, held over it as Bullet's
            // solver applies it: with the positions stepped at the rate the step ends with,
            // symplectic Euler, which keeps an undamped spring's swing. The damper -c dq/dt
            // at the rate where the step ends (implicit): the rate where it starts already
            // carries gravity's h g, a force c h g that would hold a body at rest off its rest.
            Spring& spring = springs_[spring_count_++];
            spring.ga = ga;
            spring.gb = b_moves_ ? gb : Vec6::Zero();
            spring.force = -joint.spring_stiffness[row] * (start - joint.spring_rest[row]);
            spring.damping = joint.spring_damping[row];
            spring.offset = rate * h_;
        }
        if (!std::isfinite(lower) && !std::isfinite(upper)) continue;
        if (!b_moves_) gb.setZero();
        if (lower == upper) {
            r0_[locked] = (1.0 - kSeparationRecovery) * (value - lower);
            ja_.row(locked) = ga.transpose();
            jb_.row(locked) = gb.transpose();
            weight_[locked] = weight;
            ++locked;
            continue;
        }
        Limit& limit = limits_[limit_count_++];
        limit = Limit{};
        limit.ga = ga;
        limit.gb = gb;
        limit.value0 = value;
        limit.lower = lower;
        limit.upper = upper;
        limit.weight = weight;
    }
}

void BodyJointMember::condense(bool fresh) {
    Eigen::Matrix<double, 6, 12> j;
    j << ja_, jb_;
    const Eigen::Matrix<double, 6, 1> r = residual(disp_a_, disp_b_);
    hessian_ = j.transpose() * weight_.asDiagonal() * j;
    gradient_ = j.transpose() * weight_.cwiseProduct(r);
    for (int k = 0; k < motor_count_; ++k) {
        const Motor& motor = motors_[k];
        Eigen::Matrix<double, 12, 1> g;
        g << motor.ga, motor.gb;
        // Beyond its force the term is linear in |s|: its Hessian there is T / |s| (the
        // quadratic through the point that lies above the term, as friction's lagged weight
        // does), not zero, so that a step from a saturated motor stops near its rate instead
        // of running on under constant force against the bodies' inertia alone.
        const double slip = motor.slip(disp_a_, disp_b_);
        gradient_ += motor.pull(slip) * g;
        const double stiffness = std::abs(slip) * motor.weight < motor.force ? motor.weight : motor.force / std::abs(slip);
        hessian_ += stiffness * g * g.transpose();
    }
    for (int k = 0; k < spring_count_; ++k) {
        const Spring& spring = springs_[k];
        const Eigen::Matrix<double, 12, 1> g = spring.g();
        const double weight = spring.damping / h_;
        gradient_ += (weight * spring.change(disp_a_, disp_b_) - spring.force) * g;
        hessian_ += weight * g * g.transpose();
    }
    for (int k = 0; k < limit_count_; ++k) {
        Limit& limit = limits_[k];
        const double value = limit.at(disp_a_, disp_b_);
        if (fresh) limit.held = limit.past(value) != 0.0;
        if (!limit.held) continue;
        // Held inside the bounds (the step runs past one), the model carries the way to it:
        // k (phi + g . dd - bound)^2 / 2 with the bound the step runs past.
        Eigen::Matrix<double, 12, 1> g;
        g << limit.ga, limit.gb;
        const double after = limit.at(disp_a_ + du_a_, disp_b_ + du_b_);
        const double past = limit.past(value) != 0.0 ? limit.past(value) : value - (after < limit.lower ? limit.lower : limit.upper);
        hessian_ += limit.weight * g * g.transpose();
        gradient_ += limit.weight * past * g;
    }
}

// The limits' active set, as the contacts' (BodyContactMember::addPredictedContacts).
bool BodyJointMember::addPredictedContacts() {
    bool changed = false;
    for (int k = 0; k < limit_count_; ++k) {
        Limit& limit = limits_[k];
        const double after = limit.past(limit.at(disp_a_ + du_a_, disp_b_ + du_b_));
        const double now = limit.past(limit.at(disp_a_, disp_b_));
        if (!limit.held && after != 0.0) {
            limit.held = true;
            changed = true;
        } else if (limit.held && after == 0.0 && now == 0.0) {
            limit.held = false;
            changed = true;
        }
    }
    return changed;
}

double BodyJointMember::energy(double alpha) const {
    const Vec6 da = disp_a_ + alpha * du_a_, db = disp_b_ + alpha * du_b_;
    const Eigen::Matrix<double, 6, 1> r = residual(da, db);
    double e = 0.5 * r.dot(weight_.cwiseProduct(r));
    for (int k = 0; k < limit_count_; ++k) {
        const double past = limits_[k].past(limits_[k].at(da, db));
        e += 0.5 * limits_[k].weight * past * past;
    }
    for (int k = 0; k < motor_count_; ++k) {
        // Huber's function of the slip: k s^2 / 2 within the force's reach, then linear.
        const Motor& motor = motors_[k];
        const double slip = std::abs(motor.slip(da, db)), reach = motor.force / motor.weight;
        e += slip < reach ? 0.5 * motor.weight * slip * slip : motor.force * (slip - 0.5 * reach);
    }
    for (int k = 0; k < spring_count_; ++k) {
        const Spring& spring = springs_[k];
        const double change = spring.change(da, db);
        e += 0.5 * spring.damping / h_ * change * change - spring.force * (change - spring.offset);
    }
    return e;
}

// The joint's forces at the solution: minus the energy's gradient in each body's
// displacement (u, theta), the force and the torque about its centre of mass; times h.
void BodyJointMember::finish(int) {
    const Eigen::Matrix<double, 6, 1> f = weight_.cwiseProduct(residual(disp_a_, disp_b_));
    Vec6 on_a = -(ja_.transpose() * f), on_b = -(jb_.transpose() * f);
    for (int k = 0; k < limit_count_; ++k) {
        const Limit& limit = limits_[k];
        const double past = limit.past(limit.at(disp_a_, disp_b_));
        on_a -= limit.weight * past * limit.ga;
        on_b -= limit.weight * past * limit.gb;
    }
    for (int k = 0; k < motor_count_; ++k) {
        const Motor& motor = motors_[k];
        const double pull = motor.pull(motor.slip(disp_a_, disp_b_));
        on_a -= pull * motor.ga;
        on_b -= pull * motor.gb;
    }
    for (int k = 0; k < spring_count_; ++k) {
        const Spring& spring = springs_[k];
        const double force = spring.force - spring.damping / h_ * spring.change(disp_a_, disp_b_);
        on_a += force * spring.ga;
        on_b += force * spring.gb;
    }
    joint_->impulse_a = h_ * on_a.head<3>();
    joint_->angular_impulse_a = h_ * on_a.tail<3>();
    if (b_moves_) {
        joint_->impulse_b = h_ * on_b.head<3>();
        joint_->angular_impulse_b = h_ * on_b.tail<3>();
    }
}

double BodyJointMember::apply(double alpha, const std::vector<int>& slot, const Eigen::VectorXd& displacement) {
    const double move = alpha * (move_a_ * du_a_ + move_b_ * du_b_).norm();
    takeDisplacements(slot, displacement);
    return move / kPairMoveTolerance;
}

}  // namespace tearables::detail
