// Google Benchmark: the string-string broad phase (Strings, Sec. 6). The paper's 7-cell
// search, the exact 27-cell search and brute force on ropes (segment length 1 cm, radius
// 4 mm) laid as smooth random walks in a box at 5% volume fraction, 100-segment chains.
// Counters: pairs found, narrow-phase tests, and the time per segment (s_per_segment).
// Registered into the suite's executable (bench_string.cpp has the main).
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "collision/grid.hpp"
#include "collision/reference_grid.hpp"

namespace {

using tearables::Vec3;
using namespace tearables::detail;
using namespace tearables::reference;
using tearables::reference::SegmentGrid;

struct RopePile {
    std::vector<Vec3> x;
    std::vector<CollisionSegment> segs;
    double cell = 0.0;
};

RopePile makeRopePile(int segments) {
    const double l = 0.01, r = 0.004, fraction = 0.05;
    const double volume = segments * 3.14159265358979 * r * r * l / fraction;
    const double box = std::cbrt(volume);
    std::mt19937_64 rng(1234);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    std::normal_distribution<double> n;
    RopePile pile;
    std::uint32_t chain = 0;
    for (int done = 0; done < segments; ++chain) {
        const int len = std::min(100, segments - done);
        Vec3 p = box * Vec3(u(rng), u(rng), u(rng));
        Vec3 dir = Vec3(n(rng), n(rng), n(rng)).normalized();
        const auto first = static_cast<std::uint32_t>(pile.x.size());
        pile.x.push_back(p);
        for (int k = 0; k < len; ++k) {
            dir = (dir + 0.35 * Vec3(n(rng), n(rng), n(rng))).normalized();  // a smooth rope
            Vec3 q = p + l * dir;
            for (int c = 0; c < 3; ++c)  // reflect at the walls of the box
                if (q[c] < 0.0 || q[c] > box) {
                    dir[c] = -dir[c];
                    q = p + l * dir;
                }
            p = q;
            pile.x.push_back(p);
            pile.segs.push_back({first + static_cast<std::uint32_t>(k), first + static_cast<std::uint32_t>(k) + 1,
                                 chain, static_cast<std::uint32_t>(k), r, false});
        }
        done += len;
    }
    pile.cell = requiredCellSize(pile.x.data(), pile.x.size(), pile.segs, 0.0);
    return pile;
}

void setCounters(benchmark::State& state, std::size_t segments, std::size_t pairs, std::size_t tests,
                 std::size_t particle_pairs = 0) {
    state.counters["pairs"] = static_cast<double>(pairs);
    if (particle_pairs) state.counters["particle_pairs"] = static_cast<double>(particle_pairs);
    state.counters["narrow_tests"] = static_cast<double>(tests);
    state.counters["s_per_segment"] = benchmark::Counter(
        static_cast<double>(segments), benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
}

void runGrid(benchmark::State& state, NeighbourSearch search) {
    const RopePile pile = makeRopePile(static_cast<int>(state.range(0)));
    SegmentGrid grid;
    std::vector<SegmentPair> out;
    grid.findPairs(pile.x.data(), pile.x.size(), pile.segs, pile.cell, 0.0, search, out);  // warm up
    for (auto _ : state) {
        grid.findPairs(pile.x.data(), pile.x.size(), pile.segs, pile.cell, 0.0, search, out);
        benchmark::DoNotOptimize(out.data());
    }
    setCounters(state, pile.segs.size(), out.size(), grid.lastStats().narrow_tests, grid.lastStats().particle_pairs);
}

void BM_Grid7(benchmark::State& state) { runGrid(state, NeighbourSearch::Seven); }
void BM_Grid27(benchmark::State& state) { runGrid(state, NeighbourSearch::TwentySeven); }

void BM_GridBruteForce(benchmark::State& state) {
    const RopePile pile = makeRopePile(static_cast<int>(state.range(0)));
    std::vector<SegmentPair> out;
    for (auto _ : state) {
        out = bruteForcePairs(pile.x.data(), pile.x.size(), pile.segs, 0.0);
        benchmark::DoNotOptimize(out.data());
    }
    const std::size_t n = pile.segs.size();
    setCounters(state, n, out.size(), n * (n - 1) / 2);
}

BENCHMARK(BM_Grid7)->Arg(100)->Arg(1000)->Arg(10000)->Arg(100000)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_Grid27)->Arg(100)->Arg(1000)->Arg(10000)->Arg(100000)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_GridBruteForce)->Arg(100)->Arg(1000)->Arg(5000)->Unit(benchmark::kMicrosecond);

}  // namespace
