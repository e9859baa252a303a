// Ropes in Bullet's ray tests (BulletWorld::setRopesRayTestable): what keeping one compound
// collision object per string costs a step, and what a ray costs through Bullet's world
// against the core's O(segments) tearables::rayTest. The scene: 16 ropes of 128 segments
// (2048 capsules, 1.28 m, 4 mm) hanging side by side, swinging after being laid out at an
// angle (after 0.5 s of settling they hang nearly straight down, from 2 m to 0.74 m), with
// a crate resting on the ground beside each; dt = 0.01 s.
// Run: build/tests/benchmarks/tearables_bench --benchmark_filter=RopeObjects
#include "tearables/bullet_core.hpp"
#include "tearables/queries.hpp"

#include <btBulletDynamicsCommon.h>
#include <benchmark/benchmark.h>

#include <memory>
#include <vector>

namespace {

using namespace tearables;

constexpr int kRopes = 16;
constexpr int kSegmentsEach = 128;
constexpr double kDt = 0.01;
constexpr int kSettle = 50;

struct Scene {
    btDefaultCollisionConfiguration config;
    btCollisionDispatcher dispatcher{&config};
    btDbvtBroadphase broadphase;
    btSequentialImpulseConstraintSolver solver;
    btDiscreteDynamicsWorld world{&dispatcher, &broadphase, &solver, &config};
    btBoxShape ground_shape{btVector3(5, 0.05f, 5)};
    btBoxShape crate_shape{btVector3(0.05f, 0.05f, 0.05f)};
    std::vector<std::unique_ptr<btRigidBody>> bodies;
    std::unique_ptr<BulletWorld> ropes;

    explicit Scene(bool ray_objects) {
        world.setGravity(btVector3(0, -9.81f, 0));
        add(ground_shape, 0.0, btVector3(0, -0.05f, 0));
        ropes = std::make_unique<BulletWorld>(world);
        ropes->setRopesRayTestable(ray_objects);
        for (int r = 0; r < kRopes; ++r) {
            const double z = 0.1 * r;
            StringDesc d = StringDesc::straight({0, 2, z}, {0.9, 1.1, z}, kSegmentsEach);
            d.radius = 0.004;
            d.tearable = false;
            const StringId id = ropes->addString(d);
            ropes->attach(id, 0, btVector3(0, 2, static_cast<btScalar>(z)));
            add(crate_shape, 1.0, btVector3(0.3f, 0.05f, static_cast<btScalar>(z)));
        }
        for (int i = 0; i < kSettle; ++i) world.stepSimulation(static_cast<btScalar>(kDt), 1, static_cast<btScalar>(kDt));
    }
    ~Scene() {
        ropes.reset();
        for (auto& b : bodies) world.removeRigidBody(b.get());
    }
    void add(btCollisionShape& shape, double mass, const btVector3& at) {
        btVector3 inertia(0, 0, 0);
        if (mass > 0.0) shape.calculateLocalInertia(static_cast<btScalar>(mass), inertia);
        bodies.push_back(std::make_unique<btRigidBody>(
            btRigidBody::btRigidBodyConstructionInfo(static_cast<btScalar>(mass), nullptr, &shape, inertia)));
        bodies.back()->setWorldTransform(btTransform(btQuaternion::getIdentity(), at));
        world.addRigidBody(bodies.back().get());
    }
};

/// One step of the scene, with the ropes' objects (ray_objects:1) or without (0).
void BM_RopeObjects_Step(benchmark::State& state) {
    Scene scene(state.range(0) != 0);
    for (auto _ : state) scene.world.stepSimulation(static_cast<btScalar>(kDt), 1, static_cast<btScalar>(kDt));
    state.counters["segments"] = kRopes * kSegmentsEach;
}
BENCHMARK(BM_RopeObjects_Step)->ArgName("ray_objects")->Arg(0)->Arg(1)->Unit(benchmark::kMicrosecond)->Iterations(300);

/// 64 horizontal rays along x, 1 m long, at heights from 0.9 to 1.9 m, each at the depth of
/// one rope (z = 0.1 m * (k mod 16)): every one crosses its rope. Through Bullet's
/// world.rayTest (closest hit).
void BM_RopeObjects_BulletRays(benchmark::State& state) {
    Scene scene(true);
    int hits = 0;
    for (auto _ : state) {
        hits = 0;
        for (int k = 0; k < 64; ++k) {
            const btScalar y = 0.9f + static_cast<btScalar>(k) / 64, z = 0.1f * static_cast<btScalar>(k % kRopes);
            const btVector3 from(-0.5f, y, z), to(0.5f, y, z);
            btCollisionWorld::ClosestRayResultCallback cb(from, to);
            scene.world.rayTest(from, to, cb);
            hits += cb.hasHit();
        }
        benchmark::DoNotOptimize(hits);
    }
    state.counters["hits"] = hits;
}
BENCHMARK(BM_RopeObjects_BulletRays)->Unit(benchmark::kMicrosecond);

/// The same 64 rays through the core's tearables::rayTest (every segment of every rope).
void BM_RopeObjects_CoreRays(benchmark::State& state) {
    Scene scene(false);
    int hits = 0;
    for (auto _ : state) {
        hits = 0;
        for (int k = 0; k < 64; ++k) {
            const double y = 0.9 + k / 64.0, z = 0.1 * (k % kRopes);
            hits += tearables::rayTest(scene.ropes->core(), Vec3(-0.5, y, z), Vec3(0.5, y, z)).has_value();
        }
        benchmark::DoNotOptimize(hits);
    }
    state.counters["hits"] = hits;
}
BENCHMARK(BM_RopeObjects_CoreRays)->Unit(benchmark::kMicrosecond);

}  // namespace
