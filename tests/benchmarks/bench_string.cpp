// Google Benchmark: the core's full string step (prediction, shape matching, strain
// limiting, string-string collision, twist, momentum tension, material response) in the
// setting of Strings' Table 1 (issue 9): a rope of 1 cm segments hanging from one end
// with a tip mass 10x its own, laid out horizontally so that it swings (and folds onto
// itself near the tip), dt = 0.01 s. Per step: CPU time, and per stage (counters, in
// microseconds per step, from World::lastStageTimes):
//   update = prediction + velocities (the paper's "particle update"), csm, strain (the
//   strain limit: our exact replacement of the paper's sweeps), collision (rigid and
//   string-string), twist, tension, material.
// Plus 10 000 and 100 000 segments in total, as one long string and as many short ones
// (100 segments each, side by side, not touching), on 1 and 2 threads
// (WorldSettings::threads). And the shape matching kernel alone (BM_CsmKernel).
// And the step in which a long rope tears (BM_LongRopeTear).
// And Table 1's 746-segment rope stepped by BDF2 (BM_Table1RopeBdf2; BM_Table1RopeFirstSwing
// against backward Euler where both move it alike), and with its plastic
// flow solved in the strain limit (BM_Table1RopeYield).
// Run: build/tests/benchmarks/tearables_bench --benchmark_filter='Table1|Segments|CsmKernel|LongRopeTear'
#include "world/world_access.hpp"
#include "long_rope.hpp"
#include "string/shape_matching.hpp"
#include "tearables/world.hpp"

#include <benchmark/benchmark.h>

#include <cmath>
#include <vector>

namespace {

constexpr double kPi = 3.14159265358979;
constexpr double kSegment = 0.01;  // m
constexpr double kRadius = 0.005;  // m
constexpr double kDensity = 0.001 / (kPi * kRadius * kRadius * kSegment);  // 1 g per 1 cm segment

tearables::StringDesc rope(const tearables::Vec3& start, int segments, double tip_factor) {
    auto desc = tearables::StringDesc::straight(start, start + tearables::Vec3(kSegment * segments, 0, 0), segments);
    desc.radius = kRadius;
    desc.density = kDensity;
    if (tip_factor > 0.0) desc.particle_masses = {{-1, tip_factor * 0.001 * segments}};
    return desc;
}

/// Adds the stage times of the measured steps as counters (microseconds per step).
struct StageCounters {
    tearables::StageTimes sum;
    void add(const tearables::World& world) { sum += world.lastStageTimes(); }
    void report(benchmark::State& state) const {
        const double steps = static_cast<double>(state.iterations());
        auto us = [&](double seconds) { return benchmark::Counter(1e6 * seconds / steps); };
        state.counters["update_us"] = us(sum.predict + sum.velocities);
        state.counters["csm_us"] = us(sum.shape_matching);
        state.counters["strain_us"] = us(sum.strain_limit);
        state.counters["collision_us"] = us(sum.collision);
        state.counters["twist_us"] = us(sum.twist);
        state.counters["tension_us"] = us(sum.tension);
        state.counters["material_us"] = us(sum.material);
        state.counters["total_us"] = us(sum.total());
    }
};

/// One rope pinned at its first particle, `settle` steps (200: into the swing), then the
/// benchmark's iterations measured, one step each, with the stages' times.
void timeSwing(benchmark::State& state, const tearables::StringDesc& desc, int settle = 200) {
    tearables::World world;
    const auto id = world.addString(desc);
    world.attachToPoint(id, 0, {0, 0, 0});
    for (int i = 0; i < settle; ++i) world.step(0.01);
    StageCounters stages;
    for (auto _ : state) {
        world.step(0.01);
        stages.add(world);
        benchmark::DoNotOptimize(world.view(id).tension->data());
    }
    stages.report(state);
    state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(desc.points.size() - 1));
}

/// Strings' Table 1 sizes: 300 steps measured (a fixed count: the swing's Newton
/// iterations vary from 2 to 4 a step, so a count the library chose from the host's speed
/// measured other steps on a faster host).
void BM_Table1Rope(benchmark::State& state) { timeSwing(state, rope({0, 0, 0}, static_cast<int>(state.range(0)), 10.0)); }
BENCHMARK(BM_Table1Rope)->Arg(100)->Arg(150)->Arg(200)->Arg(746)->Iterations(300)->Unit(benchmark::kMicrosecond);

/// BM_Table1Rope's rope stepped by BDF2 (StringDesc::integrator): the cost of the
/// second-order step against backward Euler's on the same swing (steps that start with a
/// slack segment, where the tip folds, are backward Euler's).
void BM_Table1RopeBdf2(benchmark::State& state) {
    const int segments = static_cast<int>(state.range(0));
    tearables::World world;
    tearables::StringDesc desc = rope({0, 0, 0}, segments, 10.0);
    desc.integrator = tearables::StringIntegrator::BDF2;
    const auto id = world.addString(desc);
    world.attachToPoint(id, 0, {0, 0, 0});
    for (int i = 0; i < 200; ++i) world.step(0.01);
    StageCounters stages;
    int bdf2_steps = 0;
    for (auto _ : state) {
        world.step(0.01);
        stages.add(world);
        bdf2_steps += (*tearables::detail::WorldAccess::parts(world).strings)[0].inertia_gain != 1.0;
        benchmark::DoNotOptimize(world.view(id).tension->data());
    }
    stages.report(state);
    state.counters["bdf2_steps"] = benchmark::Counter(static_cast<double>(bdf2_steps) / static_cast<double>(state.iterations()));
    state.SetItemsProcessed(state.iterations() * segments);
}
BENCHMARK(BM_Table1RopeBdf2)->Arg(746)->Iterations(300)->Unit(benchmark::kMicrosecond);

/// Table 1's 746-segment rope, released level, by backward Euler (range(0) = 0) or BDF2
/// (1), timed over steps 10-30 of its fall, where both integrators move it alike (later
/// BDF2's keeps its swing and backward Euler's loses it, so the two time different
/// motions): what the integrator itself costs a step.
void BM_Table1RopeFirstSwing(benchmark::State& state) {
    tearables::StringDesc desc = rope({0, 0, 0}, 746, 10.0);
    if (state.range(0) != 0) desc.integrator = tearables::StringIntegrator::BDF2;
    timeSwing(state, desc, 10);
}
BENCHMARK(BM_Table1RopeFirstSwing)->ArgName("bdf2")->Arg(0)->Arg(1)->Iterations(20)->Unit(benchmark::kMicrosecond);

/// BM_Table1Rope's rope with its plastic flow solved in the strain limit
/// (StringDesc::yield_in_solve = range(1)): the option's cost. range(2) = 0: the default
/// nylon, which this swing never takes past yield (the cost of the check alone); 1: a
/// material that yields at 0.5 MPa (39 N on the 5 mm radius, below the tip's weight), not
/// tearable, so that every segment flows on the plastic branch during the timed steps.
void BM_Table1RopeYield(benchmark::State& state) {
    tearables::StringDesc desc = rope({0, 0, 0}, static_cast<int>(state.range(0)), 10.0);
    desc.yield_in_solve = state.range(1) != 0;
    if (state.range(2) != 0) {
        desc.material.tensile.yield = 5e5;
        desc.material.tensile.rupture = 1e9;
        desc.tearable = false;
    }
    timeSwing(state, desc);
}
BENCHMARK(BM_Table1RopeYield)
    ->ArgNames({"segments", "in_solve", "soft"})
    ->Args({746, 0, 0})
    ->Args({746, 1, 0})
    ->Args({746, 0, 1})
    ->Args({746, 1, 1})
    ->Iterations(300)
    ->Unit(benchmark::kMicrosecond);

/// The chain shape matching kernel alone on one piece of 747 particles (BM_Table1Rope/746's
/// rope, w = 2) bent into a swinging curve: range(0) = 0, a straight rest shape (every region
/// rank 1, the rope's case) through the straight kernel, as the stage does; 1, a curved one
/// (every region of full rank, a coiled cord's); 2, the straight one through the general
/// kernel (what the stage did before the straight kernel).
void BM_CsmKernel(benchmark::State& state) {
    const int n = 747;
    std::vector<tearables::Vec3> x(n), rest(n), goal(n);
    std::vector<double> mass(n, 0.001);
    mass.back() = 7.46;
    for (int i = 0; i < n; ++i) {
        const double t = 0.01 * i;
        rest[i] = state.range(0) != 1 ? tearables::Vec3(t, 0, 0)
                                      : tearables::Vec3(t, 0.05 * std::sin(0.1 * i), 0.02 * std::cos(0.07 * i));
        x[i] = tearables::Vec3(0.5 * std::sin(t), -t * std::cos(t), 0.01 * std::sin(3 * t));
    }
    tearables::detail::CsmScratch scratch;
    for (auto _ : state) {
        if (state.range(0) == 0)
            tearables::detail::straightChainShapeMatchingGoals(x.data(), rest.data(), mass.data(), 0, n - 1, 2,
                                                               tearables::Vec3::UnitX(), goal.data(), scratch);
        else
            tearables::detail::chainShapeMatchingGoals(x.data(), rest.data(), mass.data(), 0, n - 1, 2, goal.data(), scratch);
        benchmark::DoNotOptimize(goal.data());
        benchmark::ClobberMemory();
    }
    state.SetItemsProcessed(state.iterations() * n);
}
BENCHMARK(BM_CsmKernel)->ArgName("rest")->Arg(0)->Arg(1)->Arg(2)->Unit(benchmark::kMicrosecond);

/// Many segments in total: range(0) segments, as one string (range(1) = 0) or as strings
/// of range(1) segments side by side 5 cm apart, each pinned at its first particle with a
/// 10x tip mass; range(2) threads. 30 steps of settling, then 10 measured: a fixed window,
/// past the first 25 steps, where the long rope's solve takes 4-6 Newton iterations a step
/// and 2 after (with 20 steps of settling and a count chosen from the host's speed, a slow
/// host measured those first steps).
void BM_Segments(benchmark::State& state) {
    const int total = static_cast<int>(state.range(0));
    const int per_string = state.range(1) > 0 ? static_cast<int>(state.range(1)) : total;
    tearables::WorldSettings settings;
    settings.threads = static_cast<int>(state.range(2));
    tearables::World world(settings);
    std::vector<tearables::StringId> ids;
    for (int i = 0; i * per_string < total; ++i) {
        const tearables::Vec3 start(0, 0, 0.05 * i);
        ids.push_back(world.addString(rope(start, per_string, 10.0)));
        world.attachToPoint(ids.back(), 0, start);
    }
    for (int i = 0; i < 30; ++i) world.step(0.01);
    StageCounters stages;
    for (auto _ : state) {
        world.step(0.01);
        stages.add(world);
        benchmark::DoNotOptimize(world.view(ids.back()).tension->data());
    }
    stages.report(state);
    state.SetItemsProcessed(state.iterations() * total);
    state.counters["per_segment"] =
        benchmark::Counter(static_cast<double>(total), benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
}
BENCHMARK(BM_Segments)
    ->ArgNames({"segments", "per_string", "threads"})
    ->Args({10000, 0, 1})
    ->Args({10000, 100, 1})
    ->Args({100000, 0, 1})
    ->Args({100000, 0, 2})
    ->Args({100000, 100, 1})
    ->Args({100000, 100, 2})
    ->Iterations(10)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

}  // namespace

BENCHMARK_MAIN();

/// The step in which a long rope tears: tests/long_rope.hpp's 5000 segments, pulled at
/// particle 2600 by range(0) newtons
/// for one step after three of settling: 5 kN is about its rupture load, 50 kN ten times
/// it. The recoiling arms fold onto each other within the step, and the string collision's
/// joint solve takes every pair the swept search keeps (~1e5 at 5 kN, ~8e5 at 50 kN) into
/// one cluster: the case that took 0.4 s and 28 s before the joint solve's sparse step and
/// gap bounds (README, known limits). Real time of that one step, a fresh world each time.
void BM_LongRopeTear(benchmark::State& state) {
    const double force = static_cast<double>(state.range(0));
    std::size_t pairs = 0;
    for (auto _ : state) {
        state.PauseTiming();
        tearables::WorldSettings settings;
        settings.threads = 1;
        tearables::World world(settings);
        const auto id = tearables::testing::addLongRope(world);
        for (int i = 0; i < 3; ++i) world.step(0.01);
        world.applyForce(id, 2600, {0.0, force, 0.0});
        state.ResumeTiming();
        world.step(0.01);
        state.PauseTiming();
        pairs = tearables::detail::WorldAccess::lastStringSearchPairs(world).size();
        std::size_t broken = 0;
        for (const auto b : *world.view(id).broken) broken += b;
        if (broken == 0) state.SkipWithError("the rope did not tear");
        state.ResumeTiming();
    }
    state.counters["candidate_pairs"] = static_cast<double>(pairs);
}
BENCHMARK(BM_LongRopeTear)->ArgName("newtons")->Arg(5000)->Arg(50000)->Iterations(2)->Unit(benchmark::kMillisecond)->UseRealTime();
