// Google Benchmark: the core's full string step (prediction, direct strain limiting,
// momentum tension, material response) for a rope hanging with a tip mass 10x its own,
// at the segment counts of Strings' Table 1. Run: build/tests/benchmarks/tearables_bench
#include "tearables/world.hpp"

#include <benchmark/benchmark.h>

namespace {

void BM_HangingRopeStep(benchmark::State& state) {
    const int segments = static_cast<int>(state.range(0));
    tearables::World world;
    auto desc = tearables::StringDesc::straight({0, 0, 0}, {0.01 * segments, 0, 0}, segments);
    desc.radius = 0.005;
    desc.density = 0.001 / (3.14159265358979 * 0.005 * 0.005 * 0.01);  // 1 g per 1 cm segment
    desc.particle_masses = {{-1, 10 * 0.001 * segments}};
    const auto id = world.addString(desc);
    world.attachToPoint(id, 0, {0, 0, 0});
    for (int i = 0; i < 200; ++i) world.step(0.01);  // settle into the swing
    for (auto _ : state) {
        world.step(0.01);
        benchmark::DoNotOptimize(world.view(id).tension->data());
    }
    state.SetItemsProcessed(state.iterations() * segments);
}
BENCHMARK(BM_HangingRopeStep)->Arg(100)->Arg(150)->Arg(200)->Arg(746)->Arg(10000)->Unit(benchmark::kMicrosecond);

}  // namespace

BENCHMARK_MAIN();
