// Google Benchmark: one step of a paper sheet (Paper Sec. III.A implicit Euler with 8
// Jacobi iterations, creasing checks, no rigid bodies): a sheet held at two corners, hanging
// and swinging, at 32x32, 64x64 and 128x128 vertices (h = 1/60 s), with and without
// breakable springs (creases form while it swings), and with Yarn's momentum-balance
// tension (a sparse least squares per step). The breakable sheet is timed over a fixed
// window, steps 31-130, in one run: it gains vertices and springs as it creases, so a
// step's cost depends on when it is taken, and the library's own choice of count ran it
// several times, whose first runs left the heap grown for the measured one (which then
// never met a growing allocation, as an application's one sheet does).
// BM_PaperStepSolver/n/d: the hanging sheet's solve by the sweeps (d = 0) or by
// conjugate gradients to a relative residual of 10^-d, with its iterations a step;
// BM_PaperStepMultigrid/n/d: the same with the multigrid preconditioner.
// Run: build/tests/benchmarks/tearables_bench --benchmark_filter=Paper
#include "world/world_access.hpp"
#include "tearables/world.hpp"

#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>

namespace {

void paperStep(benchmark::State& state, bool breakable, tearables::PaperTension tension = tearables::PaperTension::Stretch,
               tearables::PaperSolver solver = tearables::PaperDesc{}.solver, double tolerance = tearables::PaperDesc{}.tolerance) {
    const int n = static_cast<int>(state.range(0));
    tearables::World world;
    tearables::PaperDesc d;
    d.size[0] = 0.3;
    d.size[1] = 0.3;
    d.resolution[0] = n;
    d.resolution[1] = n;
    d.breakable = breakable;
    d.tension = tension;
    d.solver = solver;
    d.tolerance = tolerance;
    d.attachments.push_back(tearables::PaperAttachment{0, {}, tearables::Vec3::Zero(), {}});
    d.attachments.push_back(tearables::PaperAttachment{static_cast<int>(n - 1), {}, tearables::Vec3::Zero(), {}});
    const auto id = world.addPaper(d);
    for (int i = 0; i < 30; ++i) world.step(1.0 / 60.0);  // falling and swinging
    const auto parts = tearables::detail::WorldAccess::parts(world);
    double cg_iterations = 0.0, worst_residual = 0.0, solve_iterations = 0.0, worst_solve = 0.0;
    for (auto _ : state) {
        world.step(1.0 / 60.0);
        benchmark::DoNotOptimize(world.viewPaper(id).positions->data());
        const tearables::detail::PaperSheet& sheet = (*parts.papers)[id.index];
        cg_iterations += sheet.tension_scratch.iterations;
        worst_residual = std::max(worst_residual, sheet.tension_scratch.residual_norm);
        solve_iterations += sheet.cg_iterations;
        worst_solve = std::max(worst_solve, sheet.cg_residual);
    }
    state.SetItemsProcessed(state.iterations() * n * n);
    // The momentum tension's conjugate gradient iterations a step (0 without it).
    state.counters["tension_cg_iterations"] = cg_iterations / static_cast<double>(state.iterations());
    state.counters["tension_residual"] = worst_residual;  // the largest relative residual at the solve's end
    // The velocity solve's conjugate gradient iterations a step and its largest relative
    // residual (0 with the Paper solver's Jacobi sweeps).
    state.counters["solve_iterations"] = solve_iterations / static_cast<double>(state.iterations());
    state.counters["solve_residual"] = worst_solve;
    state.counters["vertices"] = static_cast<double>(world.viewPaper(id).vertexCount());
}

void BM_PaperStep(benchmark::State& state) { paperStep(state, false); }
void BM_PaperStepBreakable(benchmark::State& state) { paperStep(state, true); }
void BM_PaperStepMomentumTension(benchmark::State& state) { paperStep(state, false, tearables::PaperTension::Momentum); }
/// The velocity solve's two methods: Jacobi sweeps (range(1) = 0) and conjugate
/// gradients to a relative residual of 10^-range(1).
void BM_PaperStepSolver(benchmark::State& state) {
    const auto digits = static_cast<int>(state.range(1));
    paperStep(state, false, tearables::PaperTension::Stretch,
              digits == 0 ? tearables::PaperSolver::Paper : tearables::PaperSolver::ConjugateGradient,
              digits == 0 ? tearables::PaperDesc{}.tolerance : std::pow(10.0, -digits));
}
BENCHMARK(BM_PaperStepSolver)->ArgsProduct({{32, 64}, {0, 2, 3, 4, 6}})->Unit(benchmark::kMillisecond);
/// The same conjugate gradients preconditioned by the smoothed aggregation multigrid
/// (PaperSolver::Multigrid) to a relative residual of 10^-range(1).
void BM_PaperStepMultigrid(benchmark::State& state) {
    paperStep(state, false, tearables::PaperTension::Stretch, tearables::PaperSolver::Multigrid, std::pow(10.0, -static_cast<int>(state.range(1))));
}
BENCHMARK(BM_PaperStepMultigrid)->ArgsProduct({{32, 64}, {2, 4, 6, 7}})->Unit(benchmark::kMillisecond);
BENCHMARK(BM_PaperStepMomentumTension)->Arg(32)->Arg(64)->Arg(128)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_PaperStep)->Arg(32)->Arg(64)->Arg(128)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_PaperStepBreakable)->Arg(32)->Arg(64)->Arg(128)->Iterations(100)->Unit(benchmark::kMillisecond);

}  // namespace
