// Google Benchmark: whole built-in scenes through the scene runner (Bullet world, plugin,
// drivers), wall time per step. The bridge (Strings Fig. 10: 8 boards, 18 ropes of 746
// segments in all, crates falling until ropes tear) is issue 9's "bridge scene".
// Run: build/tests/benchmarks/tearables_bench --benchmark_filter='Scene'
#include "tearables/scene.hpp"

#include <benchmark/benchmark.h>

#include <string>

namespace {

void runBuiltin(benchmark::State& state, const std::string& name) {
    const auto scene = tearables::scene::parseScene(*tearables::scene::builtinSceneText(name));
    tearables::scene::RunOptions options;  // no output files
    options.steps = state.range(0);
    for (auto _ : state) {
        const auto result = tearables::scene::runScene(scene, options);
        state.SetIterationTime(result.wall_seconds);
        state.counters["ms_per_step"] = 1e3 * result.wall_seconds / static_cast<double>(result.steps);
    }
}

void BM_BridgeScene(benchmark::State& state) { runBuiltin(state, "bridge"); }
void BM_SwingScene(benchmark::State& state) { runBuiltin(state, "swing"); }
BENCHMARK(BM_BridgeScene)->Arg(600)->UseManualTime()->Unit(benchmark::kMillisecond)->Iterations(1);
BENCHMARK(BM_SwingScene)->Arg(300)->UseManualTime()->Unit(benchmark::kMillisecond)->Iterations(3);

}  // namespace
