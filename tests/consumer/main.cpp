// A Bullet user's program: a rope holding a crate, through the installed package. It fills
// a descriptor itself, so it includes the descriptor's header beside the plugin's.
#include <tearables/bullet.hpp>
#include <tearables/string.hpp>

#include <btBulletDynamicsCommon.h>

#include <cmath>
#include <cstdio>

int main() {
    btDefaultCollisionConfiguration config;
    btCollisionDispatcher dispatcher(&config);
    btDbvtBroadphase broadphase;
    btSequentialImpulseConstraintSolver solver;
    btDiscreteDynamicsWorld world(&dispatcher, &broadphase, &solver, &config);
    world.setGravity(btVector3(0, -9.81f, 0));

    btBoxShape box(btVector3(0.1f, 0.1f, 0.1f));
    btVector3 inertia;
    box.calculateLocalInertia(2.0f, inertia);
    btRigidBody crate(btRigidBody::btRigidBodyConstructionInfo(2.0f, nullptr, &box, inertia));
    crate.setWorldTransform(btTransform(btQuaternion::getIdentity(), btVector3(0, 0.9f, 0)));
    world.addRigidBody(&crate);

    tearables::BulletWorld ropes(world);
    auto rope = ropes.addString(tearables::StringDesc::straight({0, 2, 0}, {0, 1, 0}, 20));
    ropes.attach(rope, 0, btVector3(0, 2, 0));
    ropes.attach(rope, -1, crate, btVector3(0, 0.1f, 0));
    for (int i = 0; i < 120; ++i) world.stepSimulation(1.0f / 60.0f, 1, 1.0f / 60.0f);

    const double top = ropes.tensions(rope).front();
    std::printf("top tension %.3f N (crate weight %.3f N)\n", top, 2.0 * 9.81);
    world.removeRigidBody(&crate);
    return std::abs(top - 2.0 * 9.81) < 0.1 * 2.0 * 9.81 ? 0 : 1;
}
