// The rope of the side-by-side benchmarks (bench_bullet.cpp against Bullet's ropes,
// bench_mujoco.cpp against MuJoCo's chain): segments of 1 cm and 1 g, held at one end, a
// tip of 10x the rope's mass, dt = 0.01 s, laid out horizontally and swinging down.
#pragma once

#include "tearables/bullet_core.hpp"

#include <btBulletDynamicsCommon.h>
#include <benchmark/benchmark.h>

#include <algorithm>

namespace tearables::bench {

constexpr double kSegmentLength = 0.01;  // m
constexpr double kSegmentMass = 0.001;   // kg
constexpr double kDt = 0.01;             // s
constexpr int kSettle = 200;             // steps before measuring
/// Steps timed on the ropes side by side with Bullet's (bench_bullet.cpp): 8 s after the
/// 2 s of settling. Bullet's soft-body rope costs least late in that window and most early
/// (at 2 position iterations ~170 us a step in steps 200-300, ~71 in steps 700-1000, where
/// it has stretched 60x), tearables' rope the same throughout; a window of 100 steps
/// judged Bullet by its dearest part.
constexpr int kTimedSteps = 800;

/// A Bullet rigid-body world with gravity, as a user would make it.
struct RigidWorld {
    btDefaultCollisionConfiguration config;
    btCollisionDispatcher dispatcher{&config};
    btDbvtBroadphase broadphase;
    btSequentialImpulseConstraintSolver solver;
    btDiscreteDynamicsWorld world{&dispatcher, &broadphase, &solver, &config};
    RigidWorld() { world.setGravity(btVector3(0, -9.81f, 0)); }
};

/// The largest stretch of any segment of string `id` now, relative to kSegmentLength (the
/// length it was made with, as "stretch" measures it: plastic growth counts).
inline double worstSegmentStretch(const World& core, StringId id) {
    const auto& x = *core.view(id).positions;
    double worst = 0.0;
    for (std::size_t j = 0; j + 1 < x.size(); ++j) worst = std::max(worst, (x[j + 1] - x[j]).norm() / kSegmentLength - 1.0);
    return worst;
}

/// The rope in tearables (the Bullet plugin) with `settings`, timed per step after kSettle
/// steps. Counters: "stretch", its length over its rest length, minus one, at the end of
/// the timed steps; "worst_segment", the largest relative stretch of any one segment over
/// the settling steps (the swing down from the horizontal, the roughest part) and over
/// kSettle more steps after the timed ones (checked after each step, untimed).
inline void timeTearablesRope(benchmark::State& state, int segments, const WorldSettings& settings = {}) {
    RigidWorld bullet;
    btDiscreteDynamicsWorld& world = bullet.world;
    BulletWorld ropes(world, settings);
    const double length = segments * kSegmentLength;
    auto desc = StringDesc::straight({0, 0, 0}, {length, 0, 0}, segments);
    desc.radius = 0.004;
    desc.density = kSegmentMass / (3.14159265358979 * desc.radius * desc.radius * kSegmentLength);
    desc.particle_masses = {{-1, 10.0 * segments * kSegmentMass}};
    desc.tearable = false;
    desc.bending = 0.0;
    const auto id = ropes.addString(desc);
    ropes.attach(id, 0, btVector3(0, 0, 0));
    double worst = 0.0;
    for (int i = 0; i < kSettle; ++i) {
        world.stepSimulation(kDt, 1, kDt);
        worst = std::max(worst, worstSegmentStretch(ropes.core(), id));
    }
    for (auto _ : state) world.stepSimulation(kDt, 1, kDt);
    const auto& x = *ropes.core().view(id).positions;
    double sum = 0.0;
    for (std::size_t i = 1; i < x.size(); ++i) sum += (x[i] - x[i - 1]).norm();
    state.counters["stretch"] = sum / length - 1.0;
    for (int i = 0; i < kSettle; ++i) {
        world.stepSimulation(kDt, 1, kDt);
        worst = std::max(worst, worstSegmentStretch(ropes.core(), id));
    }
    state.counters["worst_segment"] = worst;
}

}  // namespace tearables::bench
