// A joint between bodies as a member of an island (sim/island.hpp): a ball joint, a hinge
// or a frame joint (a slider, a 6-dof joint, a weld) the host handed over (BodyJoint),
// solved in the same Newton system as the strings that hold the bodies and the contacts
// between them, so that no solver undoes another.
#pragma once

#include "island/body_pair.hpp"

#include <algorithm>
#include <array>
#include <vector>

namespace tearables::detail {

class BodyJointMember final : public BodyPairMember {
public:
    /// Joint `joint` (prepared: a movable, b movable or fixed) at the table's poses.
    /// `joint` receives the impulses it gave (BodyJoint::impulse_a, ...) at finish().
    void start(BodyJoint& joint, const RigidTable& rigids, const StepContext& ctx);

    void condense(bool fresh) override;
    bool addPredictedContacts() override;
    double energy(double alpha) const override;
    double apply(double alpha, const std::vector<int>& slot, const Eigen::VectorXd& displacement) override;
    bool frictional() const override { return false; }
    double reweigh() override { return 0.0; }
    void finish(int) override;

private:
    /// A frame joint's rows: its locked coordinates into the residuals, its limited ones
    /// into limits_, its motors into motors_.
    void startFrame(const BodyJoint& joint, const RigidTable& rigids, double linear_weight, double angular_weight);

    /// The joint's residuals for the bodies' displacements d = (u, theta) from where the
    /// solve started, linearised there, each r0 + Ja d_a + Jb d_b: the pivots' separation
    /// and, for a hinge, the axes' cross product (zero rows for a ball joint); for a frame
    /// joint its locked coordinates less their values (zero rows for the others).
    Eigen::Matrix<double, 6, 1> residual(const Vec6& da, const Vec6& db) const {
        return r0_ + ja_ * da + jb_ * db;
    }

    /// A one-sided coordinate: a hinge's angle, or a frame joint's limited coordinate,
    /// linearised where the solve started (value0 + ga . d_a + gb . d_b), with its bounds
    /// and the stiffness of its penalty past them.
    struct Limit {
        Vec6 ga = Vec6::Zero(), gb = Vec6::Zero();
        double value0 = 0.0, lower = 0.0, upper = 0.0, weight = 0.0;
        bool held = false;  ///< in the Newton system (past a bound, or the step runs past one)
        double at(const Vec6& da, const Vec6& db) const { return value0 + ga.dot(da) + gb.dot(db); }
        /// How far the coordinate is past the nearer bound (0 within them).
        double past(double value) const { return value < lower ? value - lower : value > upper ? value - upper : 0.0; }
    };

    /// A motor: a coordinate (a hinge's turn about its axis, a frame joint's coordinate)
    /// driven at a rate with at most a force or torque T. Its slip for the displacements is
    /// the coordinate's change over the step less the rate times h, s = offset + ga . d_a +
    /// gb . d_b (offset: the free motion's change, from the bodies' velocities now, less
    /// the rate times h). Its energy is Huber's function of s, k s^2 / 2 up to T (|s| =
    /// T / k) and T |s| - T^2 / 2k beyond: the motor holds its rate stiffly (k ten times the
    /// limits') and gives way at its largest force, a convex term (as Coulomb friction).
    struct Motor {
        Vec6 ga = Vec6::Zero(), gb = Vec6::Zero();
        double offset = 0.0, force = 0.0, weight = 0.0;
        double slip(const Vec6& da, const Vec6& db) const { return offset + ga.dot(da) + gb.dot(db); }
        /// The energy's derivative in the slip: k s within the largest force, else +-T.
        double pull(double s) const { return std::clamp(weight * s, -force, force); }
    };

    /// A spring on a coordinate: its elastic force held over the step (read where it
    /// starts), the energy's term -force (ga . d_a + gb . d_b); and its damper on the
    /// coordinate's rate where the step ends, (change / h), the change over the step
    /// offset + ga . d_a + gb . d_b: the term damping / (2 h) change^2, convex.
    struct Spring {
        Vec6 ga = Vec6::Zero(), gb = Vec6::Zero();
        double force = 0.0, damping = 0.0, offset = 0.0;
        double change(const Vec6& da, const Vec6& db) const { return offset + ga.dot(da) + gb.dot(db); }
        Eigen::Matrix<double, 12, 1> g() const {
            Eigen::Matrix<double, 12, 1> out;
            out << ga, gb;
            return out;
        }
    };

    BodyJoint* joint_ = nullptr;  ///< where finish() writes the impulses
    double h_ = 0.0;
    Mat36 move_a_ = Mat36::Zero(), move_b_ = Mat36::Zero();  ///< the pivots' relative move in d_a, d_b (apply)
    std::array<Limit, 6> limits_;  ///< the first limit_count_ are the joint's
    int limit_count_ = 0;
    std::array<Motor, 6> motors_;  ///< the first motor_count_ are the joint's
    int motor_count_ = 0;
    std::array<Spring, 6> springs_;  ///< the first spring_count_ are the joint's
    int spring_count_ = 0;
    Eigen::Matrix<double, 6, 1> r0_ = Eigen::Matrix<double, 6, 1>::Zero();
    Eigen::Matrix<double, 6, 6> ja_ = Eigen::Matrix<double, 6, 6>::Zero(), jb_ = Eigen::Matrix<double, 6, 6>::Zero();
    Eigen::Matrix<double, 6, 1> weight_ = Eigen::Matrix<double, 6, 1>::Zero();  ///< per residual: its stiffness
};

/// The joints the island solve keeps: of a movable body (with a movable one or a fixed
/// frame), finite, with unit axes; a joint whose a is fixed and b movable is turned round.
void prepareBodyJoints(std::vector<BodyJoint>& joints, const RigidTable& rigids);

}  // namespace tearables::detail
