// A Bullet world as a user would make it, for the plugin tests.
#pragma once

#include "tearables/string.hpp"

#include <btBulletDynamicsCommon.h>

#include <memory>
#include <string>
#include <vector>

namespace tearables::testing {

/// Owns a btDiscreteDynamicsWorld and the bodies the test adds; removes them before it
/// dies (the world itself may be destroyed early: `world.reset()`).
struct Physics {
    btDefaultCollisionConfiguration config;
    btCollisionDispatcher dispatcher{&config};
    btDbvtBroadphase broadphase;
    btSequentialImpulseConstraintSolver solver;
    std::unique_ptr<btDiscreteDynamicsWorld> world =
        std::make_unique<btDiscreteDynamicsWorld>(&dispatcher, &broadphase, &solver, &config);
    std::vector<std::unique_ptr<btCollisionShape>> shapes;
    std::vector<std::unique_ptr<btRigidBody>> bodies;

    explicit Physics(double gravity = -9.81) { world->setGravity(btVector3(0, static_cast<btScalar>(gravity), 0)); }
    ~Physics() {
        if (world)
            for (auto& b : bodies) world->removeRigidBody(b.get());
    }
    /// A body of `shape` and `mass` (0 = static) at `at`, added to the world.
    btRigidBody& add(std::unique_ptr<btCollisionShape> shape, double mass, const btVector3& at) {
        shapes.push_back(std::move(shape));
        btVector3 inertia(0, 0, 0);
        if (mass > 0.0) shapes.back()->calculateLocalInertia(static_cast<btScalar>(mass), inertia);
        bodies.push_back(std::make_unique<btRigidBody>(
            btRigidBody::btRigidBodyConstructionInfo(static_cast<btScalar>(mass), nullptr, shapes.back().get(), inertia)));
        bodies.back()->setWorldTransform(btTransform(btQuaternion::getIdentity(), at));
        world->addRigidBody(bodies.back().get());
        return *bodies.back();
    }
    btRigidBody& box(const btVector3& half, double mass, const btVector3& at) {
        return add(std::make_unique<btBoxShape>(half), mass, at);
    }
    btRigidBody& sphere(double r, double mass, const btVector3& at) {
        return add(std::make_unique<btSphereShape>(static_cast<btScalar>(r)), mass, at);
    }
    /// n internal steps of dt.
    void step(int n, double dt = 0.01) {
        for (int i = 0; i < n; ++i) world->stepSimulation(static_cast<btScalar>(dt), 1, static_cast<btScalar>(dt));
    }
};

/// A straight rope for tests about holding and coupling: no material scatter, untearable,
/// no bending.
inline StringDesc plainRope(const Vec3& from, const Vec3& to, int segments) {
    StringDesc d = StringDesc::straight(from, to, segments);
    d.material.variation = 0.0;
    d.tearable = false;
    d.bending = 0.0;
    return d;
}

/// Kinetic energy of a body (translation and rotation), J.
inline double kineticEnergy(const btRigidBody& body) {
    const double mass = body.getInvMass() > 0 ? 1.0 / static_cast<double>(body.getInvMass()) : 0.0;
    double e = 0.5 * mass * static_cast<double>(body.getLinearVelocity().length2());
    const btVector3 w = body.getWorldTransform().getBasis().transpose() * body.getAngularVelocity();
    const btVector3 inv = body.getInvInertiaDiagLocal();
    for (int k = 0; k < 3; ++k)
        if (inv[k] > 0) e += 0.5 * static_cast<double>(w[k] * w[k] / inv[k]);
    return e;
}

/// Bullet's state of a body that a user restores along with the snapshot.
struct BodyState {
    btTransform xf, interpolation;
    btVector3 v, w, interpolation_v, interpolation_w;
    int activation;
    btScalar deactivation;
    explicit BodyState(const btRigidBody& b)
        : xf(b.getWorldTransform()), interpolation(b.getInterpolationWorldTransform()), v(b.getLinearVelocity()),
          w(b.getAngularVelocity()), interpolation_v(b.getInterpolationLinearVelocity()),
          interpolation_w(b.getInterpolationAngularVelocity()), activation(b.getActivationState()),
          deactivation(b.getDeactivationTime()) {}
    void applyTo(btRigidBody& b) const {
        b.setWorldTransform(xf);
        b.setCenterOfMassTransform(xf);
        b.setInterpolationWorldTransform(interpolation);
        b.setLinearVelocity(v);
        b.setAngularVelocity(w);
        b.setInterpolationLinearVelocity(interpolation_v);
        b.setInterpolationAngularVelocity(interpolation_w);
        b.forceActivationState(activation);
        b.setDeactivationTime(deactivation);
    }
};

/// Appends the bits of a body's pose and velocities to `out` (bit-identity checks).
inline void appendBodyBits(std::string& out, const btRigidBody& b) {
    const btTransform& xf = b.getWorldTransform();
    auto add = [&](const btVector3& v) { out.append(reinterpret_cast<const char*>(&v), sizeof v); };
    add(xf.getOrigin());
    add(xf.getBasis().getRow(0));
    add(xf.getBasis().getRow(1));
    add(xf.getBasis().getRow(2));
    add(b.getLinearVelocity());
    add(b.getAngularVelocity());
}

}  // namespace tearables::testing
