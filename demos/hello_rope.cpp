// Hello rope: Bullet's HelloWorld with a rope. A static ground, a 5 kg crate hanging on a
// metre of nylon rope pinned at the top, two seconds of stepSimulation; it prints the crate's
// height and the rope's tension as it goes, then checks that the top of the rope holds the
// crate's weight plus the rope's own (to 1%), as a rope at rest does.
//
// Only tearables/bullet.hpp is needed: no Eigen, no descriptor. Build it as any Bullet
// program, linking tearables::bullet (CMake: find_package(tearables), then
// target_link_libraries(app PRIVATE tearables::tearables)).
#include <tearables/bullet.hpp>

#include <btBulletDynamicsCommon.h>

#include <cmath>
#include <cstdio>

int main() {
    // The Bullet world, as in Bullet's HelloWorld.
    btDefaultCollisionConfiguration config;
    btCollisionDispatcher dispatcher(&config);
    btDbvtBroadphase broadphase;
    btSequentialImpulseConstraintSolver solver;
    btDiscreteDynamicsWorld world(&dispatcher, &broadphase, &solver, &config);
    const btScalar g = btScalar(9.81);
    world.setGravity(btVector3(0, -g, 0));

    // The ground: a static box whose top face is y = 0.
    btBoxShape ground_shape(btVector3(50, 50, 50));
    btRigidBody ground(btRigidBody::btRigidBodyConstructionInfo(0, nullptr, &ground_shape));
    ground.setWorldTransform(btTransform(btQuaternion::getIdentity(), btVector3(0, -50, 0)));
    world.addRigidBody(&ground);

    // The crate: 5 kg, 0.4 m on a side, its top face where the rope will end (y = 2).
    const btScalar crate_mass = 5;
    btBoxShape crate_shape(btVector3(0.2f, 0.2f, 0.2f));
    btVector3 inertia(0, 0, 0);
    crate_shape.calculateLocalInertia(crate_mass, inertia);
    btRigidBody crate(btRigidBody::btRigidBodyConstructionInfo(crate_mass, nullptr, &crate_shape, inertia));
    crate.setWorldTransform(btTransform(btQuaternion::getIdentity(), btVector3(0, 1.8f, 0)));
    world.addRigidBody(&crate);

    // The rope: 1 m of laid nylon rope (the "nylon_rope" preset, 12 mm) in 40 segments from
    // the hook at y = 3 to the crate's top face, pinned at the hook and glued to the crate.
    tearables::BulletWorld ropes(world);
    const btVector3 hook(0, 3, 0), crate_top(0, 2, 0);
    const tearables::StringId rope = ropes.addRope(hook, crate_top, 1.0, 40, "nylon_rope");
    ropes.attach(rope, 0, hook);
    ropes.attach(rope, -1, crate, btVector3(0, 0.2f, 0));  // in the crate's frame

    // Two seconds at 60 frames a second, each frame four internal steps of 1/240 s.
    for (int frame = 1; frame <= 120; ++frame) {
        world.stepSimulation(btScalar(1.0 / 60.0), 4, btScalar(1.0 / 240.0));
        if (!ropes.lastError().empty()) {
            std::printf("tearables: %s\n", ropes.lastError().c_str());
            return 1;
        }
        if (frame % 30 == 0)
            std::printf("t = %.2f s: crate at y = %.4f m, rope tension at the top %.3f N\n", frame / 60.0,
                        static_cast<double>(crate.getCenterOfMassPosition().y()), ropes.tensions(rope).front());
    }

    // At rest the top segment holds everything below it: the crate and the rope.
    const double top = ropes.tensions(rope).front();
    const double weight = (static_cast<double>(crate_mass) + ropes.mass(rope)) * static_cast<double>(g);
    std::printf("rope: %.4f m long, %.4f kg\n", ropes.length(rope), ropes.mass(rope));
    std::printf("top tension %.3f N, crate and rope weigh %.3f N: ratio %.4f\n", top, weight, top / weight);

    world.removeRigidBody(&crate);
    world.removeRigidBody(&ground);
    return std::abs(top / weight - 1.0) <= 0.01 ? 0 : 1;
}
