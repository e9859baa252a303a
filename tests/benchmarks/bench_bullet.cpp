// Tearables against Bullet's own ropes, in the same run (issue 9): the same rope, 746
// segments of 1 cm and 1 g, hanging from a fixed point with a tip mass 10x the rope's,
// dt = 0.01 s. Reported per step, over the kTimedSteps (8 s) after 2 s of settling: time,
// and the elongation the rope has reached at their end (counter "stretch", relative).
// Bullet's ropes:
//  - btSoftBody rope (btSoftBodyHelpers::CreateRope) at 1 (Bullet's default) to 6, 8 and 64
//    position iterations. The cost of its step is not monotonic in them (1 iteration is
//    the dearest of the first six), so the sweep is what finds Bullet's cheapest setting;
//  - a chain of rigid capsules joined by btPoint2PointConstraint at 10 and 50 solver
//    iterations, timed over 20 steps only (1.4-2.8 ms a step: 10x the others).
// tearables: at its defaults (BM_Rope746_Tearables) and at the loosest tolerance, which
// holds the same 1% (BM_Rope746_TearablesAt1Percent).
// Run: build/tests/benchmarks/tearables_bench --benchmark_filter=Rope746
#include "bench_rope.hpp"
#include "tearables/bullet_core.hpp"

#include <BulletSoftBody/btSoftBodyHelpers.h>
#include <BulletSoftBody/btSoftRigidDynamicsWorld.h>
#include <BulletSoftBody/btSoftBodyRigidBodyCollisionConfiguration.h>
#include <btBulletDynamicsCommon.h>
#include <benchmark/benchmark.h>

#include <memory>
#include <vector>

namespace {

using namespace tearables::bench;

constexpr int kSegments = 746;
constexpr double kTip = 10.0 * kSegments * kSegmentMass;
constexpr double kLength = kSegments * kSegmentLength;

double ropeLength(const std::vector<btVector3>& x) {
    double sum = 0.0;
    for (std::size_t i = 1; i < x.size(); ++i) sum += (x[i] - x[i - 1]).length();
    return sum;
}

void BM_Rope746_Tearables(benchmark::State& state) { timeTearablesRope(state, kSegments); }
BENCHMARK(BM_Rope746_Tearables)->Unit(benchmark::kMicrosecond)->Iterations(kTimedSteps);

/// tearables at the 1% too, as Bullet's ropes are measured at the iterations they
/// need for it: the loosest strain tolerance the setting allows (1e-2, a solve stops once
/// its moves are within 1% of a segment's length; the rope then stretches by its
/// material's elasticity, ~0.16% at worst, as at the default 1e-6), with its self-collision
/// (default) and without it (self_collision:0: what Bullet's ropes here have, btSoftBody's
/// default collisions being rigid against soft only and the capsule chain's links not
/// colliding with each other).
void BM_Rope746_TearablesAt1Percent(benchmark::State& state) {
    tearables::WorldSettings settings;
    settings.strain_tolerance = 1e-2;
    settings.string_collisions = state.range(0) != 0;
    timeTearablesRope(state, kSegments, settings);
}
BENCHMARK(BM_Rope746_TearablesAt1Percent)->ArgName("self_collision")->Arg(1)->Arg(0)->Unit(benchmark::kMicrosecond)->Iterations(kTimedSteps);

void BM_Rope746_BulletSoftBody(benchmark::State& state) {
    btSoftBodyRigidBodyCollisionConfiguration config;
    btCollisionDispatcher dispatcher(&config);
    btDbvtBroadphase broadphase;
    btSequentialImpulseConstraintSolver solver;
    btSoftRigidDynamicsWorld world(&dispatcher, &broadphase, &solver, &config);
    world.setGravity(btVector3(0, -9.81f, 0));
    btSoftBodyWorldInfo& info = world.getWorldInfo();
    info.m_gravity = world.getGravity();
    info.m_broadphase = &broadphase;
    info.m_dispatcher = &dispatcher;
    info.m_sparsesdf.Initialize();
    btSoftBody* rope = btSoftBodyHelpers::CreateRope(info, btVector3(0, 0, 0), btVector3(static_cast<btScalar>(kLength), 0, 0),
                                                    kSegments - 1, 1);  // res = interior nodes; fix the first
    rope->m_cfg.piterations = static_cast<int>(state.range(0));
    rope->m_materials[0]->m_kLST = 1.0f;
    for (int i = 0; i < rope->m_nodes.size(); ++i) rope->setMass(i, i == 0 ? 0.0f : static_cast<btScalar>(kSegmentMass));
    rope->setMass(rope->m_nodes.size() - 1, static_cast<btScalar>(kTip));
    world.addSoftBody(rope);
    for (int i = 0; i < kSettle; ++i) world.stepSimulation(kDt, 1, kDt);
    for (auto _ : state) world.stepSimulation(kDt, 1, kDt);
    std::vector<btVector3> x;
    for (int i = 0; i < rope->m_nodes.size(); ++i) x.push_back(rope->m_nodes[i].m_x);
    state.counters["stretch"] = ropeLength(x) / kLength - 1.0;
    world.removeSoftBody(rope);
    delete rope;
}
BENCHMARK(BM_Rope746_BulletSoftBody)->DenseRange(1, 6)->Arg(8)->Arg(64)->Unit(benchmark::kMicrosecond)->Iterations(kTimedSteps);

void BM_Rope746_BulletCapsuleChain(benchmark::State& state) {
    RigidWorld bullet;
    btDiscreteDynamicsWorld& world = bullet.world;
    world.getSolverInfo().m_numIterations = static_cast<int>(state.range(0));
    btCapsuleShapeX capsule(0.004f, static_cast<btScalar>(kSegmentLength - 0.008));
    btSphereShape tip_shape(0.05f);
    std::vector<std::unique_ptr<btRigidBody>> links;
    std::vector<std::unique_ptr<btPoint2PointConstraint>> joints;
    for (int i = 0; i < kSegments; ++i) {
        const bool last = i == kSegments - 1;
        const btScalar mass = static_cast<btScalar>(last ? kTip + kSegmentMass : kSegmentMass);
        btCollisionShape* shape = last ? static_cast<btCollisionShape*>(&tip_shape) : &capsule;
        btVector3 inertia;
        shape->calculateLocalInertia(mass, inertia);
        auto body = std::make_unique<btRigidBody>(btRigidBody::btRigidBodyConstructionInfo(mass, nullptr, shape, inertia));
        body->setWorldTransform(btTransform(btQuaternion::getIdentity(), btVector3(static_cast<btScalar>((i + 0.5) * kSegmentLength), 0, 0)));
        body->setActivationState(DISABLE_DEACTIVATION);
        world.addRigidBody(body.get(), 1, 0);  // no collisions between links
        const btVector3 half(static_cast<btScalar>(0.5 * kSegmentLength), 0, 0);
        if (i == 0) {
            joints.push_back(std::make_unique<btPoint2PointConstraint>(*body, -half));
        } else {
            joints.push_back(std::make_unique<btPoint2PointConstraint>(*links.back(), *body, half, -half));
        }
        world.addConstraint(joints.back().get(), true);
        links.push_back(std::move(body));
    }
    for (int i = 0; i < kSettle; ++i) world.stepSimulation(kDt, 1, kDt);
    for (auto _ : state) world.stepSimulation(kDt, 1, kDt);
    // Length along the joints: from the anchor through every link's two ends.
    std::vector<btVector3> x{btVector3(0, 0, 0)};
    for (const auto& link : links) x.push_back(link->getWorldTransform() * btVector3(static_cast<btScalar>(0.5 * kSegmentLength), 0, 0));
    state.counters["stretch"] = ropeLength(x) / kLength - 1.0;
    for (auto& j : joints) world.removeConstraint(j.get());
    for (auto& l : links) world.removeRigidBody(l.get());
}
BENCHMARK(BM_Rope746_BulletCapsuleChain)->Arg(10)->Arg(50)->Unit(benchmark::kMicrosecond)->Iterations(20);

}  // namespace
