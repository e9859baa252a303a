// The Bullet adapter: converts and forwards. Bullet calls Action::updateAction once per
// internal step, after it has integrated the rigid bodies; we copy the bodies that strings
// hold into the core's proxies, step the core, and write the bodies' corrected poses and
// velocities back.
#include "bullet_world_impl.hpp"

#include "tearables/colormap.hpp"

#include "island_claim.hpp"

#include <BulletCollision/CollisionShapes/btEmptyShape.h>
#include <btBulletDynamicsCommon.h>
#include <BulletCollision/BroadphaseCollision/btDbvt.h>
#include <BulletCollision/CollisionShapes/btTriangleShape.h>
#include <BulletCollision/NarrowPhaseCollision/btGjkEpaPenetrationDepthSolver.h>
#include <BulletCollision/NarrowPhaseCollision/btGjkPairDetector.h>
#include <BulletCollision/NarrowPhaseCollision/btPointCollector.h>
#include <BulletCollision/NarrowPhaseCollision/btVoronoiSimplexSolver.h>

#include <algorithm>
#include <climits>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <map>
#include <memory>
#include <exception>
#include <functional>

namespace tearables {

namespace {

/// Whether the island solve takes joint c from Bullet (BodyJoint): a ball joint
/// (btPoint2PointConstraint); a hinge (btHingeConstraint, its limits as hard stops, its
/// motor) not in angular-only mode; a cone-twist joint (btConeTwistConstraint, its cone and
/// twist limits; no motor); a slider (btSliderConstraint, its powered motors); a
/// 6-dof joint (btGeneric6DofConstraint and btUniversalConstraint; btGeneric6DofSpring2Constraint,
/// btFixedConstraint and btHinge2Constraint, with their motors, servos and springs); enabled
/// (a breaking impulse is checked after the step, writeJointImpulses); a gear
/// (btGearConstraint). Others (the older spring 6-dof, a cone-twist joint's motor or fixed
/// spans) leave their islands to Bullet.
bool islandJoint(const btTypedConstraint& c) {
    if (!c.isEnabled()) return false;
    auto& joint = const_cast<btTypedConstraint&>(c);  // Bullet's getters are not const
    switch (c.getConstraintType()) {
    case POINT2POINT_CONSTRAINT_TYPE:
        return true;
    case HINGE_CONSTRAINT_TYPE:
        return !static_cast<btHingeConstraint&>(joint).getAngularOnly();
    case SLIDER_CONSTRAINT_TYPE:
    case D6_CONSTRAINT_TYPE:
    case D6_SPRING_2_CONSTRAINT_TYPE:
    case GEAR_CONSTRAINT_TYPE:
        return true;
    case CONETWIST_CONSTRAINT_TYPE: {
        // A cone and a twist limit (frameJoint): not angular-only, no motor, and spans
        // Bullet solves as a cone (both swing spans at least its fix threshold).
        auto& cone = static_cast<btConeTwistConstraint&>(joint);
        return !cone.getAngularOnly() && !cone.isMotorEnabled() && cone.getSwingSpan1() >= cone.getFixThresh() &&
               cone.getSwingSpan2() >= cone.getFixThresh() && cone.getTwistSpan() >= cone.getFixThresh();
    }
    default:
        return false;
    }
}

Quat toCore(const btQuaternion& q) { return Quat(q.w(), q.x(), q.y(), q.z()); }
btQuaternion toBullet(const Quat& q) {
    return btQuaternion(static_cast<btScalar>(q.x()), static_cast<btScalar>(q.y()), static_cast<btScalar>(q.z()),
                        static_cast<btScalar>(q.w()));
}

constexpr double kPi = 3.14159265358979323846;

Mat3 basisToCore(const btMatrix3x3& m) {
    Mat3 out;
    for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) out(r, c) = static_cast<double>(m[r][c]);
    return out;
}

/// Bullet's bounds of a joint coordinate as BodyJoint's: lower > upper leaves it free.
void bulletBounds(btScalar lower, btScalar upper, double& lo, double& hi) {
    const double inf = std::numeric_limits<double>::infinity();
    lo = lower > upper ? -inf : static_cast<double>(lower);
    hi = lower > upper ? inf : static_cast<double>(upper);
}

/// A 6-dof joint's frames at the bodies' poses ta and tb, its bounds into `j`, and its
/// angles for a pose of b (Bullet's Euler angles of b's frame relative to a's, after
/// calculateTransforms). btGeneric6DofConstraint and btGeneric6DofSpring2Constraint share
/// these methods, not a base.
template <class SixDof>
std::function<Vec3(const btTransform&)> readSixDof(SixDof& d6, const btTransform& ta, const btTransform& tb, btTransform& fa,
                                                   btTransform& fb, BodyJoint& j) {
    d6.calculateTransforms(ta, tb);
    fa = d6.getCalculatedTransformA();
    fb = d6.getCalculatedTransformB();
    btVector3 lin_lo, lin_hi, ang_lo, ang_hi;
    d6.getLinearLowerLimit(lin_lo);
    d6.getLinearUpperLimit(lin_hi);
    d6.getAngularLowerLimit(ang_lo);
    d6.getAngularUpperLimit(ang_hi);
    for (int i = 0; i < 3; ++i) {
        bulletBounds(lin_lo[i], lin_hi[i], j.linear_lower[i], j.linear_upper[i]);
        bulletBounds(ang_lo[i], ang_hi[i], j.angular_lower[i], j.angular_upper[i]);
    }
    return [&d6, ta](const btTransform& b) {
        d6.calculateTransforms(ta, b);
        return Vec3(static_cast<double>(d6.getAngle(0)), static_cast<double>(d6.getAngle(1)), static_cast<double>(d6.getAngle(2)));
    };
}

/// A 6-dof joint's velocity motors into `j` (frameJoint has the signs): a linear row along
/// a's axis i runs coordinate i at minus its target; an angular one goes to angularDrive.
template <class SixDof, class AngularDrive>
void readSixDofMotors(SixDof& d6, BodyJoint& j, const AngularDrive& angularDrive) {
    const auto& linear = *d6.getTranslationalLimitMotor();
    for (int i = 0; i < 3; ++i) {
        if (linear.m_enableMotor[i]) {
            j.drive_velocity[i] = -static_cast<double>(linear.m_targetVelocity[i]);
            j.drive_force[i] = static_cast<double>(linear.m_maxMotorForce[i]);
        }
        const auto& angular = *d6.getRotationalLimitMotor(i);
        if (angular.m_enableMotor) angularDrive(i, d6.getAxis(i), angular.m_targetVelocity, angular.m_maxMotorForce);
    }
}

/// btGeneric6DofSpring2Constraint's servos and springs into `j`, for internal steps of h.
/// A servo is a motor readSixDofMotors read, its speed the size of the rate it gave. Where
/// the joint limits a spring (setStiffness and setDamping do by default), its stiffness and
/// damping are Bullet's limited ones (btGeneric6DofSpring2Constraint::get_limit_motor_info2):
/// the stiffness at most m / (16 h^2), so that the spring's angular frequency is at most a
/// quarter of the rate of steps, and the damping at most m / h, with m the lighter body's
/// mass (about an angle's axis: its mass times its arm squared plus its moment about the
/// axis).
void readSpring2(btGeneric6DofSpring2Constraint& d6, double h, BodyJoint& j) {
    const btRigidBody& a = d6.getRigidBodyA();
    const btRigidBody& b = d6.getRigidBodyB();
    const auto mass = [&](bool angular, const btVector3& axis) {
        double lightest = std::numeric_limits<double>::infinity();
        for (const btRigidBody* body : {&a, &b}) {
            if (!(body->getInvMass() > 0)) continue;
            double m = 1.0 / static_cast<double>(body->getInvMass());
            if (angular) {
                const btTransform& frame = body == &a ? d6.getCalculatedTransformA() : d6.getCalculatedTransformB();
                const double arm2 = static_cast<double>((frame.getOrigin() - body->getCenterOfMassPosition()).length2());
                m = m * arm2 + 1.0 / static_cast<double>((body->getInvInertiaTensorWorld() * axis).length());
            }
            lightest = std::min(lightest, m);
        }
        return lightest;
    };
    const auto spring = [&](int row, bool enabled, btScalar stiffness, bool stiffness_limited, btScalar damping,
                            bool damping_limited, btScalar rest, bool angular, const btVector3& axis) {
        if (!enabled) return;
        double k = static_cast<double>(stiffness), c = static_cast<double>(damping);
        const double m = mass(angular, axis);
        if (stiffness_limited && std::sqrt(k / m) * h > 0.25) k = m / (16.0 * h * h);
        if (damping_limited && c * h > m) c = m / h;
        j.spring_stiffness[static_cast<std::size_t>(row)] = k;
        j.spring_damping[static_cast<std::size_t>(row)] = c;
        j.spring_rest[static_cast<std::size_t>(row)] = static_cast<double>(rest);
    };
    const btTranslationalLimitMotor2& linear = *d6.getTranslationalLimitMotor();
    for (int i = 0; i < 3; ++i) {
        const auto row = static_cast<std::size_t>(i);
        if (linear.m_enableMotor[i] && linear.m_servoMotor[i]) {
            j.servo[row] = true;
            j.servo_target[row] = static_cast<double>(linear.m_servoTarget[i]);
            j.drive_velocity[row] = std::abs(j.drive_velocity[row]);
        }
        spring(i, linear.m_enableSpring[i], linear.m_springStiffness[i], linear.m_springStiffnessLimited[i],
               linear.m_springDamping[i], linear.m_springDampingLimited[i], linear.m_equilibriumPoint[i], false, d6.getAxis(i));
        const btRotationalLimitMotor2& angular = *d6.getRotationalLimitMotor(i);
        if (angular.m_enableMotor && angular.m_servoMotor) {
            j.servo[3 + row] = true;
            j.servo_target[3 + row] = static_cast<double>(angular.m_servoTarget);
            j.drive_velocity[3 + row] = std::abs(j.drive_velocity[3 + row]);
        }
        spring(3 + i, angular.m_enableSpring, angular.m_springStiffness, angular.m_springStiffnessLimited,
               angular.m_springDamping, angular.m_springDampingLimited, angular.m_equilibriumPoint, true, d6.getAxis(i));
    }
}

/// A frame joint (BodyJoint::Kind::Frame) from a cone-twist joint, a slider or a 6-dof joint
/// at the bodies' poses ta and tb (islandJoint's types): its frames, Bullet's coordinates and bounds (a
/// coordinate Bullet leaves free, lower > upper, is free), and how its angles turn,
/// measured by small turns of b's pose about each world axis (Bullet's angle conventions,
/// Euler angles in a joint's rotation order, have no rates to read).
BodyJoint frameJoint(btTypedConstraint& c, const btTransform& ta, const btTransform& tb, double h) {
    BodyJoint j;
    j.kind = BodyJoint::Kind::Frame;
    std::function<Vec3(const btTransform&)> angles;  // of b's frame relative to a's, b at a pose
    btTransform fa, fb;
    if (c.getConstraintType() == CONETWIST_CONSTRAINT_TYPE) {
        // Bullet's cone-twist joint: b's frame relative to a's, q = q_a^-1 q_b, is a swing
        // (the shortest turn taking a's x axis to b's) after a twist about x. The twist is
        // limited to +-twistSpan; the swing, a rotation vector phi in a's (y, z) plane, to an
        // ellipse (btConeTwistConstraint::computeConeLimitInfo): its angle at most
        // 1 / sqrt(y^2 / span2^2 + z^2 / span1^2) along the unit direction (y, z), that is
        // |(phi_y / span2, phi_z / span1)| <= 1, the coordinate given here.
        auto& cone = static_cast<btConeTwistConstraint&>(c);
        fa = ta * cone.getAFrame();
        fb = tb * cone.getBFrame();
        const double inf = std::numeric_limits<double>::infinity();
        j.angular_lower = Vec3(-static_cast<double>(cone.getTwistSpan()), -inf, -inf);
        j.angular_upper = Vec3(static_cast<double>(cone.getTwistSpan()), 1.0, inf);
        if (cone.getTwistSpan() >= btScalar(kPi)) j.angular_lower.x() = -inf, j.angular_upper.x() = inf;
        const double span1 = static_cast<double>(cone.getSwingSpan1()), span2 = static_cast<double>(cone.getSwingSpan2());
        angles = [fa, &cone, span1, span2](const btTransform& b) {
            const btQuaternion q = fa.getRotation().inverse() * (b * cone.getBFrame()).getRotation();  // in a's frame
            const btVector3 x(1, 0, 0);
            const btQuaternion swing = shortestArcQuat(x, quatRotate(q, x));
            const btQuaternion twist = swing.inverse() * q;
            const double twist_angle = 2.0 * std::atan2(static_cast<double>(twist.x()), static_cast<double>(twist.w()));
            // The swing's rotation vector (its axis lies in a's (y, z) plane): its angle,
            // 2 atan2(|v|, w) of the quaternion (w, v), along v.
            const double norm = std::sqrt(static_cast<double>(swing.y() * swing.y() + swing.z() * swing.z()));
            const double scale = norm > 0.0 ? 2.0 * std::atan2(norm, static_cast<double>(swing.w())) / norm : 2.0;
            const double phi_y = scale * static_cast<double>(swing.y()), phi_z = scale * static_cast<double>(swing.z());
            return Vec3(twist_angle, std::hypot(phi_y / span2, phi_z / span1), 0.0);
        };
    } else if (c.getConstraintType() == SLIDER_CONSTRAINT_TYPE) {
        auto& slider = static_cast<btSliderConstraint&>(c);
        fa = ta * slider.getFrameOffsetA();
        fb = tb * slider.getFrameOffsetB();
        // Bullet's slider: a's x axis is the slide; b's position along it, from a's pivot
        // (from b's to a's where the linear reference is b's); its turn about it, b's y axis
        // in a's (y, z); about a's y and z axes, the x axes' misalignment (ax x bx).
        const btScalar lower = slider.getLowerLinLimit(), upper = slider.getUpperLinLimit();
        bulletBounds(lower, upper, j.linear_lower.x(), j.linear_upper.x());
        if (!slider.getUseLinearReferenceFrameA() && lower <= upper) {
            j.linear_lower.x() = -static_cast<double>(upper);
            j.linear_upper.x() = -static_cast<double>(lower);
        }
        const btScalar ang_lower = slider.getLowerAngLimit(), ang_upper = slider.getUpperAngLimit();
        bulletBounds(ang_lower, ang_upper, j.angular_lower.x(), j.angular_upper.x());
        angles = [fa, &slider](const btTransform& b) {
            const btMatrix3x3 frame_b = b.getBasis() * slider.getFrameOffsetB().getBasis();
            const btVector3 ax = fa.getBasis().getColumn(0), ay = fa.getBasis().getColumn(1), az = fa.getBasis().getColumn(2);
            const btVector3 by = frame_b.getColumn(1), misalign = ax.cross(frame_b.getColumn(0));
            btScalar turn = btAtan2(by.dot(az), by.dot(ay));
            if (slider.getLowerAngLimit() <= slider.getUpperAngLimit())
                turn = btAdjustAngleToLimits(turn, slider.getLowerAngLimit(), slider.getUpperAngLimit());
            return Vec3(static_cast<double>(turn), static_cast<double>(misalign.dot(ay)), static_cast<double>(misalign.dot(az)));
        };
    } else if (c.getConstraintType() == D6_CONSTRAINT_TYPE) {
        angles = readSixDof(static_cast<btGeneric6DofConstraint&>(c), ta, tb, fa, fb, j);
    } else {
        angles = readSixDof(static_cast<btGeneric6DofSpring2Constraint&>(c), ta, tb, fa, fb, j);
    }
    j.pivot_a = tearables::toCore(fa.getOrigin());
    j.pivot_b = tearables::toCore(fb.getOrigin());
    j.basis_a = basisToCore(fa.getBasis());
    j.angles = angles(tb);
    // The rates: b turned by +-eps about world axis k changes the angles by
    // -+eps angle_rates e_k (they turn with theta_a - theta_b); central differences.
    const btScalar eps = 1e-3f;
    for (int k = 0; k < 3; ++k) {
        btVector3 axis(0, 0, 0);
        axis[k] = 1;
        btTransform plus = tb, minus = tb;
        plus.setBasis(btMatrix3x3(btQuaternion(axis, eps)) * tb.getBasis());
        minus.setBasis(btMatrix3x3(btQuaternion(axis, -eps)) * tb.getBasis());
        const Vec3 up = angles(plus), down = angles(minus);
        for (int i = 0; i < 3; ++i)
            j.angle_rates(i, k) = -static_cast<double>(btNormalizeAngle(static_cast<btScalar>(up[i] - down[i]))) / (2.0 * static_cast<double>(eps));
    }
    angles(tb);  // a 6-dof joint's calculated transforms back at the poses
    // Motors. Bullet drives a row w . (V_A - V_B) = target, w along or about an axis of the
    // joint; a linear row along a's axis i is minus the rate of coordinate i, an angular
    // row about w turns the bodies relatively by target w / |w|^2, which angle i follows
    // at its rates (angle_rates (omega_A - omega_B)).
    const auto angularDrive = [&j](int i, const btVector3& w, btScalar target, btScalar force) {
        const Vec3 axis = tearables::toCore(w);
        j.drive_velocity[3 + i] = j.angle_rates.row(i).dot(axis) / axis.squaredNorm() * static_cast<double>(target);
        j.drive_force[3 + i] = static_cast<double>(force);
    };
    if (c.getConstraintType() == SLIDER_CONSTRAINT_TYPE) {
        // The slider's linear row is written with its reference sign: it drives b's
        // position along a's axis from a's pivot (a's from b's, linear reference b) at the
        // target rate.
        auto& slider = static_cast<btSliderConstraint&>(c);
        if (slider.getPoweredLinMotor()) {
            j.drive_velocity[0] = (slider.getUseLinearReferenceFrameA() ? 1.0 : -1.0) * static_cast<double>(slider.getTargetLinMotorVelocity());
            j.drive_force[0] = static_cast<double>(slider.getMaxLinMotorForce());
        }
        if (slider.getPoweredAngMotor())
            angularDrive(0, fa.getBasis().getColumn(0), slider.getTargetAngMotorVelocity(), slider.getMaxAngMotorForce());
    } else if (c.getConstraintType() == D6_CONSTRAINT_TYPE) {
        readSixDofMotors(static_cast<btGeneric6DofConstraint&>(c), j, angularDrive);
    } else if (c.getConstraintType() == D6_SPRING_2_CONSTRAINT_TYPE) {
        readSixDofMotors(static_cast<btGeneric6DofSpring2Constraint&>(c), j, angularDrive);
        readSpring2(static_cast<btGeneric6DofSpring2Constraint&>(c), h, j);
    }
    return j;
}

// Where a body is at the end of internal step `tick` of `ticks`: Bullet moves a kinematic
// body only once a frame, to its end pose, with the velocity that takes it there over the
// frame (saveKinematicState); the steps between follow that velocity.
btTransform tickPose(const btRigidBody& body, double h, int tick, int ticks) {
    if (!body.isKinematicObject() || tick >= ticks) return body.getWorldTransform();
    btTransform at;
    btTransformUtil::integrateTransform(body.getWorldTransform(), -body.getLinearVelocity(), -body.getAngularVelocity(),
                                        static_cast<btScalar>(h * (ticks - tick)), at);
    return at;
}

// Throw InvalidInput("string"/"cloth"/"paper") unless `id` names a live object; a stale id
// (its object removed) is named as such by the core.
void requireLive(const World& core, StringId id) { (void)core.desc(id); }
void requireLive(const World& core, ClothId id) { (void)core.clothDesc(id); }
void requireLive(const World& core, PaperId id) { (void)core.paperDesc(id); }

}  // namespace

// The per-substep callback, plus a sentinel collision object that tells us whether the
// Bullet world still exists: ~btCollisionWorld clears the broadphase handle of every
// object it still holds, and the sentinel's memory is ours, so reading it stays safe.
//
// The sentinel is also the frame clock. An action is told neither how many internal steps
// the current stepSimulation takes nor which one it is; but a stepSimulation that steps
// calls saveKinematicState(n h) on every kinematic body once, before its n steps
// (btDiscreteDynamicsWorld::stepSimulation), which sets w = angle(R_interp -> R) / (n h) and
// R_interp = R. The sentinel is a kinematic body turned by 1 rad at the first step of each
// frame: at the next frame's first step R == R_interp again, and n = 1 rad / (|w| h). It
// turns about its own origin, so its bounds (an empty shape's: the origin) never move.
class BulletWorld::Impl::Action : public btActionInterface {
public:
    explicit Action(Impl& owner)
        : owner_(owner), shape_(), sentinel_(btRigidBody::btRigidBodyConstructionInfo(0, nullptr, &shape_)) {
        sentinel_.setCollisionFlags(btCollisionObject::CF_KINEMATIC_OBJECT | btCollisionObject::CF_NO_CONTACT_RESPONSE);
        sentinel_.setActivationState(DISABLE_DEACTIVATION);
        arm();
    }
    void updateAction(btCollisionWorld*, btScalar time_step) override {
        const double h = static_cast<double>(time_step);
        if (sentinel_.getWorldTransform().getBasis() == sentinel_.getInterpolationWorldTransform().getBasis()) {
            const double w = static_cast<double>(sentinel_.getAngularVelocity().length());
            const double n = w > 0.0 && h > 0.0 ? std::round(1.0 / (w * h)) : 1.0;
            ticks_ = n >= 1.0 && n < 1e6 ? static_cast<int>(n) : 1;
            tick_ = 0;
            arm();
        }
        ++tick_;
        if (tick_ > ticks_) ticks_ = tick_;  // the clock was disturbed: never past the frame's end
        owner_.substep(h, tick_, ticks_);
    }
    void debugDraw(btIDebugDraw* drawer) override {
        if (drawer) owner_.debugDraw(*drawer);
    }

    btCollisionObject& sentinel() { return sentinel_; }
    bool inWorld() const { return sentinel_.getBroadphaseHandle() != nullptr; }

private:
    void arm() {
        sentinel_.setInterpolationWorldTransform(btTransform::getIdentity());
        sentinel_.setWorldTransform(btTransform(btQuaternion(btVector3(1, 0, 0), 1), btVector3(0, 0, 0)));
    }

    Impl& owner_;
    btEmptyShape shape_;
    btRigidBody sentinel_;
    int tick_ = 0, ticks_ = 1;
};

/// The pattern search that sharpens a contact on a curved convex body (refineOnConvexBody):
/// its first and last step (rad), and the gain in separation (m) below which GJK's answer
/// is kept.
constexpr double kRefineFirstStep = 0.1;
constexpr double kRefineLastStep = 1e-6;
constexpr double kRefineGain = 1e-7;
constexpr double kRefineKeepPoint = 1e-6;
/// A box's face carries a segment (boxFaceContacts) where it separates the segment from
/// the box as well as GJK's answer does, to this much (m): GJK in float leaves its
/// separating direction off by up to a tenth of a radian where a segment lies parallel
/// to a face (any point of it is then a closest point), so its distance there is short
/// by up to a few micrometres.
constexpr double kFaceSlack = 1e-5;

// Contacts between string segments and rigid bodies, with Bullet's own narrow phase: each
// segment is a capsule, tested against the bodies the broadphase found near its string
// (BulletWorld::findCandidates) by btCollisionWorld::contactPairTest.
class BulletWorld::Impl::Contacts : public ContactProvider {
public:
    explicit Contacts(Impl& owner) : owner_(owner) {}

    /// Proxies of the bodies some contact named this step, sorted; of those a string's.
    std::vector<std::uint32_t> touched, string_touched;

    void findContacts(const CollisionQuery& query, std::vector<RigidContact>& out) override {
        if (!owner_.attachedToBullet()) return;  // the Bullet world is gone: no bodies to touch
        const std::size_t first = out.size();
        findStringContacts(query, out);
        string_touched.clear();
        for (std::size_t k = first; k < out.size(); ++k) string_touched.push_back(out[k].body.index);
        std::sort(string_touched.begin(), string_touched.end());
        touched.insert(touched.end(), string_touched.begin(), string_touched.end());
        std::sort(touched.begin(), touched.end());
    }

    void findPointContacts(const PointQuery& query, std::vector<PointContact>& out) override {
        if (!owner_.attachedToBullet()) return;
        const std::size_t first = out.size();
        findMeshContacts(query, out);
        for (std::size_t k = first; k < out.size(); ++k) touched.push_back(out[k].body.index);
        std::sort(touched.begin(), touched.end());
    }

    /// The contacts of the bodies taken from Bullet's solver this step (the manifolds it
    /// withheld, found at the start of the step), at the bodies' poses now: each point's
    /// local points follow their bodies, its normal turns with body 1 (Bullet's normal on B
    /// points from body 1 toward body 0).
    void findBodyContacts(std::vector<BodyContact>& out) override {
        points_.clear();
        if (!owner_.attachedToBullet() || !owner_.claim_) return;
        const double h = owner_.step_;
        for (btPersistentManifold* m : owner_.claim_->withheldManifolds()) {
            const auto* o0 = btRigidBody::upcast(m->getBody0());
            const auto* o1 = btRigidBody::upcast(m->getBody1());
            if (!o0 || !o1 || m->getNumContacts() == 0) continue;
            const Side s0 = side(*o0, h), s1 = side(*o1, h);
            if (!s0.body.valid() && !s1.body.valid()) continue;
            const std::size_t first = out.size();
            for (int k = 0; k < m->getNumContacts(); ++k) {
                const btManifoldPoint& p = m->getContactPoint(k);
                const btVector3 a_now = s0.now * p.m_localPointA, b_now = s1.now * p.m_localPointB;
                const btVector3 a_then = s0.then * p.m_localPointA, b_then = s1.then * p.m_localPointB;
                BodyContact c;
                c.a = s0.body;
                c.b = s1.body;
                c.point_a = toCore(a_now);
                c.point_b = toCore(b_now);
                c.normal = toCore(s1.now.getBasis() * (s1.then.getBasis().transpose() * p.m_normalWorldOnB));
                c.motion = toCore((a_now - a_then) - (b_now - b_then));
                c.depth = std::max(0.0, -static_cast<double>(p.getDistance()));
                c.friction = static_cast<double>(p.m_combinedFriction);
                c.force = h > 0.0 ? static_cast<double>(p.m_appliedImpulse) / h : 0.0;
                c.host_tag = points_.size();
                points_.push_back({m, k});
                out.push_back(c);
            }
            // A full manifold (four points) holds the pair already; fewer is a first touch.
            if (m->getNumContacts() < 4)
                addBoxCorners(*o0, swept(*o0, s0), *o1, swept(*o1, s1), static_cast<double>(m->getContactPoint(0).m_combinedFriction),
                              first, out);
        }
        addSpeculativeBodyContacts(h, out);
    }

    /// Speculative contacts for the claimed bodies' pairs that Bullet's manifolds give no
    /// point this step. Those are found where the step starts, before the island moves the
    /// bodies, and only within a breaking threshold (Bullet's box-box test gives none for
    /// boxes apart at all): two island bodies closing faster than they are apart per step
    /// meet no contact before they overlap, and past half a body's width they pass through
    /// (two 0.1 m boxes closing at 12 m/s at 1/60 s). Each pair of convex bodies whose
    /// swept bounds overlap gets its closest points where the step started (GJK), when
    /// they are within the distance both can travel in the step, as a contact with a
    /// positive gap: the island holds it only where the step runs into it, as it does a
    /// manifold point apart (BodyContact); two boxes get their corners over each other
    /// (addBoxCorners). Its impulse goes back to no manifold (host_tag past points_);
    /// Bullet's own points take over at the next step.
    void addSpeculativeBodyContacts(double h, std::vector<BodyContact>& out) {
        const std::vector<const btRigidBody*>& claimed = owner_.claimed_;  // sorted by address
        if (claimed.empty()) return;
        // In the broadphase's order (deterministic, as bodiesIn gives the others).
        auto uid = [](const btRigidBody* body) { return body->getBroadphaseHandle() ? body->getBroadphaseHandle()->getUid() : -1; };
        by_uid_.assign(claimed.begin(), claimed.end());
        std::sort(by_uid_.begin(), by_uid_.end(), [&](const btRigidBody* x, const btRigidBody* y) { return uid(x) < uid(y); });
        auto ordered = [](const btCollisionObject* x, const btCollisionObject* y) {
            return x < y ? std::make_pair(x, y) : std::make_pair(y, x);
        };
        touching_.clear();
        for (btPersistentManifold* m : owner_.claim_->withheldManifolds())
            if (m->getNumContacts() > 0) touching_.push_back(ordered(m->getBody0(), m->getBody1()));
        std::sort(touching_.begin(), touching_.end());
        // Candidates: the claimed bodies' swept bounds against each other and against what
        // Bullet's broadphase has there (bodies it does not move in the step, or moves on
        // its own), each pair once.
        candidates_.clear();
        bounds_.clear();
        for (const btRigidBody* a : by_uid_) bounds_.push_back(swept(*a, side(*a, h)));
        for (std::size_t i = 0; i < by_uid_.size(); ++i) {
            const Swept& sa = bounds_[i];
            for (std::size_t j = i + 1; j < by_uid_.size(); ++j)
                if (TestAabbAgainstAabb2(sa.lo, sa.hi, bounds_[j].lo, bounds_[j].hi)) candidates_.push_back({i, by_uid_[j], j});
            for (const btRigidBody* b : owner_.bodiesIn(toCore(sa.lo), toCore(sa.hi)))
                if (b != by_uid_[i] && !std::binary_search(claimed.begin(), claimed.end(), b)) candidates_.push_back({i, b, kUnclaimed});
        }
        btDispatcher& dispatcher = *owner_.world_->getDispatcher();
        btOverlapFilterCallback* filter = owner_.world_->getPairCache()->getOverlapFilterCallback();
        for (const Candidate& pair : candidates_) {
            const btRigidBody *a = by_uid_[pair.a], *b = pair.b;
            const btCollisionShape &shape_a = *a->getCollisionShape(), &shape_b = *b->getCollisionShape();
            if (!shape_a.isConvex() || !shape_b.isConvex()) continue;
            if (std::binary_search(touching_.begin(), touching_.end(), ordered(a, b))) continue;
            const btBroadphaseProxy *pa = a->getBroadphaseHandle(), *pb = b->getBroadphaseHandle();
            if (!pa || !pb || !dispatcher.needsCollision(a, b)) continue;
            const bool passes = filter ? filter->needBroadphaseCollision(const_cast<btBroadphaseProxy*>(pa), const_cast<btBroadphaseProxy*>(pb))
                                       : Filter{pa->m_collisionFilterGroup, pa->m_collisionFilterMask}.passes(*b);
            if (!passes) continue;
            const Swept& sa = bounds_[pair.a];
            const Swept sb = pair.b_claimed != kUnclaimed ? bounds_[pair.b_claimed] : swept(*b, side(*b, h));
            if (!sa.side.body.valid()) continue;  // a claimed body has a proxy (startClaimedBodies)
            const double reach = sa.travel + sb.travel + kContactMargin;
            btVoronoiSimplexSolver simplex;
            btGjkEpaPenetrationDepthSolver epa;
            btGjkPairDetector gjk(static_cast<const btConvexShape*>(&shape_a), static_cast<const btConvexShape*>(&shape_b), &simplex, &epa);
            btGjkPairDetector::ClosestPointInput input;
            input.m_transformA = sa.side.then;
            input.m_transformB = sb.side.then;
            input.m_maximumDistanceSquared = static_cast<btScalar>(reach * reach);
            btPointCollector result;
            gjk.getClosestPoints(input, result, nullptr);
            if (!result.m_hasResult || static_cast<double>(result.m_distance) > reach) continue;
            // Bullet's normal on B points from B toward A; A's point is B's moved along it.
            const btVector3 n = result.m_normalOnBInWorld;
            const btVector3 closest_b = result.m_pointInWorld, closest_a = closest_b + n * result.m_distance;
            const double friction = std::min(10.0, static_cast<double>(a->getFriction() * b->getFriction()));  // Bullet's combination
            const std::size_t before = out.size();
            addBoxCorners(*a, sa, *b, sb, friction, before, out);
            if (out.size() > before) continue;
            // Other shapes: one contact, slid across the normal (the gap stays) to below the
            // midpoint of the centres, where its arm has no turn to open it with (see
            // addBoxCorners).
            const btVector3 mid = 0.5 * (sa.side.then.getOrigin() + sb.side.then.getOrigin()) - closest_b;
            const btVector3 shift = mid - n * n.dot(mid);
            out.push_back(carried(sa, sb, closest_a + shift, closest_b + shift, n, friction));
        }
    }

    /// The joints withheld with the claimed bodies (islandJoint), at the bodies' poses now:
    /// a ball joint's pivots, a hinge's pivots and axes (its frames' origins and z axes), a
    /// slider's or 6-dof joint's frames and coordinates (frameJoint).
    void findBodyJoints(std::vector<BodyJoint>& out) override {
        joints_.clear();
        if (!owner_.attachedToBullet() || !owner_.claim_) return;
        const double h = owner_.step_;
        for (btTypedConstraint* c : owner_.claim_->withheldConstraints()) {
            if (!islandJoint(*c)) continue;
            const Side sa = side(c->getRigidBodyA(), h), sb = side(c->getRigidBodyB(), h);
            if (!sa.body.valid() && !sb.body.valid()) continue;
            const int type = c->getConstraintType();
            const bool frame = type != POINT2POINT_CONSTRAINT_TYPE && type != HINGE_CONSTRAINT_TYPE && type != GEAR_CONSTRAINT_TYPE;
            BodyJoint j = frame ? frameJoint(*c, sa.now, sb.now, h) : BodyJoint{};
            j.host_tag = joints_.size();
            joints_.push_back(c);
            j.a = sa.body;
            j.b = sb.body;
            if (type == GEAR_CONSTRAINT_TYPE) {
                // Bullet's row: (omega_A . axisA + ratio omega_B . axisB) = 0, the axes turning
                // with their bodies; no pivot (the bodies' centres stand for it).
                const auto& gear = static_cast<const btGearConstraint&>(*c);
                j.kind = BodyJoint::Kind::Gear;
                j.axis_a = toCore(sa.now.getBasis() * gear.getAxisA());
                j.axis_b = static_cast<double>(gear.getRatio()) * toCore(sb.now.getBasis() * gear.getAxisB());
                j.pivot_a = toCore(sa.now.getOrigin());
                j.pivot_b = toCore(sb.now.getOrigin());
            } else if (type == POINT2POINT_CONSTRAINT_TYPE) {
                const auto& ball = static_cast<const btPoint2PointConstraint&>(*c);
                j.pivot_a = toCore(sa.now * ball.getPivotInA());
                j.pivot_b = toCore(sb.now * ball.getPivotInB());
            } else if (type == HINGE_CONSTRAINT_TYPE) {
                const auto& hinge = static_cast<const btHingeConstraint&>(*c);
                const btTransform fa = sa.now * hinge.getAFrame(), fb = sb.now * hinge.getBFrame();
                j.kind = BodyJoint::Kind::Hinge;
                j.pivot_a = toCore(fa.getOrigin());
                j.pivot_b = toCore(fb.getOrigin());
                j.axis_a = toCore(fa.getBasis().getColumn(2));
                j.axis_b = toCore(fb.getBasis().getColumn(2));
                auto& limited = const_cast<btHingeConstraint&>(hinge);  // Bullet's getters are not const
                if (limited.hasLimit() || limited.getEnableAngularMotor()) {
                    // Bullet's angle, and which way it turns when a turns about the axis
                    // (its reference sign, which has no getter): measured by a small turn.
                    const btScalar turn = 1e-3f;
                    btTransform turned = sa.now;
                    turned.setBasis(btMatrix3x3(btQuaternion(fa.getBasis().getColumn(2), turn)) * sa.now.getBasis());
                    const btScalar angle = limited.getHingeAngle(sa.now, sb.now);
                    const btScalar moved = btNormalizeAngle(limited.getHingeAngle(turned, sb.now) - angle);
                    j.angle_sign = moved > 0 ? 1.0 : -1.0;
                    if (limited.hasLimit()) {
                        j.angle = static_cast<double>(angle);
                        j.lower = static_cast<double>(limited.getLowerLimit());
                        j.upper = static_cast<double>(limited.getUpperLimit());
                    }
                    // The motor's row drives (omega_A - omega_B) . axis_A to the target rate
                    // times the reference sign (btHingeConstraint::getInfo2Internal), the
                    // sign the small turn measures.
                    if (limited.getEnableAngularMotor()) {
                        j.motor = true;
                        j.motor_velocity = j.angle_sign * static_cast<double>(limited.getMotorTargetVelocity());
                        j.motor_impulse = static_cast<double>(limited.getMaxMotorImpulse());
                    }
                }
            }
            out.push_back(j);
        }
    }

    /// After the step: each kept contact's impulse into its manifold point (Bullet's
    /// warm start and users read m_appliedImpulse); the points the solve dropped carry 0.
    void writeBodyImpulses(const std::vector<BodyContact>& solved) {
        const double h = owner_.step_;
        for (const auto& [m, k] : points_) m->getContactPoint(k).m_appliedImpulse = 0;
        for (const BodyContact& c : solved)
            if (c.host_tag < points_.size()) {
                const auto& [m, k] = points_[c.host_tag];
                m->getContactPoint(k).m_appliedImpulse = static_cast<btScalar>(c.force * h);
            }
    }

    /// After the step, for every joint the island solved, what Bullet's solver leaves on a
    /// constraint it solved (btSequentialImpulseConstraintSolver's finish): its applied
    /// impulse, the sum of its rows' impulses (a ball joint's rows are the world's axes,
    /// acting on A: the sum of the components of the impulse on A; a hinge's also its
    /// alignment about the two axes across its own, and its limit about the axis); its
    /// joint feedback (forces and torques on A and B: the impulses over h); and where a row's
    /// impulse reaches the breaking threshold, the constraint disabled (it stays with Bullet
    /// from the next step, disabled).
    void writeJointImpulses(const std::vector<BodyJoint>& solved) {
        const double h = owner_.step_;
        if (!(h > 0.0)) return;
        for (const BodyJoint& j : solved) {
            if (j.host_tag >= joints_.size()) continue;
            btTypedConstraint& c = *joints_[j.host_tag];
            // The host's A and B (the solve may have turned the joint round). A side the
            // island does not move (a fixed frame, a static or kinematic body) takes the
            // reaction, as Bullet's feedback gives it: the opposite impulse at its own
            // pivot, and the opposite of the couple the joint put on the other.
            const bool a_moves = (j.swapped ? j.b : j.a).valid(), b_moves = (j.swapped ? j.a : j.b).valid();
            Vec3 lin_a = j.swapped ? j.impulse_b : j.impulse_a, ang_a = j.swapped ? j.angular_impulse_b : j.angular_impulse_a;
            Vec3 lin_b = j.swapped ? j.impulse_a : j.impulse_b, ang_b = j.swapped ? j.angular_impulse_a : j.angular_impulse_b;
            const Vec3 arm_a = (j.swapped ? j.pivot_b : j.pivot_a) - toCore(c.getRigidBodyA().getCenterOfMassPosition());
            const Vec3 arm_b = (j.swapped ? j.pivot_a : j.pivot_b) - toCore(c.getRigidBodyB().getCenterOfMassPosition());
            if (!b_moves) {
                lin_b = -lin_a;
                ang_b = -(ang_a - arm_a.cross(lin_a)) + arm_b.cross(lin_b);
            } else if (!a_moves) {
                lin_a = -lin_b;
                ang_a = -(ang_b - arm_b.cross(lin_b)) + arm_a.cross(lin_a);
            }
            // A's row impulses: the pivot's along the world axes.
            double sum = lin_a.sum(), largest = lin_a.cwiseAbs().maxCoeff();
            if (j.kind == BodyJoint::Kind::Frame) {
                // The rows along and about the axes of A's frame (the host's basis_a).
                const Vec3 turning = ang_a - arm_a.cross(lin_a);
                sum = 0.0;
                largest = 0.0;
                for (int i = 0; i < 3; ++i) {
                    const double along = j.basis_a.col(i).dot(lin_a), about = j.basis_a.col(i).dot(turning);
                    sum += along + about;
                    largest = std::max({largest, std::abs(along), std::abs(about)});
                }
            } else if (j.kind == BodyJoint::Kind::Gear) {
                // The one row, its Jacobian on A the host's axis of A: the angular impulse on A
                // is the row's impulse times that axis.
                const Vec3 axis = j.swapped ? j.axis_b : j.axis_a;
                sum = axis.squaredNorm() > 0.0 ? axis.dot(ang_a) / axis.squaredNorm() : 0.0;
                largest = std::abs(sum);
            } else if (j.kind == BodyJoint::Kind::Hinge) {
                // The angular rows about A's axis frame: the two across it (alignment) and
                // the axis itself (the limit), each the angular impulse's component less
                // the pivot force's moment, which the linear rows carry.
                const Vec3 axis = j.swapped ? j.axis_b : j.axis_a;
                const Vec3 turning = ang_a - arm_a.cross(lin_a);
                const Vec3 across = turning - axis * axis.dot(turning);
                sum += across.norm() + axis.dot(turning);
                largest = std::max({largest, across.norm(), std::abs(axis.dot(turning))});
            }
            c.internalSetAppliedImpulse(static_cast<btScalar>(sum));
            if (btJointFeedback* fb = c.needsFeedback() ? c.getJointFeedback() : nullptr) {
                fb->m_appliedForceBodyA = tearables::toBullet(lin_a / h);
                fb->m_appliedTorqueBodyA = tearables::toBullet(ang_a / h);
                fb->m_appliedForceBodyB = tearables::toBullet(lin_b / h);
                fb->m_appliedTorqueBodyB = tearables::toBullet(ang_b / h);
            }
            if (largest >= static_cast<double>(c.getBreakingImpulseThreshold())) c.setEnabled(false);
        }
    }

private:
    /// One body of a withheld manifold: its proxy (none for a fixed one: static,
    /// kinematic, or a body not claimed), and its poses now and at the step's start.
    struct Side {
        RigidId body;
        btTransform now, then;
    };
    Side side(const btRigidBody& body, double h) const {
        Side s;
        s.now = now(body);
        s.then = s.now;
        if (body.isKinematicObject())
            btTransformUtil::integrateTransform(s.now, -body.getLinearVelocity(), -body.getAngularVelocity(),
                                                static_cast<btScalar>(h), s.then);
        if (!std::binary_search(owner_.claimed_.begin(), owner_.claimed_.end(), &body)) return s;
        const auto it = owner_.proxies_.find(&body);
        if (it == owner_.proxies_.end()) return s;
        s.body = it->second;
        for (const ClaimedBody& c : owner_.claim_->claimedBodies())
            if (c.body == &body) s.then = c.transform;
        return s;
    }

    /// A body over the step for the body-body contacts: its poses (side), its swept bounds
    /// and how far any of its points can travel in the step.
    struct Swept {
        Side side;
        btVector3 lo, hi;
        double travel = 0.0;
    };
    Swept swept(const btRigidBody& body, const Side& poses) const {
        Swept s{poses, {}, {}, 0.0};
        btVector3 lo, hi;
        body.getCollisionShape()->getAabb(s.side.then, s.lo, s.hi);
        body.getCollisionShape()->getAabb(s.side.now, lo, hi);
        s.lo.setMin(lo);
        s.hi.setMax(hi);
        const btQuaternion turn = s.side.now.getRotation() * s.side.then.getRotation().inverse();
        s.travel = static_cast<double>((s.side.now.getOrigin() - s.side.then.getOrigin()).length() +
                                       turn.getAngleShortestPath() * body.getCollisionShape()->getAngularMotionDisc());
        return s;
    }

    /// One body-body contact from points where the step started (`a_then` on A,
    /// `b_then` on B, normal `n` from B toward A): carried to the bodies' poses now.
    static BodyContact carried(const Swept& a, const Swept& b, const btVector3& a_then, const btVector3& b_then, const btVector3& n,
                               double friction) {
        const btVector3 a_now = a.side.now * (a.side.then.inverse() * a_then);
        const btVector3 b_now = b.side.now * (b.side.then.inverse() * b_then);
        BodyContact c;
        c.a = a.side.body;
        c.b = b.side.body;
        c.point_a = toCore(a_now);
        c.point_b = toCore(b_now);
        c.normal = toCore(b.side.now.getBasis() * (b.side.then.getBasis().transpose() * n)).normalized();
        c.motion = toCore((a_now - a_then) - (b_now - b_then));
        c.depth = std::max(0.0, -static_cast<double>(n.dot(a_then - b_then)));
        c.friction = friction;
        c.force = 0.0;
        c.host_tag = std::numeric_limits<std::size_t>::max();  // no manifold point takes its impulse
        return c;
    }

    /// Bullet's first points of two boxes meeting face to face are often one edge (two
    /// points), and the manifold fills over the next steps. An island moves its bodies in
    /// one step by their positions, with contacts linearised where the step started: held
    /// by one edge, the step meets the contact by turning both boxes about it (the edge
    /// opens by its arm times the turn), and the opposite edge, with no point, swings into
    /// the other box (docs/island-plan.md: 6 cm deep at 6 m/s closing). So each
    /// corner of either box within the pair's reach of the other box is a contact too: its
    /// closest point on the other box, the normal from there (the face it lies over, an
    /// edge or a corner), or where it is inside, the nearest face. Only the corners of a
    /// box's near half (within its smallest half extent of its nearest corner): its far
    /// corners lie behind its own near faces. A corner that a contact of the pair (from
    /// `first` in `out`) already holds is left to it. (A corner just past the other box's
    /// edge gets a plane through that edge, a wall the box does not have: a crate sliding
    /// back onto a board it overhangs by less than its reach would be stopped at the edge.
    /// The manifold's own points at the edge, within kContactMargin of such a corner, and
    /// a full manifold, which takes no corners, keep that to first touches.)
    void addBoxCorners(const btRigidBody& a, const Swept& sa, const btRigidBody& b, const Swept& sb, double friction,
                       std::size_t first, std::vector<BodyContact>& out) {
        if (a.getCollisionShape()->getShapeType() != BOX_SHAPE_PROXYTYPE ||
            b.getCollisionShape()->getShapeType() != BOX_SHAPE_PROXYTYPE)
            return;
        const btVector3 half_a = static_cast<const btBoxShape*>(a.getCollisionShape())->getHalfExtentsWithMargin();
        const btVector3 half_b = static_cast<const btBoxShape*>(b.getCollisionShape())->getHalfExtentsWithMargin();
        const double reach = sa.travel + sb.travel + kContactMargin;
        const std::size_t found = out.size();
        // Corners of box X (pose x, half extents hx) against box Y; `on_a`: X is A.
        auto corners = [&](const btTransform& x, const btVector3& hx, const btTransform& y, const btVector3& hy, bool on_a) {
            std::array<btVector3, 8> corner, on_y, normal;  // world; normal from Y toward the corner
            std::array<double, 8> distance;                 // signed: < 0 inside Y
            for (int i = 0; i < 8; ++i) {
                corner[i] = x * btVector3((i & 1) ? hx.x() : -hx.x(), (i & 2) ? hx.y() : -hx.y(), (i & 4) ? hx.z() : -hx.z());
                const btVector3 local = y.invXform(corner[i]);
                btVector3 closest(btClamped(local.x(), -hy.x(), hy.x()), btClamped(local.y(), -hy.y(), hy.y()),
                                  btClamped(local.z(), -hy.z(), hy.z()));
                btVector3 n = local - closest;
                distance[i] = static_cast<double>(n.length());
                if (distance[i] > 0.0) {
                    n /= static_cast<btScalar>(distance[i]);
                } else {  // inside: out through the nearest face
                    int axis = 0;
                    for (int k = 1; k < 3; ++k)
                        if (hy[k] - btFabs(local[k]) < hy[axis] - btFabs(local[axis])) axis = k;
                    const btScalar side = local[axis] < 0 ? -1 : 1;
                    distance[i] = -static_cast<double>(hy[axis] - btFabs(local[axis]));
                    n.setZero();
                    n[axis] = side;
                    closest[axis] = side * hy[axis];
                }
                on_y[i] = y * closest;
                normal[i] = y.getBasis() * n;
            }
            const double near = std::min(reach, *std::min_element(distance.begin(), distance.end()) +
                                                    static_cast<double>(hx[hx.minAxis()]));
            for (int i = 0; i < 8; ++i) {
                if (distance[i] > near) continue;
                const BodyContact c = on_a ? carried(sa, sb, corner[i], on_y[i], normal[i], friction)
                                           : carried(sa, sb, on_y[i], corner[i], -normal[i], friction);
                bool there = false;
                for (std::size_t k = first; k < found && !there; ++k)
                    there = ((on_a ? c.point_a : c.point_b) - (on_a ? out[k].point_a : out[k].point_b)).norm() < kContactMargin;
                if (!there) out.push_back(c);
            }
        };
        corners(sa.side.then, half_a, sb.side.then, half_b, true);
        corners(sb.side.then, half_b, sa.side.then, half_a, false);
    }

    std::vector<std::pair<btPersistentManifold*, int>> points_;  // per body contact: its manifold point
    std::vector<std::pair<const btCollisionObject*, const btCollisionObject*>> touching_;  // pairs with manifold points
    /// A pair for speculative contacts: its claimed body (an index into by_uid_ and
    /// bounds_), the other body, and the other's index there if it is claimed too.
    static constexpr std::size_t kUnclaimed = std::numeric_limits<std::size_t>::max();
    struct Candidate {
        std::size_t a;
        const btRigidBody* b;
        std::size_t b_claimed;
    };
    std::vector<Candidate> candidates_;
    std::vector<const btRigidBody*> by_uid_;  // the claimed bodies in the broadphase's order
    std::vector<Swept> bounds_;               // per by_uid_
    std::vector<btTypedConstraint*> joints_;                      // per body joint: its constraint

    void findStringContacts(const CollisionQuery& query, std::vector<RigidContact>& out) {
        const double h = owner_.step_;
        // Trees of strings that are gone (removed, frozen) are dropped.
        for (auto it = trees_.begin(); it != trees_.end();) {
            const bool live = std::any_of(query.strings.begin(), query.strings.end(),
                                          [&](StringId s) { return s.index == it->first; });
            it = live ? std::next(it) : trees_.erase(it);
        }
        for (std::size_t i = 0; i < query.strings.size(); ++i) {
            const auto it = owner_.candidates_.find(query.strings[i].index);
            if (it == owner_.candidates_.end()) continue;
            const auto& start = *query.start[i];
            const auto& pred = *query.predicted[i];
            const auto& radius = *query.radius[i];
            const auto& broken = *query.broken[i];
            const auto glued = std::equal_range(query.glued.begin(), query.glued.end(), std::make_pair(query.strings[i], RigidId{}),
                                                [](const auto& a, const auto& b) { return a.first.index < b.first.index; });
            auto isGlued = [&](btRigidBody* body) {
                const RigidId proxy = owner_.proxies_.at(body);
                return std::any_of(glued.first, glued.second, [&](const auto& g) { return g.second == proxy; });
            };
            // A string near only the bodies it is glued to (a rope hanging from a board)
            // leaves its tree as it is: the next step that needs it brings every leaf up to date.
            if (std::all_of(it->second.begin(), it->second.end(), isGlued)) continue;
            SegmentTree& tree = treeFor(query.strings[i].index, start, pred, radius, broken);
            for (btRigidBody* body : it->second) {
                if (isGlued(body)) continue;
                const RigidId proxy = owner_.proxies_.at(body);
                const SweptBody swept(*body, h, now(*body));
                const btTransform& before = swept.found_at;
                const btVector3 &bmin = swept.lo, &bmax = swept.hi;
                const double body_travel = swept.travel;
                // The segments whose swept bounds overlap the body's: from the string's own
                // btDbvt, in segment order (deterministic).
                hits_.clear();
                if (tree.tree.m_root) {
                    const btDbvtVolume volume = btDbvtVolume::FromMM(bmin, bmax);
                    Overlaps collect(hits_);
                    tree.tree.collideTV(tree.tree.m_root, volume, collect);
                }
                std::sort(hits_.begin(), hits_.end());
                const std::size_t first = out.size();
                double seg_travel = 0.0;
                for (const std::uint32_t j : hits_) {
                    const double travel = std::max((pred[j] - start[j]).norm(), (pred[j + 1] - start[j + 1]).norm());
                    seg_travel = std::max(seg_travel, travel);
                    test(query.strings[i], j, start[j], start[j + 1], radius[j], *body, before,
                         body_travel + travel + kContactMargin, proxy, out);
                }
                coverEnds(query.strings[i], start, radius, hits_, first, *body, before,
                          body_travel + seg_travel + kContactMargin, proxy, out);
            }
        }
    }

    void findMeshContacts(const PointQuery& query, std::vector<PointContact>& out) {
        const double h = owner_.step_;
        std::vector<RigidContact> found;
        std::vector<const std::vector<Vec3>*> seen_meshes;
        for (std::size_t i = 0; i < query.start.size(); ++i) {
            const auto& start = *query.start[i];
            const auto& pred = *query.predicted[i];
            const double radius = query.radius[i];
            if (start.empty() || start.size() != pred.size() || !(radius > 0.0)) continue;
            const auto* triangles = i < query.triangles.size() ? query.triangles[i] : nullptr;
            // The object's swept bounds: candidate bodies from Bullet's broadphase.
            Vec3 lo = Vec3::Constant(1e300), hi = Vec3::Constant(-1e300);
            for (std::size_t v = 0; v < start.size(); ++v) {
                lo = lo.cwiseMin(start[v]).cwiseMin(pred[v]);
                hi = hi.cwiseMax(start[v]).cwiseMax(pred[v]);
            }
            if (!lo.allFinite() || !hi.allFinite()) continue;
            const double grow = radius + kContactMargin;
            const double margin = radius + kContactMargin;
            std::vector<btRigidBody*> bodies = owner_.bodiesIn(lo.array() - grow, hi.array() + grow);
            // Only bodies that were given a proxy before the step (findCandidates), and that
            // the object's collision filter lets through.
            const Filter filter = owner_.meshFilter(query, i);
            bodies.erase(std::remove_if(bodies.begin(), bodies.end(),
                                        [&](btRigidBody* b) {
                                            return !std::binary_search(owner_.mesh_candidates_.begin(),
                                                                       owner_.mesh_candidates_.end(), b) ||
                                                   !filter.passes(*b);
                                        }),
                         bodies.end());
            if (bodies.empty()) continue;
            // A surface: its triangles in a btDbvt of their swept bounds, kept from step to
            // step; a body's candidates are the triangles that overlap its swept bounds.
            TriangleTree* tree = nullptr;
            if (triangles && !triangles->empty()) {
                tree = &triangleTree(query.start[i], start, pred, *triangles, margin);
                seen_meshes.push_back(query.start[i]);
                vertex_stamp_.assign(start.size(), 0);
                touched_stamp_.assign(start.size(), 0);
            }
            std::uint32_t stamp = 0;
            for (btRigidBody* body : bodies) {
                const SweptBody swept(*body, h, now(*body));
                const btVector3 &bmin = swept.lo, &bmax = swept.hi;
                const RigidId proxy = owner_.proxies_.at(body);
                // A vertex: a sphere at the start of the step, reaching as far as both can
                // travel (as the segments' capsules do).
                auto testVertex = [&](std::size_t v) {
                    const Vec3 vlo = start[v].cwiseMin(pred[v]).array() - margin;
                    const Vec3 vhi = start[v].cwiseMax(pred[v]).array() + margin;
                    if (vlo.x() > bmax.x() || vlo.y() > bmax.y() || vlo.z() > bmax.z() || vhi.x() < bmin.x() ||
                        vhi.y() < bmin.y() || vhi.z() < bmin.z())
                        return;
                    found.clear();
                    testSphere(start[v], radius, *body, swept.before, swept.travel + (pred[v] - start[v]).norm() + kContactMargin,
                               proxy, found);
                    if (tree && !found.empty()) touched_stamp_[v] = stamp;
                    for (const RigidContact& rc : found) {
                        PointContact c;
                        c.object = static_cast<std::uint32_t>(i);
                        c.vertex = static_cast<std::uint32_t>(v);
                        c.normal = rc.normal;
                        c.point = rc.point;
                        c.body = rc.body;
                        c.friction = rc.friction;
                        out.push_back(c);
                    }
                };
                if (!tree) {
                    for (std::size_t v = 0; v < start.size(); ++v) testVertex(v);
                    continue;
                }
                hits_.clear();
                Overlaps collect(hits_);
                tree->tree.collideTV(tree->tree.m_root, btDbvtVolume::FromMM(bmin, bmax), collect);
                std::sort(hits_.begin(), hits_.end());  // a deterministic order
                ++stamp;
                for (const std::uint32_t t : hits_)
                    for (const std::uint32_t v : (*triangles)[t])
                        if (v < start.size() && vertex_stamp_[v] != stamp) {
                            vertex_stamp_[v] = stamp;
                            testVertex(v);
                        }
                // Faces: only convex bodies (Bullet's GJK); compounds and triangle meshes
                // touch the surface at its vertices.
                if (!body->getCollisionShape()->isConvex()) continue;
                for (const std::uint32_t t : hits_) {
                    const auto& tri = (*triangles)[t];
                    if (tri[0] >= start.size() || tri[1] >= start.size() || tri[2] >= start.size()) continue;
                    // All three corners touch the body already: their contacts hold the
                    // triangle (and lend the body's mass to the solve, which a face
                    // contact does not). A face contact is for a body that reaches
                    // between the corners: a small ball, a box's edge or corner.
                    if (touched_stamp_[tri[0]] == stamp && touched_stamp_[tri[1]] == stamp && touched_stamp_[tri[2]] == stamp)
                        continue;
                    double travel = 0.0;
                    for (std::uint32_t v : tri) travel = std::max(travel, (pred[v] - start[v]).norm());
                    testFace(i, tri, start, radius, *body, swept, swept.travel + travel + kContactMargin, proxy, out);
                }
            }
        }
        // Forget the trees of meshes that were not asked about (removed, frozen).
        std::sort(seen_meshes.begin(), seen_meshes.end());
        for (auto it = triangle_trees_.begin(); it != triangle_trees_.end();)
            it = std::binary_search(seen_meshes.begin(), seen_meshes.end(), it->first) ? std::next(it) : triangle_trees_.erase(it);
    }

    static constexpr double kContactMargin = 0.005;
    /// A contact this close to an end of its segment (a fraction of it) is at the end.
    static constexpr double kEndSnap = 1e-3;

    /// Where the body is at the end of this internal step (tickPose).
    btTransform now(const btRigidBody& body) const { return tickPose(body, owner_.step_, owner_.tick_, owner_.ticks_); }

    /// A body over the step: where it was at the start (Bullet has already moved it by
    /// x += h v, so step back along its velocities), the bounds of both poses, and how far
    /// any of its points can have travelled.
    ///
    /// `found_at`: the pose a string's contacts are found at. Where the body was (`before`),
    /// unless it turns through more than kLargeTurn in the step: a contact is a plane fixed
    /// in the body and carried to `now` with it, so one found where the body was turns by
    /// the whole step's turn, a plane that faced the string at the start faces along it (or
    /// away) by the end, and the string slips past a spinning box. Found at the body's
    /// turned orientation (and the start's position: a body moving fast still meets the
    /// string on its way), the plane faces the string as the body will.
    struct SweptBody {
        /// A turn in one step beyond which contacts are found at the turned orientation,
        /// rad: where the plane's tilt over the step (1 - cos 0.1 = 0.5%) starts to matter.
        static constexpr double kLargeTurn = 0.1;
        btTransform now, before, found_at;
        btVector3 lo, hi;
        double travel = 0.0;
        SweptBody(const btRigidBody& body, double h, const btTransform& at) : now(at) {
            btTransformUtil::integrateTransform(now, -body.getLinearVelocity(), -body.getAngularVelocity(),
                                                static_cast<btScalar>(h), before);
            // A ball's surface is the same at any orientation: its contacts are found at the
            // turned one, whose carry to `now` is a pure translation (spherical contacts keep
            // the direction they were found with).
            const bool ball = body.getCollisionShape()->getShapeType() == SPHERE_SHAPE_PROXYTYPE;
            const bool turns = ball || static_cast<double>(body.getAngularVelocity().length()) * h > kLargeTurn;
            found_at = turns ? btTransform(now.getBasis(), before.getOrigin()) : before;
            btVector3 plo, phi;
            body.getCollisionShape()->getAabb(now, lo, hi);
            body.getCollisionShape()->getAabb(before, plo, phi);
            lo.setMin(plo);
            hi.setMax(phi);
            travel = static_cast<double>((now.getOrigin() - before.getOrigin()).length() +
                                         body.getAngularVelocity().length() * h * body.getCollisionShape()->getAngularMotionDisc());
        }
    };

    /// A string's segments in a btDbvt of their swept bounds (where each segment was at the
    /// start of the step and where it is predicted to go, grown by its radius and the
    /// contact margin). Kept from step to step: each leaf is updated in place.
    struct SegmentTree {
        btDbvt tree;
        std::vector<btDbvtNode*> leaves;  // per segment; null while broken
    };

    struct Overlaps : btDbvt::ICollide {
        explicit Overlaps(std::vector<std::uint32_t>& out) : hits(out) {}
        void Process(const btDbvtNode* leaf) override {
            hits.push_back(static_cast<std::uint32_t>(reinterpret_cast<std::uintptr_t>(leaf->data)));
        }
        std::vector<std::uint32_t>& hits;
    };

    SegmentTree& treeFor(std::uint32_t string, const std::vector<Vec3>& start, const std::vector<Vec3>& pred,
                         const std::vector<double>& radius, const std::vector<std::uint8_t>& broken) {
        std::unique_ptr<SegmentTree>& slot = trees_[string];
        if (!slot || slot->leaves.size() != broken.size()) slot = std::make_unique<SegmentTree>();
        SegmentTree& t = *slot;
        t.leaves.resize(broken.size(), nullptr);
        for (std::size_t j = 0; j < broken.size(); ++j) {
            if (broken[j]) {
                if (t.leaves[j]) t.tree.remove(t.leaves[j]);
                t.leaves[j] = nullptr;
                continue;
            }
            const double margin = radius[j] + kContactMargin;
            const Vec3 lo = start[j].cwiseMin(start[j + 1]).cwiseMin(pred[j]).cwiseMin(pred[j + 1]).array() - margin;
            const Vec3 hi = start[j].cwiseMax(start[j + 1]).cwiseMax(pred[j]).cwiseMax(pred[j + 1]).array() + margin;
            btDbvtVolume volume = btDbvtVolume::FromMM(toBullet(lo), toBullet(hi));
            if (t.leaves[j])
                t.tree.update(t.leaves[j], volume);
            else
                t.leaves[j] = t.tree.insert(volume, reinterpret_cast<void*>(static_cast<std::uintptr_t>(j)));
        }
        return t;
    }

    std::map<std::uint32_t, std::unique_ptr<SegmentTree>> trees_;  // per string index
    std::vector<std::uint32_t> hits_;  ///< m: near contacts are kept, in case the solve closes them
    std::vector<std::uint8_t> end_covered_;  ///< per particle, coverEnds' marks (all 0 between calls)

    /// A surface's triangles in a btDbvt of their swept bounds (where the corners were at
    /// the start of the step and where they are predicted to go, grown by the radius and the
    /// margin). Kept from step to step, keyed by the mesh's vertex array; triangles are only
    /// ever appended, so leaf t stays triangle t and is updated in place.
    struct TriangleTree {
        btDbvt tree;
        std::vector<btDbvtNode*> leaves;
    };

    TriangleTree& triangleTree(const void* key, const std::vector<Vec3>& start, const std::vector<Vec3>& pred,
                               const std::vector<std::array<std::uint32_t, 3>>& triangles, double margin) {
        std::unique_ptr<TriangleTree>& slot = triangle_trees_[key];
        if (!slot || slot->leaves.size() > triangles.size()) slot = std::make_unique<TriangleTree>();
        TriangleTree& t = *slot;
        t.leaves.resize(triangles.size(), nullptr);
        for (std::size_t k = 0; k < triangles.size(); ++k) {
            Vec3 lo = Vec3::Constant(1e300), hi = Vec3::Constant(-1e300);
            for (std::uint32_t v : triangles[k]) {
                if (v >= start.size()) continue;
                lo = lo.cwiseMin(start[v]).cwiseMin(pred[v]);
                hi = hi.cwiseMax(start[v]).cwiseMax(pred[v]);
            }
            if (!lo.allFinite() || !hi.allFinite()) lo = hi = Vec3::Constant(1e30);  // far away: never a candidate
            btDbvtVolume volume = btDbvtVolume::FromMM(toBullet(Vec3(lo.array() - margin)), toBullet(Vec3(hi.array() + margin)));
            if (t.leaves[k])
                t.tree.update(t.leaves[k], volume);
            else
                t.leaves[k] = t.tree.insert(volume, reinterpret_cast<void*>(static_cast<std::uintptr_t>(k)));
        }
        return t;
    }

    std::map<const void*, std::unique_ptr<TriangleTree>> triangle_trees_;  // per mesh (its vertex array)
    std::vector<std::uint32_t> vertex_stamp_;   // per vertex: the body it was last tested against
    std::vector<std::uint32_t> touched_stamp_;  // per vertex: the body it last touched

    /// A body touching a surface inside a triangle (speculative, as a vertex): Bullet's GJK
    /// (with EPA when they overlap) between the triangle where it was at the start of the
    /// step and the convex body where it was. Kept when the closest point of the triangle
    /// lies between its corners (its largest barycentric weight below 0.9: near a corner,
    /// the corner's own sphere answers) and the gap is within the reach.
    void testFace(std::size_t object, const std::array<std::uint32_t, 3>& tri, const std::vector<Vec3>& x, double radius,
                  btRigidBody& body, const SweptBody& swept, double reach, RigidId proxy, std::vector<PointContact>& out) {
        const Vec3 &p0 = x[tri[0]], &p1 = x[tri[1]], &p2 = x[tri[2]];
        const Vec3 e1 = p1 - p0, e2 = p2 - p0;
        const double area2 = e1.cross(e2).squaredNorm();
        if (!(area2 > 1e-24)) return;
        btTriangleShape shape(toBullet(p0), toBullet(p1), toBullet(p2));
        shape.setMargin(0);
        const auto* convex = static_cast<const btConvexShape*>(body.getCollisionShape());
        btVoronoiSimplexSolver simplex;
        btGjkEpaPenetrationDepthSolver epa;
        btGjkPairDetector gjk(&shape, convex, &simplex, &epa);
        btGjkPairDetector::ClosestPointInput input;
        input.m_transformA.setIdentity();
        input.m_transformB = swept.before;
        const double limit = radius + reach;
        input.m_maximumDistanceSquared = static_cast<btScalar>(limit * limit);
        btPointCollector result;
        gjk.getClosestPoints(input, result, nullptr);
        if (!result.m_hasResult || result.m_distance > limit) return;
        // From the body (B) toward the triangle (A); the triangle's point is past the gap.
        const Vec3 normal = toCore(result.m_normalOnBInWorld).normalized();
        if (!normal.allFinite()) return;
        const Vec3 on_body = toCore(result.m_pointInWorld);
        const Vec3 on_triangle = on_body + static_cast<double>(result.m_distance) * normal;
        // Barycentric weights of that point.
        const Vec3 d = on_triangle - p0;
        const double d11 = e1.dot(e1), d12 = e1.dot(e2), d22 = e2.dot(e2), d1 = d.dot(e1), d2 = d.dot(e2);
        const double det = d11 * d22 - d12 * d12;
        if (!(det > 0.0)) return;
        double w1 = (d22 * d1 - d12 * d2) / det, w2 = (d11 * d2 - d12 * d1) / det;
        Vec3 w(1.0 - w1 - w2, w1, w2);
        w = w.cwiseMax(0.0);
        if (!(w.sum() > 0.0)) return;
        w /= w.sum();
        if (w.maxCoeff() > 0.9) return;
        PointContact c;
        c.object = static_cast<std::uint32_t>(object);
        c.vertex = tri[0];
        c.face = tri;
        c.weights = w;
        // The contact point and normal move with the body: from the earlier pose to now.
        const btTransform& now = swept.now;
        c.point = toCore(now * (swept.before.inverse() * toBullet(on_body)));
        c.normal = toCore(now.getBasis() * (swept.before.getBasis().transpose() * toBullet(normal))).normalized();
        c.body = proxy;
        c.friction = body.getFriction();
        out.push_back(c);
    }

    /// Collects the deepest point Bullet reports between the capsule and the body.
    struct Deepest : btCollisionWorld::ContactResultCallback {
        const btCollisionObject* capsule = nullptr;
        bool found = false;
        btScalar distance = BT_LARGE_FLOAT;
        btVector3 on_capsule, on_body, normal;  // normal: from the body toward the capsule
        btScalar addSingleResult(btManifoldPoint& cp, const btCollisionObjectWrapper* a, int, int,
                                 const btCollisionObjectWrapper*, int, int) override {
            if (cp.getDistance() >= distance) return 0;
            const bool capsule_first = a->getCollisionObject() == capsule;
            distance = cp.getDistance();
            on_capsule = capsule_first ? cp.m_positionWorldOnA : cp.m_positionWorldOnB;
            on_body = capsule_first ? cp.m_positionWorldOnB : cp.m_positionWorldOnA;
            normal = capsule_first ? cp.m_normalWorldOnB : -cp.m_normalWorldOnB;
            found = true;
            return 0;
        }
    };

    /// Sharpens Bullet's closest points of a segment (a + s axis, the capsule's core) and a
    /// curved convex body at pose `pose`. GJK stops when its distance is within a relative
    /// 1e-6 of squared distance (in float), which leaves its separating direction off by
    /// up to a tenth of a radian on a cylinder (contact points inside it, tilted contact
    /// planes a rope creeps along). The plane through the body's
    /// support point along a direction n, normal n, always bounds the body; the best such
    /// plane for the segment is the one the segment lies farthest in front of,
    ///     f(n) = min(n . a, n . b) - max over the body of n . y,
    /// the separating distance GJK itself maximises. A pattern search on the unit sphere
    /// from GJK's direction (steps of 0.1 rad, halved down to 1e-6 rad, four tangent
    /// directions each) climbs it: f is only piecewise smooth on a cylinder (its support
    /// jumps between rims), so no gradient steps. Polytopes (GJK is exact there), spheres
    /// and capsules (points and segments with a margin) keep GJK's answer, and so does a
    /// segment that reaches into the body.
    static void refineOnConvexBody(const btCollisionShape& shape, const btTransform& pose, const Vec3& a, const Vec3& axis,
                                   Vec3& normal, Vec3& on_body, double& s) {
        if (!shape.isConvex() || shape.isPolyhedral()) return;
        const int type = shape.getShapeType();
        if (type == SPHERE_SHAPE_PROXYTYPE || type == CAPSULE_SHAPE_PROXYTYPE) return;
        const auto& convex = static_cast<const btConvexShape&>(shape);
        const Vec3 b = a + axis;
        auto support = [&](const Vec3& n) {
            return toCore(pose * convex.localGetSupportingVertex(pose.getBasis().transpose() * toBullet(n)));
        };
        auto separation = [&](const Vec3& n) { return std::min(n.dot(a), n.dot(b)) - n.dot(support(n)); };
        double best = separation(normal);
        if (!(best > 0.0)) return;  // reaching into the body: GJK's penetration answer stands
        const double start = best;
        Vec3 n = normal;
        for (double step = kRefineFirstStep; step > kRefineLastStep; step *= 0.5) {
            bool moved = true;
            while (moved) {
                moved = false;
                const Vec3 t1 = n.unitOrthogonal(), t2 = n.cross(t1);
                for (const Vec3& dir : {t1, Vec3(-t1), t2, Vec3(-t2)}) {
                    const Vec3 trial = (n + step * dir).normalized();
                    const double sep = separation(trial);
                    if (sep > best) {
                        best = sep;
                        n = trial;
                        moved = true;
                    }
                }
            }
        }
        if (!(best > start + kRefineGain)) return;
        normal = n;
        on_body = support(n);
        // Where on the segment: GJK's point while it is (to 1 um) as near the new plane as
        // the segment gets, else the nearer end. (The support point itself may lie anywhere
        // along a cylinder's straight side, e.g. on its rim: projecting it onto the segment
        // put the contacts of a rope lying across a cylinder at segment ends, and the rope
        // crept off.)
        const double nearest = std::min(n.dot(a), n.dot(b));
        if (n.dot(a + s * axis) > nearest + kRefineKeepPoint) s = n.dot(a) <= n.dot(b) ? 0.0 : 1.0;
    }

    /// Where a segment lies on a face of a box, the support is a line, not a point. GJK
    /// answers with one closest point anywhere along it (which one changes from step to
    /// step with rounding), and a single contact there lets the segment rock about it:
    /// its ends dip into the face and are pushed out at the next step at another point,
    /// which feeds energy into whatever rests on it (a box on two ropes yaws and slides
    /// off under Coulomb friction). As Box2D and Bullet's own box-box manifolds do, the
    /// face is clipped instead: the face whose plane separates the segment (the capsule's
    /// core) from the box best, when it does as well as GJK's answer (kFaceSlack), and
    /// the part of the segment over that face (the four side planes of the face, in the
    /// box's frame) gives a contact at each end of that part, at most two, each with the
    /// face's normal and its point on the face. No face qualifies where the segment's
    /// nearest feature is an edge or a corner (a rope bending over an edge): GJK's answer
    /// stands, and so where the segment is over no part of the face. Writes `found`
    /// contacts into `s_out`, `normal_out` and `on_body_out` (world, at `pose`).
    static int boxFaceContacts(const btBoxShape& box, const btTransform& pose, const Vec3& a, const Vec3& axis, double radius,
                               double reach, const Vec3& gjk_normal, std::array<double, 2>& s_out, Vec3& normal_out,
                               std::array<Vec3, 2>& on_body_out) {
        Mat3 basis;
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j) basis(i, j) = pose.getBasis()[i][j];
        const Vec3 centre = toCore(pose.getOrigin());
        const Vec3 half = toCore(box.getHalfExtentsWithMargin());
        const Vec3 la = basis.transpose() * (a - centre), ld = basis.transpose() * axis, lb = la + ld;
        // Separation of the core along a direction (box frame): the segment's nearest end
        // minus the box's support.
        auto separation = [&](const Vec3& n) {
            return std::min(n.dot(la), n.dot(lb)) - (std::abs(n.x()) * half.x() + std::abs(n.y()) * half.y() + std::abs(n.z()) * half.z());
        };
        int face = -1;
        double sign = 1.0, best = -std::numeric_limits<double>::infinity();
        for (int i = 0; i < 3; ++i)
            for (const double sg : {1.0, -1.0}) {
                const double sep = std::min(sg * la[i], sg * lb[i]) - half[i];
                if (sep > best) {
                    best = sep;
                    face = i;
                    sign = sg;
                }
            }
        if (best < separation(basis.transpose() * gjk_normal) - kFaceSlack) return 0;
        // The part of the segment over the face: |p_j(t)| <= half_j for the face's other
        // two axes.
        double t0 = 0.0, t1 = 1.0;
        for (int j = 0; j < 3; ++j) {
            if (j == face) continue;
            if (std::abs(ld[j]) < 1e-12) {
                if (std::abs(la[j]) > half[j]) return 0;
                continue;
            }
            double lo = (-half[j] - la[j]) / ld[j], hi = (half[j] - la[j]) / ld[j];
            if (lo > hi) std::swap(lo, hi);
            t0 = std::max(t0, lo);
            t1 = std::min(t1, hi);
        }
        if (!(t0 <= t1)) return 0;
        // Bullet's points are floats: a part that reaches to within kEndSnap of the
        // segment's end is held at the end (its particle).
        if (t0 < kEndSnap) t0 = 0.0;
        if (t1 > 1.0 - kEndSnap) t1 = 1.0;
        Vec3 ln = Vec3::Zero();
        ln[face] = sign;
        normal_out = basis * ln;
        int found = 0;
        for (const double t : {t0, t1}) {
            if (found == 1 && t - s_out[0] < kEndSnap) break;  // one point (the part is a point)
            Vec3 p = la + t * ld;
            if (sign * p[face] - half[face] - radius > reach) continue;
            p[face] = sign * half[face];
            s_out[static_cast<std::size_t>(found)] = t;
            on_body_out[static_cast<std::size_t>(found)] = centre + basis * p;
            ++found;
        }
        return found;
    }

    /// Speculative contact (continuous in effect): the closest points of the segment and
    /// the body at the *start* of the step give the normal and the contact point (in the
    /// body's frame), kept when they are closer than the distance both can travel this
    /// step. The solve then keeps the segment on its side of that plane at the end of the
    /// step, so a crate at 10 m/s cannot pass a 5 mm rope between two steps, and a rope
    /// already pressed into an edge is pushed back the way it came, not sideways.
    void test(StringId string, std::uint32_t segment, const Vec3& a, const Vec3& b, double radius, btRigidBody& body,
              const btTransform& before, double reach, RigidId proxy, std::vector<RigidContact>& out) {
        const Vec3 axis = b - a;
        const double length = axis.norm();
        if (!(length > 0.0)) return;
        btCapsuleShape shape(static_cast<btScalar>(radius), static_cast<btScalar>(length));
        btCollisionObject capsule;
        capsule.setCollisionShape(&shape);
        const btQuaternion turn = shortestArcQuat(btVector3(0, 1, 0), toBullet(axis / length));
        capsule.setWorldTransform(btTransform(turn, toBullet(0.5 * (a + b))));
        testShape(capsule, string, segment, a, axis, radius, body, before, reach, proxy, out);
    }

    /// A segment lying along a face has its closest point anywhere along it, and the
    /// narrow phase answers with one of its ends. Where two neighbouring segments both
    /// answer with their far ends, the particle between them has no contact: it sinks into
    /// the body within the step and is pushed out at the next (a rope lying on the ground
    /// chattered at 6 cm/s and took 10-20 Newton iterations a step). Each such particle of
    /// the segments `hits` (sorted) gets a contact of its own, a sphere of the radius there,
    /// where it is within reach: on the segment after it (s = 0), or before it at the last.
    /// `first`: where this body's contacts with the string begin in `out`.
    void coverEnds(StringId string, const std::vector<Vec3>& start, const std::vector<double>& radius,
                   const std::vector<std::uint32_t>& hits, std::size_t first, btRigidBody& body,
                   const btTransform& before, double reach, RigidId proxy, std::vector<RigidContact>& out) {
        const std::size_t found = out.size();
        // The particles the answers are at (marks cleared again below: the scratch stays
        // all zero between calls, and a call costs its contacts, not the string's length).
        if (end_covered_.size() < start.size()) end_covered_.resize(start.size(), 0);
        for (std::size_t k = first; k < found; ++k)
            if (out[k].s == 0.0 || out[k].s == 1.0) end_covered_[out[k].segment + (out[k].s == 1.0 ? 1 : 0)] = 1;
        auto hit = [&](std::uint32_t j) { return std::binary_search(hits.begin(), hits.end(), j); };
        for (std::size_t k = first; k < found; ++k) {
            const RigidContact& c = out[k];
            if (c.s != 0.0 && c.s != 1.0) continue;  // a point inside the segment: a true single support
            const std::uint32_t p = c.s == 0.0 ? c.segment + 1 : c.segment;  // the answer's other end
            if (end_covered_[p]) continue;
            const std::uint32_t segment = hit(p) && p + 1 < start.size() ? p : p - 1;
            const std::size_t before_test = out.size();
            btSphereShape shape(static_cast<btScalar>(radius[segment]));
            btCollisionObject sphere;
            sphere.setCollisionShape(&shape);
            sphere.setWorldTransform(btTransform(btQuaternion::getIdentity(), toBullet(start[p])));
            testShape(sphere, string, segment, start[p], Vec3::Zero(), radius[segment], body, before, reach, proxy, out);
            if (out.size() > before_test) out.back().s = segment == p ? 0.0 : 1.0;
        }
        for (std::size_t k = first; k < found; ++k)
            if (out[k].s == 0.0 || out[k].s == 1.0) end_covered_[out[k].segment + (out[k].s == 1.0 ? 1 : 0)] = 0;
    }

    /// A mesh vertex: a sphere of the radius at `centre`.
    void testSphere(const Vec3& centre, double radius, btRigidBody& body, const btTransform& before, double reach,
                    RigidId proxy, std::vector<RigidContact>& out) {
        btSphereShape shape(static_cast<btScalar>(radius));
        btCollisionObject sphere;
        sphere.setCollisionShape(&shape);
        sphere.setWorldTransform(btTransform(btQuaternion::getIdentity(), toBullet(centre)));
        testShape(sphere, StringId{}, 0, centre, Vec3::Zero(), radius, body, before, reach, proxy, out);
    }

    /// Bullet's narrow phase between `object` (a capsule of axis `a` + s `axis`, or a
    /// sphere: axis zero) and the body where it was at the start of the step.
    void testShape(btCollisionObject& object, StringId string, std::uint32_t segment, const Vec3& a, const Vec3& axis,
                   double radius, btRigidBody& body, const btTransform& before, double reach, RigidId proxy,
                   std::vector<RigidContact>& out) {
        btCollisionObject& capsule = object;
        const double length = axis.norm();
        // Test against the body where it was: a stand-in object at the earlier pose.
        btCollisionObject earlier;
        earlier.setCollisionShape(body.getCollisionShape());
        earlier.setWorldTransform(before);
        Deepest result;
        result.capsule = &capsule;
        result.m_closestDistanceThreshold = static_cast<btScalar>(reach);
        owner_.world_->contactPairTest(&capsule, &earlier, result);
        if (!result.found) return;
        RigidContact c;
        c.string = string;
        c.segment = segment;
        Vec3 normal = toCore(result.normal).normalized();
        Vec3 on_body = toCore(result.on_body);
        // The axis point behind the capsule's surface point, as a fraction along the segment.
        const Vec3 on_axis = toCore(result.on_capsule) + radius * normal;
        c.s = length > 0.0 ? std::clamp((on_axis - a).dot(axis) / (length * length), 0.0, 1.0) : 0.0;
        // Bullet's points are floats (1e-7 of the coordinates): an answer at a cap's pole
        // is the segment's end.
        if (c.s < kEndSnap) c.s = 0.0;
        if (c.s > 1.0 - kEndSnap) c.s = 1.0;
        refineOnConvexBody(*body.getCollisionShape(), before, a, axis, normal, on_body, c.s);
        // The contact point moves with the body: from the earlier pose to the current one.
        const btTransform at = now(body);
        c.body = proxy;
        c.friction = body.getFriction();
        c.spherical = body.getCollisionShape()->getShapeType() == SPHERE_SHAPE_PROXYTYPE;
        auto add = [&](double s, const Vec3& n, const Vec3& point) {
            c.s = s;
            c.point = toCore(at * (before.inverse() * toBullet(point)));
            c.normal = toCore(at.getBasis() * (before.getBasis().transpose() * toBullet(n))).normalized();
            out.push_back(c);
        };
        if (length > 0.0 && body.getCollisionShape()->getShapeType() == BOX_SHAPE_PROXYTYPE) {
            std::array<double, 2> s_face{};
            std::array<Vec3, 2> on_face{};
            Vec3 face_normal;
            const int found = boxFaceContacts(static_cast<const btBoxShape&>(*body.getCollisionShape()), before, a, axis,
                                              radius, reach, normal, s_face, face_normal, on_face);
            for (int k = 0; k < found; ++k) add(s_face[static_cast<std::size_t>(k)], face_normal, on_face[static_cast<std::size_t>(k)]);
            if (found > 0) return;
        }
        add(c.s, normal, on_body);
    }

    Impl& owner_;
};

BulletWorld::Impl::Impl(btDiscreteDynamicsWorld& world, const WorldSettings& settings)
    : world_(&world), core_(std::make_unique<World>(settings)), action_(std::make_unique<Action>(*this)),
      contacts_(std::make_unique<Contacts>(*this)) {
    core_->setContactProvider(contacts_.get());
    try {
        claim_ = std::make_unique<IslandClaimSolver>(world, ClaimScope::Island);
        claim_->setLeaveJointed(true);  // joints the island solve does not take stay Bullet's
        claim_->setTakenJoints(islandJoint);
    } catch (const std::invalid_argument&) {
        claim_.reset();  // a multibody solver: Bullet keeps solving the bodies' contacts
    }
    // Group and mask 0: the sentinel never pairs with anything nor answers ray tests.
    world_->addCollisionObject(&action_->sentinel(), 0, 0);
    installPairFilter();
    world_->addAction(action_.get());
}

// The broadphase finds the rigid bodies near each string (its bounds grown by how far
// its particles may travel this step); they become proxies for the step.
void BulletWorld::Impl::findCandidates(double h) {
    candidates_.clear();
    for (StringId id : core_->strings()) {
        const StringView v = core_->view(id);
        if (v.frozen) continue;
        Vec3 lo = Vec3::Constant(1e300), hi = Vec3::Constant(-1e300);
        // The fastest particle's speed from the largest square: one root (the same value,
        // as the root is monotonic and correctly rounded), not one per particle.
        double reach2 = 0.0;
        for (std::size_t p = 0; p < v.particleCount(); ++p) {
            lo = lo.cwiseMin((*v.positions)[p]);
            hi = hi.cwiseMax((*v.positions)[p]);
            reach2 = std::max(reach2, (*v.velocities)[p].squaredNorm());
        }
        const double reach = std::sqrt(reach2);
        const double grow = v.radius * 2.0 + reach * h + 0.5 * 9.81 * h * h + 0.01;
        std::vector<btRigidBody*> found = bodiesIn(lo.array() - grow, hi.array() + grow);
        const auto filter = string_filters_.find(id.index);
        if (filter != string_filters_.end())
            found.erase(std::remove_if(found.begin(), found.end(), [&](const btRigidBody* b) { return !filter->second.passes(*b); }),
                        found.end());
        if (found.empty()) continue;
        for (btRigidBody* body : found) proxyFor(*body);
        candidates_[id.index] = std::move(found);
    }
    // Meshes (sheets, cloths): their bodies get proxies now, before the step, so that the
    // point query during the step only reads (a proxy added mid-step would move the core's
    // body table under the solver).
    mesh_candidates_.clear();
    for (const auto& [lo, hi] : core_->meshBounds(h)) {
        for (btRigidBody* body : bodiesIn(lo, hi)) {
            proxyFor(*body);
            mesh_candidates_.push_back(body);
        }
    }
    std::sort(mesh_candidates_.begin(), mesh_candidates_.end());
    mesh_candidates_.erase(std::unique(mesh_candidates_.begin(), mesh_candidates_.end()), mesh_candidates_.end());
}

std::vector<btRigidBody*> BulletWorld::Impl::bodiesIn(const Vec3& lo, const Vec3& hi) const {
    struct Collect : btBroadphaseAabbCallback {
        const btCollisionObject* sentinel = nullptr;
        std::vector<btRigidBody*> found;
        bool process(const btBroadphaseProxy* proxy) override {
            auto* object = static_cast<btCollisionObject*>(proxy->m_clientObject);
            if (object == sentinel || !object->hasContactResponse()) return true;
            if (btRigidBody* body = btRigidBody::upcast(object)) found.push_back(body);
            return true;
        }
    };
    Collect collect;
    collect.sentinel = &action_->sentinel();
    world_->getBroadphase()->aabbTest(toBullet(lo), toBullet(hi), collect);
    std::sort(collect.found.begin(), collect.found.end(), [](const btRigidBody* a, const btRigidBody* b) {
        return a->getBroadphaseHandle()->getUid() < b->getBroadphaseHandle()->getUid();  // deterministic order
    });
    return collect.found;
}

BulletWorld::Impl::~Impl() {
    removeRopeObjectsFromWorld();
    if (attachedToBullet()) {
        world_->removeAction(action_.get());
        world_->removeCollisionObject(&action_->sentinel());
    } else if (claim_) {
        claim_->worldDestroyed();
    }
}

bool BulletWorld::Impl::attachedToBullet() const { return action_->inWorld(); }
World& BulletWorld::core() {
    impl_->dropBodiesIfDetached();
    return *impl_->core_;
}

// Once the Bullet world is gone its bodies may be too: their proxies leave the core (the
// strings holding them report Release events, cause body_removed, at their next step) and
// no pointer to them is kept.
void BulletWorld::Impl::dropBodiesIfDetached() {
    if (attachedToBullet()) return;
    for (const auto& [body, id] : proxies_) core_->removeRigid(id);
    proxies_.clear();
    named_.clear();
    candidates_.clear();
    mesh_candidates_.clear();
    removeRopeObjectsFromWorld();  // those still in a world that lost only the sentinel
    rope_objects_.clear();
}
const World& BulletWorld::core() const { return *impl_->core_; }
StringId BulletWorld::addString(const StringDesc& desc) {
    const StringId id = impl_->core_->addString(desc);
    impl_->string_filters_.erase(id.index);
    impl_->syncRopeObject(id);
    return id;
}
StringId BulletWorld::addString(const StringDesc& desc, int group, int mask) {
    const StringId id = impl_->core_->addString(desc);
    impl_->string_filters_[id.index] = Impl::Filter{group, mask};
    impl_->syncRopeObject(id);
    return id;
}
// A removed string's slot may hold the next string added (with the next generation):
// nothing of it is kept.
void BulletWorld::removeString(StringId id) {
    impl_->core_->removeString(id);
    impl_->dropRopeObject(id);
    impl_->string_filters_.erase(id.index);
    impl_->peaks_.erase(id);
    impl_->string_users_.erase(id);
    auto& forces = impl_->forces_;
    auto& pins = impl_->pins_;
    auto& turns = impl_->turns_;
    forces.erase(forces.lower_bound({id, INT_MIN}), forces.upper_bound({id, INT_MAX}));
    pins.erase(pins.lower_bound({id, INT_MIN}), pins.upper_bound({id, INT_MAX}));
    turns.erase(turns.lower_bound({id, INT_MIN}), turns.upper_bound({id, INT_MAX}));
}

// Bullet's rule (btOverlappingPairCache's needsBroadphaseCollision), both ways.
bool BulletWorld::Impl::Filter::passes(const btRigidBody& body) const {
    const btBroadphaseProxy* proxy = body.getBroadphaseHandle();
    if (!proxy) return false;
    return (group & proxy->m_collisionFilterMask) != 0 && (proxy->m_collisionFilterGroup & mask) != 0;
}

// A sheet's query object is its vertex array (PaperView::positions); a cloth's query lists
// the live cloths in slot order (ClothSystem::collideBodies).
BulletWorld::Impl::Filter BulletWorld::Impl::meshFilter(const PointQuery& query, std::size_t i) const {
    if (cloth_filters_.empty() && paper_filters_.empty()) return Filter{};
    for (const PaperId id : core_->papers()) {
        if (core_->viewPaper(id).positions != query.start[i]) continue;
        const auto it = paper_filters_.find(id.index);
        return it == paper_filters_.end() ? Filter{} : it->second;
    }
    std::size_t k = 0;
    for (const ClothId id : core_->cloths()) {
        if (core_->viewCloth(id).frozen) continue;
        if (k++ != i) continue;
        const auto it = cloth_filters_.find(id.index);
        return it == cloth_filters_.end() ? Filter{} : it->second;
    }
    return Filter{};
}
const std::vector<BulletEvent>& BulletWorld::events() const { return impl_->events_; }
void BulletWorld::clearEvents() { impl_->events_.clear(); }
const StageTimes& BulletWorld::totalStageTimes() const { return impl_->total_; }
const std::string& BulletWorld::lastError() const { return impl_->last_error_; }

void BulletWorld::Impl::debugDraw(btIDebugDraw& drawer) const {
    // Colours by load fraction T / (rupture stress * pi r^2), clamped to [0, 1], as MuJoCo's
    // cable colours by stress up to a vmax; the rupture stress is the material's nominal one
    // (the per-segment variation is a fraction of a percent).
    for (const StringId id : core_->strings()) {
        const StringView v = core_->view(id);
        const double rupture = core_->desc(id).material.tensile.rupture;
        const auto& x = *v.positions;
        for (std::size_t j = 0; j < v.segmentCount(); ++j) {
            const btVector3 a = toBullet(x[j]), b = toBullet(x[j + 1]);
            if ((*v.broken)[j]) {
                drawer.drawSphere((a + b) * btScalar(0.5), static_cast<btScalar>(std::max(2.0 * v.radius, 0.005)),
                                  brokenMarkerColor());
                continue;
            }
            const Rgb c = tensionColor(loadFraction((*v.tension)[j], rupture, v.radius));
            drawer.drawLine(a, b, btVector3(c.r, c.g, c.b));
        }
    }
    // Cloths: one line per intact yarn edge, coloured as the strings; torn yarns are gaps.
    for (const ClothId id : core_->cloths()) {
        const ClothView v = core_->viewCloth(id);
        const double rupture = core_->clothDesc(id).material.tensile.rupture;
        const auto& x = *v.positions;
        for (std::size_t e = 0; e < v.edgeCount(); ++e) {
            if ((*v.broken)[e]) continue;
            const auto [i, k] = (*v.edges)[e];
            const Rgb c = tensionColor(loadFraction((*v.tension)[e], rupture, v.yarn_radius));
            drawer.drawLine(toBullet(x[i]), toBullet(x[k]), btVector3(c.r, c.g, c.b));
        }
    }
    // Paper sheets: every triangle edge once in the paper's colour, then the creases and
    // folds (paperCreaseLines) in the crease colour.
    for (const PaperId id : core_->papers()) {
        const PaperView v = core_->viewPaper(id);
        const auto& x = *v.positions;
        std::vector<std::array<std::uint32_t, 2>> edges;
        edges.reserve(3 * v.triangles->size());
        for (const auto& t : *v.triangles)
            for (int c = 0; c < 3; ++c) edges.push_back({std::min(t[c], t[(c + 1) % 3]), std::max(t[c], t[(c + 1) % 3])});
        std::sort(edges.begin(), edges.end());
        edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
        for (const auto& [i, k] : edges)
            if (i < x.size() && k < x.size()) drawer.drawLine(toBullet(x[i]), toBullet(x[k]), paperColor());
        for (const auto& [i, k] : paperCreaseLines(v))
            if (i < x.size() && k < x.size()) drawer.drawLine(toBullet(x[i]), toBullet(x[k]), creaseColor());
    }
}

void BulletWorld::attach(StringId id, int particle, const btVector3& world_point) {
    impl_->core_->attachToPoint(id, particle, toCore(world_point));
}

RigidId BulletWorld::Impl::proxyFor(btRigidBody& body) {
    auto it = proxies_.find(&body);
    if (it != proxies_.end()) return it->second;
    RigidState state;
    state.position = toCore(body.getCenterOfMassPosition());
    state.orientation = toCore(body.getOrientation());
    const RigidId id = core_->addRigid(state);
    proxies_.emplace(&body, id);
    return id;
}

void BulletWorld::attach(StringId id, int particle, btRigidBody& body, const btVector3& local_point) {
    if (!body.getBroadphaseHandle()) throw InvalidInput("body", "is not in the Bullet world");
    requireLive(*impl_->core_, id);
    impl_->core_->resolveParticle(id, particle);  // validates before anything is created
    impl_->core_->attachToRigid(id, particle, impl_->proxyFor(body), toCore(local_point));
}

void BulletWorld::detach(StringId id, int particle) { impl_->core_->detach(id, particle); }

ClothId BulletWorld::addCloth(const ClothDesc& desc) {
    const ClothId id = impl_->core_->addCloth(desc);
    impl_->cloth_filters_.erase(id.index);
    return id;
}
ClothId BulletWorld::addCloth(const ClothDesc& desc, int group, int mask) {
    const ClothId id = impl_->core_->addCloth(desc);
    impl_->cloth_filters_[id.index] = Impl::Filter{group, mask};
    return id;
}
void BulletWorld::removeCloth(ClothId id) {
    impl_->core_->removeCloth(id);
    impl_->cloth_filters_.erase(id.index);
    impl_->cloth_users_.erase(id);
    auto& forces = impl_->cloth_forces_;
    forces.erase(forces.lower_bound({id, INT_MIN}), forces.upper_bound({id, INT_MAX}));
}

void BulletWorld::removePaper(PaperId id) {
    impl_->core_->removePaper(id);
    impl_->paper_filters_.erase(id.index);
    impl_->paper_users_.erase(id);
    auto& forces = impl_->paper_forces_;
    forces.erase(forces.lower_bound({id, 0u}), forces.upper_bound({id, UINT32_MAX}));
}

void BulletWorld::attachCloth(ClothId id, int vertex, const btVector3& world_point) {
    impl_->core_->attachClothToPoint(id, vertex, toCore(world_point));
}

void BulletWorld::attachCloth(ClothId id, int vertex, btRigidBody& body, const btVector3& local_point) {
    if (!body.getBroadphaseHandle()) throw InvalidInput("body", "is not in the Bullet world");
    requireLive(*impl_->core_, id);
    const int n = impl_->core_->clothDesc(id).vertexCount();
    if (vertex < -n || vertex >= n) throw InvalidInput("vertex", "vertex index " + std::to_string(vertex) + " out of range");
    impl_->core_->attachClothToRigid(id, vertex, impl_->proxyFor(body), toCore(local_point));
}

PaperId BulletWorld::addPaper(const PaperDesc& desc) {
    const PaperId id = impl_->core_->addPaper(desc);
    impl_->paper_filters_.erase(id.index);
    return id;
}
PaperId BulletWorld::addPaper(const PaperDesc& desc, int group, int mask) {
    const PaperId id = impl_->core_->addPaper(desc);
    impl_->paper_filters_[id.index] = Impl::Filter{group, mask};
    return id;
}

void BulletWorld::attachPaper(PaperId id, int vertex, const btVector3& world_point) {
    impl_->core_->attachPaperToPoint(id, vertex, toCore(world_point));
}

void BulletWorld::attachPaper(PaperId id, int vertex, btRigidBody& body, const btVector3& local_point) {
    if (!body.getBroadphaseHandle()) throw InvalidInput("body", "is not in the Bullet world");
    requireLive(*impl_->core_, id);
    impl_->core_->paperVertex(id, vertex);  // refused before a proxy is made for the body
    impl_->core_->attachPaperToRigid(id, vertex, impl_->proxyFor(body), toCore(local_point));
}

void BulletWorld::forgetBody(const btRigidBody& body) {
    auto it = impl_->proxies_.find(&body);
    if (it == impl_->proxies_.end()) return;
    impl_->core_->removeRigid(it->second);
    impl_->named_.erase(it->first);
    impl_->proxies_.erase(it);
}

RigidId BulletWorld::bodyId(btRigidBody& body) {
    if (!body.getBroadphaseHandle()) throw InvalidInput("body", "is not in the Bullet world");
    const RigidId id = impl_->proxyFor(body);
    impl_->named_.insert(&body);
    return id;
}

bool BulletWorld::Impl::isCandidate(const btRigidBody* body) const {
    if (std::binary_search(mesh_candidates_.begin(), mesh_candidates_.end(), body)) return true;
    for (const auto& [string, bodies] : candidates_)
        if (std::find(bodies.begin(), bodies.end(), body) != bodies.end()) return true;
    return false;
}

// Bodies out: the corrections as new poses and velocities. A body is woken (kept awake)
// only when a string, sheet or cloth holds it, pushed it (an impulse this step), or, asleep
// and so immovable this step, touched it: one that is merely near is left to Bullet's
// sleeping (btRigidBody::updateDeactivation), as Bullet's own contacts do.
void BulletWorld::Impl::writeBodies() {
    for (const auto& [key, id] : proxies_) {
        btRigidBody* body = const_cast<btRigidBody*>(key);
        const RigidState& s = core_->rigid(id);
        if (s.inverse_mass <= 0.0) continue;
        const bool holds = core_->rigidInUse(id);
        if (!s.awake) {
            if (holds || std::binary_search(contacts_->touched.begin(), contacts_->touched.end(), id.index)) body->activate();
            continue;
        }
        // A string that blew up this step is frozen (with its event) but may have moved
        // the body first: Bullet keeps the body's own finite state then.
        const bool finite_state = s.position.allFinite() && s.orientation.coeffs().allFinite() &&
                                  s.linear_velocity.allFinite() && s.angular_velocity.allFinite() &&
                                  std::fabs(s.orientation.norm() - 1.0) < 1e-3;
        if (!finite_state) continue;
        // No faster than the particles' clamp (WorldSettings::max_speed): a body a rope
        // flings keeps its direction and leaves at that speed.
        const double speed = s.linear_velocity.norm(), max_speed = core_->settings().max_speed;
        const Vec3 v = speed > max_speed ? Vec3(s.linear_velocity * (max_speed / speed)) : s.linear_velocity;
        body->setLinearVelocity(tearables::toBullet(v));
        body->setAngularVelocity(tearables::toBullet(s.angular_velocity));
        btTransform xf(toBullet(s.orientation), tearables::toBullet(s.position));
        body->setCenterOfMassTransform(xf);
        if (holds || s.impulse.squaredNorm() > 0.0) body->activate();  // its strings' tension stays true
    }
}

// The bodies Bullet's solver left to us this step (IslandClaimSolver): Bullet has moved
// each by h times its last velocity, without this step's forces. They start from the pose
// they had at the solve with the motion Bullet's solver gives a body before its contacts
// (btSequentialImpulseConstraintSolver::initSolverBody and convertBodies): the step's
// forces and gravity, h F / m and h I^-1 T, and the implicit gyroscopic term; then the
// core's island solve keeps them apart and holds them on their ropes.
void BulletWorld::Impl::startClaimedBodies(double h) {
    claimed_.clear();
    if (!claim_) return;
    const btScalar step = static_cast<btScalar>(h);
    for (const ClaimedBody& c : claim_->claimedBodies()) {
        btRigidBody& body = *c.body;
        claimed_.push_back(&body);
        body.setCenterOfMassTransform(c.transform);
        body.setAngularVelocity(c.angularVelocity);
        const btVector3 v = c.linearVelocity + body.getTotalForce() * (body.getInvMass() * step);
        btVector3 w = c.angularVelocity + body.getInvInertiaTensorWorld() * body.getTotalTorque() * step;
        if (body.getFlags() & BT_ENABLE_GYROSCOPIC_FORCE_IMPLICIT_BODY) w += body.computeGyroscopicImpulseImplicit_Body(step);
        btTransform moved;
        btTransformUtil::integrateTransform(c.transform, v, w, step, moved);
        body.setCenterOfMassTransform(moved);
        body.setLinearVelocity(v);
        body.setAngularVelocity(w);
        proxyFor(body);
    }
    std::sort(claimed_.begin(), claimed_.end());
}

// The bodies a string holds or touched this step are taken from Bullet's solver at the
// next, with every body of their Bullet islands (a crate resting on a roped board comes
// with the board), unless a joint is in the island.
void BulletWorld::Impl::claimIslandBodies() {
    if (!claim_) return;
    claim_->releaseAll();
    for (const auto& [key, id] : proxies_) {
        btRigidBody* body = const_cast<btRigidBody*>(key);
        if (body->isStaticOrKinematicObject() || !(core_->rigid(id).inverse_mass > 0.0)) continue;
        if (core_->rigidInUse(id) || std::binary_search(contacts_->string_touched.begin(), contacts_->string_touched.end(), id.index))
            claim_->claim(*body);
    }
}

// What the user gave for the next stepSimulation, spread over its internal steps: forces
// on every step, pins followed linearly to their target at the last one; both are done
// with at the frame's last step.
void BulletWorld::Impl::drive(int tick, int ticks) {
    for (auto it = forces_.begin(); it != forces_.end(); ++it) {
        const StringId id = it->first.first;
        if (core_->contains(id)) core_->applyForce(id, it->first.second, it->second);
    }
    for (const auto& [key, force] : cloth_forces_)
        if (core_->contains(key.first)) core_->applyClothForce(key.first, key.second, force);
    for (const auto& [key, force] : paper_forces_)
        if (core_->contains(key.first)) core_->applyPaperForce(key.first, key.second, force);
    for (auto it = pins_.begin(); it != pins_.end(); ++it) {
        const StringId id = it->first.first;
        Vec3 now;
        if (!core_->contains(id) || !core_->pinTarget(id, it->first.second, &now)) continue;  // detached since
        const double f = static_cast<double>(tick) / static_cast<double>(ticks);
        core_->movePin(id, it->first.second, tick == ticks ? it->second.to : it->second.from + f * (it->second.to - it->second.from));
    }
    // Turns: the share k / n of the whole angle reached at internal step k of n, all of it
    // at the last; an end unpinned since turns no further.
    for (auto& [key, turn] : turns_) {
        const auto [id, end] = key;
        if (!core_->contains(id) || !core_->pinTarget(id, end, nullptr)) continue;
        const double reached = tick == ticks ? turn.angle : turn.angle * tick / ticks;
        core_->turnEnd(id, end, reached - turn.done);
        turn.done = reached;
    }
    if (tick == ticks) {
        forces_.clear();
        cloth_forces_.clear();
        paper_forces_.clear();
        pins_.clear();
        turns_.clear();
    }
}

// Per segment, the largest tension of any step since the user cleared it: the solved
// tension, and for a segment that tore by tension this step the one it tore at (the Tear
// event's engineering stress on the original section, fracture.cpp, as the solved value is
// zeroed when it breaks).
void BulletWorld::Impl::recordPeaks() {
    const std::vector<StringId> live = core_->strings();
    for (auto it = peaks_.begin(); it != peaks_.end();)
        it = core_->contains(it->first) ? std::next(it) : peaks_.erase(it);
    for (const StringId id : live) {
        const std::vector<double>& t = *core_->view(id).tension;
        std::vector<double>& peak = peaks_[id];
        peak.resize(t.size(), 0.0);
        for (std::size_t j = 0; j < t.size(); ++j) peak[j] = std::max(peak[j], t[j]);
    }
    for (const Event& e : core_->events()) {
        if (e.type != EventType::Tear || e.cause != EventCause::Tension || !core_->contains(e.string)) continue;
        std::vector<double>& peak = peaks_[e.string];
        const double r0 = core_->desc(e.string).radius;
        if (e.segment >= 0 && static_cast<std::size_t>(e.segment) < peak.size())
            peak[e.segment] = std::max(peak[e.segment], e.stress * kPi * r0 * r0);
    }
}

void BulletWorld::applyForce(StringId id, int particle, const btVector3& force) {
    requireLive(*impl_->core_, id);
    const int p = impl_->core_->resolveParticle(id, particle);
    const Vec3 f = tearables::toCore(force);
    if (!f.allFinite()) throw InvalidInput("force", "must be finite");
    auto [it, fresh] = impl_->forces_.try_emplace({id, p}, Vec3::Zero());
    it->second += f;
}

// The core checks the object and the vertex (a zero force changes nothing).
void BulletWorld::applyClothForce(ClothId id, int vertex, const btVector3& force) {
    const Vec3 f = tearables::toCore(force);
    impl_->core_->applyClothForce(id, vertex, Vec3::Zero());
    if (!f.allFinite()) throw InvalidInput("force", "must be finite");
    auto [it, fresh] = impl_->cloth_forces_.try_emplace({id, vertex}, Vec3::Zero());
    it->second += f;
}

void BulletWorld::applyPaperForce(PaperId id, int index, const btVector3& force) {
    const Vec3 f = tearables::toCore(force);
    const std::uint32_t vertex = impl_->core_->paperVertex(id, index);
    if (!f.allFinite()) throw InvalidInput("force", "must be finite");
    auto [it, fresh] = impl_->paper_forces_.try_emplace({id, vertex}, Vec3::Zero());
    it->second += f;
}

void BulletWorld::movePin(StringId id, int particle, const btVector3& point) {
    requireLive(*impl_->core_, id);
    const int p = impl_->core_->resolveParticle(id, particle);
    Vec3 now;
    if (!impl_->core_->pinTarget(id, p, &now))
        throw InvalidInput("particle", "particle " + std::to_string(particle) + " is not pinned to a world point");
    const Vec3 to = tearables::toCore(point);
    if (!to.allFinite()) throw InvalidInput("point", "must be finite");
    auto [it, fresh] = impl_->pins_.try_emplace({id, p}, Impl::PendingPin{now, to});
    it->second.to = to;  // a second move before the step keeps the first start
}

std::vector<double> BulletWorld::peakTension(StringId id) const {
    requireLive(*impl_->core_, id);
    const auto it = impl_->peaks_.find(id);
    if (it != impl_->peaks_.end()) return it->second;
    return std::vector<double>(impl_->core_->view(id).segmentCount(), 0.0);
}

void BulletWorld::clearPeakTension(StringId id) {
    requireLive(*impl_->core_, id);
    impl_->peaks_.erase(id);
}

void BulletWorld::Impl::substep(double h, int tick, int ticks) {
    try {
        core_->settings().gravity = toCore(world_->getGravity());
        step_ = h;
        tick_ = tick;
        ticks_ = ticks;
        candidates_.clear();
        startClaimedBodies(h);
        if (core_->settings().rigid_contacts) findCandidates(h);
        // Bodies in: drop those that left the world, copy the others' state. Whether a body
        // is still in the world is read from the world's list, not from the body: a body
        // removed and deleted since the last step must not be read.
        in_world_.clear();
        const btCollisionObjectArray& objects = world_->getCollisionObjectArray();
        for (int i = 0; i < objects.size(); ++i) in_world_.push_back(objects[i]);
        std::sort(in_world_.begin(), in_world_.end());
        for (auto it = proxies_.begin(); it != proxies_.end();) {
            btRigidBody* body = const_cast<btRigidBody*>(it->first);
            if (!std::binary_search(in_world_.begin(), in_world_.end(), static_cast<const btCollisionObject*>(body))) {
                core_->removeRigid(it->second);
                named_.erase(it->first);
                it = proxies_.erase(it);
                continue;
            }
            if (!core_->rigidInUse(it->second) && !isCandidate(body) && named_.count(body) == 0 &&
                !std::binary_search(claimed_.begin(), claimed_.end(), body)) {  // nothing holds, touches or claims it
                core_->removeRigid(it->second);
                it = proxies_.erase(it);
                continue;
            }
            RigidState& s = core_->rigid(it->second);
            const btTransform pose = tickPose(*body, h, tick, ticks);
            s.position = toCore(pose.getOrigin());
            s.orientation = toCore(pose.getRotation());
            s.linear_velocity = toCore(body->getLinearVelocity());
            s.angular_velocity = toCore(body->getAngularVelocity());
            const bool dynamic = !body->isStaticOrKinematicObject() && body->getInvMass() > 0;
            s.inverse_mass = dynamic ? body->getInvMass() : 0.0;
            s.inverse_inertia_local = dynamic ? Mat3(toCore(body->getInvInertiaDiagLocal()).asDiagonal()) : Mat3::Zero();
            s.awake = body->isActive();
            ++it;
        }
        drive(tick, ticks);
        turnWinches(h);
        contacts_->touched.clear();

        core_->step(h);

        writeBodies();
        contacts_->writeBodyImpulses(core_->lastBodyContacts());
        contacts_->writeJointImpulses(core_->lastBodyJoints());
        claimIslandBodies();
        recordPeaks();
        // Rays are cast between frames: the rope objects follow at a frame's last step
        // (within a frame they keep its start; a tear or cut in it is met at its end).
        if (tick == ticks) syncRopeObjects();
        total_ += core_->lastStageTimes();
        last_error_.clear();  // this step succeeded
        reportStep(h);
    } catch (const std::exception& e) {
        last_error_ = e.what();  // never throw into Bullet's step
    } catch (...) {
        last_error_ = "unknown error in tearables step";
    }
}

}  // namespace tearables
