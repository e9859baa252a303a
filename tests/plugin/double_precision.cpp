// The Bullet plugin built against Bullet in double precision (bullet-float64.pc,
// BT_USE_DOUBLE_PRECISION): a 2 kg crate hanging on a rope reads m g at the top (plus the
// rope's weight), a ray across the rope through world.rayTest hits it where the core's ray
// test does and names its segment, and a force given once a frame over four sub-steps gives
// the impulse F dt.
#include <tearables/bullet_core.hpp>
#include <tearables/queries.hpp>

#include <btBulletDynamicsCommon.h>

#include <cmath>
#include <cstdio>
#include <type_traits>

static_assert(std::is_same<btScalar, double>::value, "this test is built against Bullet in double precision");

namespace {

int failures = 0;

void expectNear(const char* what, double got, double want, double tolerance) {
    const bool ok = std::abs(got - want) <= tolerance;
    std::printf("%s %s: %.9g (expected %.9g +- %.3g)\n", ok ? "ok  " : "FAIL", what, got, want, tolerance);
    if (!ok) ++failures;
}

}  // namespace

int main() {
    btDefaultCollisionConfiguration config;
    btCollisionDispatcher dispatcher(&config);
    btDbvtBroadphase broadphase;
    btSequentialImpulseConstraintSolver solver;
    btDiscreteDynamicsWorld world(&dispatcher, &broadphase, &solver, &config);
    world.setGravity(btVector3(0, -9.81, 0));

    btBoxShape box(btVector3(0.1, 0.1, 0.1));
    btVector3 inertia;
    box.calculateLocalInertia(2.0, inertia);
    btRigidBody crate(btRigidBody::btRigidBodyConstructionInfo(2.0, nullptr, &box, inertia));
    crate.setWorldTransform(btTransform(btQuaternion::getIdentity(), btVector3(0, 0.9, 0)));
    world.addRigidBody(&crate);

    tearables::BulletWorld ropes(world);
    tearables::StringDesc d = tearables::StringDesc::straight({0, 2, 0}, {0, 1, 0}, 20);
    d.material.variation = 0.0;
    const auto rope = ropes.addString(d);
    ropes.attach(rope, 0, btVector3(0, 2, 0));
    ropes.attach(rope, -1, crate, btVector3(0, 0.1, 0));
    for (int i = 0; i < 120; ++i) world.stepSimulation(1.0 / 60.0, 10, 1.0 / 240.0);
    const double rope_mass = d.density * 3.14159265358979323846 * d.radius * d.radius * 1.0;
    const double weight = (2.0 + rope_mass) * 9.81;
    expectNear("top tension, N", ropes.core().view(rope).tension->front(), weight, 0.01 * weight);

    // Bullet's ray test against the rope's object, in double: the core's exact hit.
    {
        const btVector3 from(-1, 1.52, 0.001), to(1, 1.52, 0.001);
        struct Closest : btCollisionWorld::ClosestRayResultCallback {
            using ClosestRayResultCallback::ClosestRayResultCallback;
            int child = -1;
            btScalar addSingleResult(btCollisionWorld::LocalRayResult& r, bool world_normal) override {
                child = r.m_localShapeInfo ? r.m_localShapeInfo->m_triangleIndex : -1;
                return ClosestRayResultCallback::addSingleResult(r, world_normal);
            }
        } cb(from, to);
        world.rayTest(from, to, cb);
        const auto exact = tearables::rayTest(ropes.core(), tearables::toCore(from), tearables::toCore(to));
        const auto named = ropes.ropeHit(cb.m_collisionObject, cb.child);
        expectNear("ray hits the rope", cb.hasHit() && cb.m_collisionObject == ropes.rayObject(rope) && exact, 1, 0);
        if (exact) {
            expectNear("ray hit point to the core's, m", (tearables::toCore(cb.m_hitPointWorld) - exact->point).norm(), 0, 1e-12);
            expectNear("ray hit segment", named ? named->segment : -1, exact->segment, 0);
        }
    }

    // A free rope in zero gravity: one frame's force over four sub-steps, momentum F dt.
    btDefaultCollisionConfiguration config2;
    btCollisionDispatcher dispatcher2(&config2);
    btDbvtBroadphase broadphase2;
    btSequentialImpulseConstraintSolver solver2;
    btDiscreteDynamicsWorld space(&dispatcher2, &broadphase2, &solver2, &config2);
    space.setGravity(btVector3(0, 0, 0));
    {
        tearables::BulletWorld free(space);
        const auto r = free.addString(d);
        free.applyForce(r, -1, btVector3(0, 0, 2.0));
        const int n = space.stepSimulation(1.0 / 64.0, 10, 1.0 / 256.0);
        const auto v = free.core().view(r);
        double p = 0.0;
        for (std::size_t i = 0; i < v.particleCount(); ++i) p += (*v.masses)[i] * (*v.velocities)[i].z();
        expectNear("sub-steps", n, 4, 0);
        expectNear("momentum, N s", p, 2.0 / 64.0, 1e-6 * 2.0 / 64.0);
    }
    world.removeRigidBody(&crate);
    return failures == 0 ? 0 : 1;
}
