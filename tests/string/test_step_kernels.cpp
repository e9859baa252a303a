// Issue 9: the faster kernels give what the ones they replace gave: ChainTree (the
// string-string broad phase) against the brute-force search, also for strings side by
// side, where the chains are swept along another axis than x; the tree's whole-node
// rejection of swept pairs (World's nodesSeparationNeeded) against the pair by pair filter.
#include "base/thread_pool.hpp"
#include "collision/grid.hpp"
#include "collision/reference_grid.hpp"
#include "world/world_access.hpp"
#include "tearables/world.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <tuple>
#include <vector>

namespace {

using tearables::Vec3;
namespace detail = tearables::detail;

Vec3 randomUnit(std::mt19937_64& rng) {
    std::normal_distribution<double> g;
    return Vec3(g(rng), g(rng), g(rng)).normalized();
}

std::vector<std::tuple<std::uint32_t, std::uint32_t>> keys(const std::vector<detail::SegmentPair>& pairs) {
    std::vector<std::tuple<std::uint32_t, std::uint32_t>> out;
    for (const auto& p : pairs) out.emplace_back(p.first, p.second);
    std::sort(out.begin(), out.end());
    return out;
}

/// Appends a chain through `points` to the search's particles and segments: segment i
/// of radius radius(i), skipped where skip(i).
template <class Radius, class Skip>
void appendChain(const std::vector<Vec3>& points, std::uint32_t chain, std::vector<Vec3>& x,
                 std::vector<detail::CollisionSegment>& segs, Radius radius, Skip skip) {
    const auto base = static_cast<std::uint32_t>(x.size());
    x.insert(x.end(), points.begin(), points.end());
    for (int i = 0; i + 1 < static_cast<int>(points.size()); ++i) {
        detail::CollisionSegment s;
        s.a = base + static_cast<std::uint32_t>(i);
        s.b = s.a + 1;
        s.chain = chain;
        s.index_in_chain = static_cast<std::uint32_t>(i);
        s.radius = radius(i);
        s.skip = skip(i);
        segs.push_back(s);
    }
}

// Random-walk ropes, as a pile and side by side (strings of equal extent in x and y,
// spread along z: the sweep runs along z), with swept radii of different sizes.
TEST(StepKernels, ChainTreeFindsTheBruteForcePairs) {
    std::mt19937_64 rng(3);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    for (int layout = 0; layout < 2; ++layout) {
        std::vector<Vec3> x;
        std::vector<detail::CollisionSegment> segs;
        const int chains = 30, per_chain = 40;
        for (int c = 0; c < chains; ++c) {
            Vec3 p = layout == 0 ? Vec3(u(rng), u(rng), u(rng)) * 0.1 : Vec3(0.0, 0.0, 0.012 * c);
            std::vector<Vec3> points;
            for (int i = 0; i <= per_chain; ++i) {
                points.push_back(p);
                p += layout == 0 ? randomUnit(rng) * 0.01 : Vec3(0.01, 0.002 * u(rng), 0.002 * u(rng));
            }
            appendChain(points, static_cast<std::uint32_t>(c), x, segs, [](int i) { return 0.004 * (1.0 + (i % 7 == 0 ? 3.0 : 0.0)); },
                        [](int i) { return i % 29 == 5; });
        }
        detail::ChainTree tree;
        std::vector<detail::SegmentPair> out;
        tree.findPairs(x.data(), segs, 0.0, out, 3);
        const auto expected = tearables::reference::bruteForcePairs(x.data(), x.size(), segs, 0.0, 3);
        ASSERT_GT(expected.size(), 10u) << layout;
        EXPECT_EQ(keys(out), keys(expected)) << layout;
    }
}

// Two worlds in lockstep, one with the tree's node-level rejection (the default), one
// without (every swept pair then goes to surelyDropped / judgePair one by one) and without
// the proof that a straight string has no self pairs: every step the search keeps the same
// pairs (the same segments, closest points and normals, in the same order) and the strings
// end in the same state, bit for bit. Returns the node pairs the pruning dropped over all
// steps (so that a test can check it was exercised); with `straight_skip`, the pruned world
// also skips the self search of the strings it proves straight enough, and `self_free`
// counts them over the steps. The pruned world runs on `threads` (its search's chains and
// chain pairs on the pool), the other on one.
std::size_t expectSamePairsWithNodePruning(const std::vector<tearables::StringDesc>& descs,
                                           const std::vector<std::vector<std::pair<int, Vec3>>>& pins, int steps,
                                           std::size_t* kept_pairs, int threads = 1, bool straight_skip = false,
                                           std::size_t* self_free = nullptr) {
    tearables::WorldSettings settings;
    settings.threads = threads;
    tearables::World pruned(settings), plain;
    detail::WorldAccess::setStringNodePruning(plain, false);
    detail::WorldAccess::setStraightStringsSkip(plain, false);
    detail::WorldAccess::setStraightStringsSkip(pruned, straight_skip);
    std::vector<tearables::StringId> ids;
    for (std::size_t k = 0; k < descs.size(); ++k) {
        ids.push_back(pruned.addString(descs[k]));
        plain.addString(descs[k]);
        for (const auto& pin : pins[k]) {
            pruned.attachToPoint(ids.back(), pin.first, pin.second);
            plain.attachToPoint(ids.back(), pin.first, pin.second);
        }
    }
    std::size_t rejects = 0;
    for (int step = 0; step < steps; ++step) {
        pruned.step(0.01);
        plain.step(0.01);
        EXPECT_EQ(detail::WorldAccess::lastStringNodeRejects(plain), 0u);
        EXPECT_EQ(detail::WorldAccess::lastSelfFreeStrings(plain), 0u);
        rejects += detail::WorldAccess::lastStringNodeRejects(pruned);
        if (self_free) *self_free += detail::WorldAccess::lastSelfFreeStrings(pruned);
        const auto& a = detail::WorldAccess::lastStringSearchPairs(pruned);
        const auto& b = detail::WorldAccess::lastStringSearchPairs(plain);
        *kept_pairs += a.size();
        EXPECT_EQ(a.size(), b.size()) << "step " << step;
        if (a.size() != b.size()) return rejects;
        for (std::size_t i = 0; i < a.size(); ++i) {
            EXPECT_EQ(a[i].first, b[i].first) << "step " << step;
            EXPECT_EQ(a[i].second, b[i].second) << "step " << step;
            EXPECT_EQ(a[i].s, b[i].s);
            EXPECT_EQ(a[i].t, b[i].t);
            EXPECT_EQ(a[i].distance, b[i].distance);
            EXPECT_EQ(a[i].normal, b[i].normal);
        }
        for (const auto id : ids) {
            const auto& xa = *pruned.view(id).positions;
            const auto& xb = *plain.view(id).positions;
            for (std::size_t p = 0; p < xa.size(); ++p) {
                EXPECT_EQ(xa[p], xb[p]) << "step " << step << " particle " << p;
                if (xa[p] != xb[p]) return rejects;
            }
        }
    }
    return rejects;
}

tearables::StringDesc ropeDesc(const Vec3& from, const Vec3& to, int segments, double tip_factor) {
    auto d = tearables::StringDesc::straight(from, to, segments);
    d.radius = 0.005;
    d.density = 0.001 / (3.14159265358979 * d.radius * d.radius * (to - from).norm() / segments);
    if (tip_factor > 0.0) d.particle_masses = {{-1, tip_factor * 0.001 * segments}};
    return d;
}

}  // namespace

// The benchmark's rope (Strings' Table 1), shorter: 1 cm segments pinned at one end,
// laid out horizontally, 10x tip mass: it swings down, the swept capsules of its fast
// segments overlapping dozens of neighbours each; beside it a rope pinned at its middle,
// whose arms swing down and meet (contacts between them, and with each other's sweeps).
TEST(StepKernels, NodePruningKeepsEveryPairOfASwingingRope) {
    std::size_t kept = 0;
    const std::size_t rejects = expectSamePairsWithNodePruning(
        {ropeDesc(Vec3(0, 0, 0), Vec3(3.0, 0, 0), 300, 10.0), ropeDesc(Vec3(0, 0, 0.5), Vec3(1.0, 0, 0.5), 100, 3.0)},
        {{{0, Vec3(0, 0, 0)}}, {{50, Vec3(0.5, 0, 0.5)}}}, 150, &kept);
    EXPECT_GT(kept, 100u);      // the arms touched
    EXPECT_GT(rejects, 1000u);  // exercised: the swing drops node pairs every step
}

// Ropes falling onto each other: a free rope dropped across one clamped at both ends (they
// touch, press and slide off), a third one hanging from a pin and swinging through both;
// the pruned world on two threads. (Long enough for trees of several levels above their
// leaves of 16 segments: ropes of 40 and 80 segments had no node pair to drop whole.)
TEST(StepKernels, NodePruningKeepsEveryPairOfRopesFallingOnEachOther) {
    std::size_t kept = 0;
    const std::size_t rejects = expectSamePairsWithNodePruning(
        {ropeDesc(Vec3(-0.5, 0, 0), Vec3(0.5, 0, 0), 80, 0.0), ropeDesc(Vec3(0, 0.05, -0.5), Vec3(0, 0.05, 0.5), 80, 0.0),
         ropeDesc(Vec3(0.2, 0.4, 0.1), Vec3(-0.6, 0.4, 0.1), 160, 3.0)},
        {{{0, Vec3(-0.5, 0, 0)}, {-1, Vec3(0.5, 0, 0)}}, {}, {{0, Vec3(0.2, 0.4, 0.1)}}}, 250, &kept, 2);
    EXPECT_GT(kept, 100u);    // they touched
    EXPECT_GT(rejects, 100u); // and the pruning was exercised
}

// The proof that a string swinging or hanging nearly straight has no self pairs
// (selfPairFree) skips its self search and keeps every pair: the scenes above with it on,
// where it holds for some strings in some steps and not for others (the arms that meet,
// the ropes that fall onto each other and bend), and a single rope swinging down, which
// it spares the whole search. The same pairs and the same bits as the plain search.
TEST(StepKernels, StraightStringsSkipTheirSelfSearchAndKeepEveryPair) {
    std::size_t kept = 0, self_free = 0;
    expectSamePairsWithNodePruning(
        {ropeDesc(Vec3(0, 0, 0), Vec3(3.0, 0, 0), 300, 10.0), ropeDesc(Vec3(0, 0, 0.5), Vec3(1.0, 0, 0.5), 100, 3.0)},
        {{{0, Vec3(0, 0, 0)}}, {{50, Vec3(0.5, 0, 0.5)}}}, 150, &kept, 1, true, &self_free);
    EXPECT_GT(kept, 100u);           // the arms touched
    EXPECT_GE(self_free, 150u);      // the swinging rope in every step
    EXPECT_LT(self_free, 2u * 150u); // the one pinned at its middle not once its arms hang and meet
    kept = 0;
    self_free = 0;
    expectSamePairsWithNodePruning(
        {ropeDesc(Vec3(-0.5, 0, 0), Vec3(0.5, 0, 0), 80, 0.0), ropeDesc(Vec3(0, 0.05, -0.5), Vec3(0, 0.05, 0.5), 80, 0.0),
         ropeDesc(Vec3(0.2, 0.4, 0.1), Vec3(-0.6, 0.4, 0.1), 160, 3.0)},
        {{{0, Vec3(-0.5, 0, 0)}, {-1, Vec3(0.5, 0, 0)}}, {}, {{0, Vec3(0.2, 0.4, 0.1)}}}, 250, &kept, 2, true, &self_free);
    EXPECT_GT(kept, 100u);
    EXPECT_GT(self_free, 0u);
    EXPECT_LT(self_free, 3u * 250u);
    kept = 0;
    self_free = 0;
    expectSamePairsWithNodePruning({ropeDesc(Vec3(0, 0, 0), Vec3(7.46, 0, 0), 746, 10.0)}, {{{0, Vec3(0, 0, 0)}}}, 200, &kept, 1,
                                   true, &self_free);
    EXPECT_EQ(kept, 0u);
    EXPECT_EQ(self_free, 200u);
}

// Random scenes: six ropes of random segment lengths (5-15 mm), radii (2-6 mm) and
// shapes (each segment turned up to ~5 degrees from the last), pinned at one end at random
// places in a 20 cm box, so that they swing through each other and bend: the proof holds
// for about a quarter of the strings' steps, and the search keeps every pair the plain
// one keeps, bit for bit (one scene on one thread, one on two).
TEST(StepKernels, StraightStringsSkipKeepsEveryPairInRandomScenes) {
    std::mt19937_64 rng(7);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    std::size_t kept = 0, self_free = 0;
    for (int scene = 0; scene < 2; ++scene) {
        std::vector<tearables::StringDesc> descs;
        std::vector<std::vector<std::pair<int, Vec3>>> pins;
        for (int k = 0; k < 6; ++k) {
            const double length = 0.01 + 0.005 * u(rng), radius = 0.004 + 0.002 * u(rng);
            Vec3 p = 0.1 * Vec3(u(rng), u(rng), u(rng)), dir = randomUnit(rng);
            tearables::StringDesc d;
            for (int i = 0; i <= 40; ++i) {
                d.points.push_back(p);
                dir = (dir + 0.08 * randomUnit(rng).cross(dir)).normalized();  // up to ~5 degrees a segment
                p += length * dir;
            }
            d.radius = radius;
            d.density = 0.001 / (3.14159265358979 * radius * radius * length);
            descs.push_back(d);
            pins.push_back({{0, d.points.front()}});
        }
        std::size_t scene_free = 0;
        expectSamePairsWithNodePruning(descs, pins, 100, &kept, 1 + scene, true, &scene_free);
        EXPECT_LT(scene_free, 6u * 100u) << scene;  // not every string in every step
        self_free += scene_free;
    }
    EXPECT_GT(kept, 100u);     // they touched
    EXPECT_GT(self_free, 0u);  // and the proof held at times
}

// A string that is not straight keeps its self search: a rope coiled in a flat spiral
// (every segment turns), and one folded back on itself in a hairpin, are never proved
// free of self pairs, and the hairpin's arms, held close together, do come into contact.
TEST(StepKernels, CurvedStringsKeepTheirSelfSearch) {
    tearables::World world;
    std::vector<Vec3> spiral, hairpin;
    for (int i = 0; i <= 200; ++i) {
        const double a = 0.1 * i, r = 0.05 + 0.004 * a;
        spiral.push_back(Vec3(r * std::cos(a), 1.0, r * std::sin(a)));
    }
    for (int i = 0; i <= 60; ++i) hairpin.push_back(Vec3(0.01 * i, 0.0, 0.5));
    for (int i = 0; i <= 60; ++i) hairpin.push_back(Vec3(0.6 - 0.01 * i, 0.0, 0.509));  // axes 9 mm apart
    tearables::StringDesc a, b;
    a.points = spiral;
    b.points = hairpin;
    a.radius = b.radius = 0.004;
    const auto ida = world.addString(a);
    const auto idb = world.addString(b);
    world.attachToPoint(idb, 0, b.points.front());
    world.attachToPoint(idb, static_cast<int>(b.points.size()) - 1, b.points.back());
    std::size_t pairs = 0;
    for (int step = 0; step < 50; ++step) {
        world.step(0.01);
        EXPECT_EQ(detail::WorldAccess::lastSelfFreeStrings(world), 0u) << "step " << step;
        pairs += detail::WorldAccess::lastStringSearchPairs(world).size();
    }
    EXPECT_GT(pairs, 0u);
    (void)ida;
}

// The pool splits a forEach over its threads, and a forEach made inside another one's
// function (any thread) runs in place: a stage may split one big string's work and still
// be called from a forEach over many strings.
TEST(StepKernels, ThreadPoolRunsNestedCallsInPlace) {
    tearables::detail::ThreadPool pool;
    pool.setThreads(2);
    EXPECT_TRUE(pool.parallel());
    std::vector<int> outer_parallel(4, -1);
    std::vector<int> inner_sum(4, 0);
    pool.forEach(4, [&](std::size_t i) {
        outer_parallel[i] = pool.parallel() ? 1 : 0;
        std::vector<int> seen(8, 0);
        pool.forEach(8, [&](std::size_t k) { seen[k] = static_cast<int>(k); });  // in place
        for (int v : seen) inner_sum[i] += v;
    });
    for (std::size_t i = 0; i < 4; ++i) {
        EXPECT_EQ(outer_parallel[i], 0) << i;
        EXPECT_EQ(inner_sum[i], 28) << i;
    }
    EXPECT_TRUE(pool.parallel());
    // Restarted with other thread counts between calls, every call still runs each index once.
    for (int round = 0; round < 200; ++round) {
        pool.setThreads(2 + round % 3);
        std::vector<int> hits(7, 0);
        pool.forEach(7, [&](std::size_t k) { ++hits[k]; });
        for (int h : hits) ASSERT_EQ(h, 1) << "round " << round;
    }
}

// A chain long enough (6000 segments) that the tree splits its build and self pairs over a
// parallel pool: a coiled random walk (thousands of self pairs) beside a short chain, found
// with and without a pool of two threads: the same pairs in the same order, and the same
// as the brute-force search.
TEST(StepKernels, ChainTreeSplitsALongChainOverThePoolWithTheSamePairs) {
    std::mt19937_64 rng(11);
    std::vector<Vec3> x;
    std::vector<detail::CollisionSegment> segs;
    for (int c = 0; c < 2; ++c) {
        const int count = c == 0 ? 6000 : 50;
        Vec3 p(0.03 * c, 0.0, 0.0);
        std::vector<Vec3> points;
        for (int i = 0; i <= count; ++i) {
            points.push_back(p);
            p += randomUnit(rng) * 0.01;
            p *= 0.999;  // pulled in: a coil, not a spreading walk
        }
        appendChain(points, static_cast<std::uint32_t>(c), x, segs, [](int i) { return 0.004; }, [](int i) { return i % 997 == 5; });
    }
    detail::ChainTree serial, split;
    std::vector<detail::SegmentPair> a, b;
    serial.findPairs(x.data(), segs, 0.0, a, 3);
    detail::ThreadPool pool;
    pool.setThreads(2);
    split.findPairs(x.data(), segs, 0.0, b, 3, &pool);
    ASSERT_GT(a.size(), 1000u);
    ASSERT_EQ(a.size(), b.size());
    for (std::size_t i = 0; i < a.size(); ++i) {
        ASSERT_EQ(a[i].first, b[i].first) << i;
        ASSERT_EQ(a[i].second, b[i].second) << i;
        ASSERT_EQ(a[i].distance, b[i].distance) << i;
    }
    EXPECT_EQ(keys(b), keys(tearables::reference::bruteForcePairs(x.data(), x.size(), segs, 0.0, 3)));
}

#if defined(__SSE2__)
#include <xmmintrin.h>

namespace {

constexpr unsigned kFlushBits = 0x8040;  // MXCSR: flush-to-zero and denormals-are-zero

/// Counts the subnormal numbers among n doubles.
std::size_t subnormals(const double* v, std::size_t n) {
    return static_cast<std::size_t>(std::count_if(v, v + n, [](double d) { return std::fpclassify(d) == FP_SUBNORMAL; }));
}

}  // namespace

// A long rope laid out straight: its chain solve carries the pin's transverse coupling
// down the rope, decaying geometrically (1e-47 after 1000 particles), and without the
// step's float mode (base/float_mode.hpp) thousands of its gains were subnormal, each
// operation on them a ~100-cycle microcode assist on Intel cores. With it, none is; and
// the step hands the caller's mode back as it was, whichever it was.
TEST(StepKernels, StepFlushesSubnormalsAndRestoresTheCallersMode) {
    const unsigned caller = _mm_getcsr();
    ASSERT_EQ(caller & kFlushBits, 0u) << "the test process starts in IEEE mode";
    tearables::WorldSettings settings;
    settings.threads = 1;
    tearables::World world(settings);
    auto d = tearables::StringDesc::straight({0, 0, 0}, {100.0, 0, 0}, 10000);
    d.particle_masses = {{-1, 10.0}};
    const auto id = world.addString(d);
    world.attachToPoint(id, 0, {0, 0, 0});
    for (int step = 0; step < 5; ++step) {
        world.step(0.01);
        EXPECT_EQ(_mm_getcsr(), caller) << "step " << step;
        const auto& s = (*detail::WorldAccess::parts(world).strings)[0];
        const auto& gains = s.scratch.blk_factor_gain;
        EXPECT_EQ(subnormals(gains.data()->data(), 9 * gains.size()), 0u) << "step " << step;
        EXPECT_EQ(subnormals(s.scratch.blk_rhs.data()->data(), 3 * s.scratch.blk_rhs.size()), 0u) << "step " << step;
    }
    // A caller that flushes already keeps its mode too.
    _mm_setcsr(caller | kFlushBits);
    world.step(0.01);
    EXPECT_EQ(_mm_getcsr(), caller | kFlushBits);
    _mm_setcsr(caller);
}

// Every thread of the pool runs its calls in the step's float mode (the same bits on any
// thread count), and the calling thread's own mode is back after the call.
TEST(StepKernels, ThreadPoolCallsFlushSubnormalsOnEveryThread) {
    const unsigned caller = _mm_getcsr();
    detail::ThreadPool pool;
    pool.setThreads(2);
    std::vector<unsigned> seen(2, 0);
    pool.forEach(2, [&](std::size_t i) { seen[i] = _mm_getcsr(); });
    for (unsigned csr : seen) EXPECT_EQ(csr & kFlushBits, kFlushBits);
    EXPECT_EQ(_mm_getcsr(), caller);
}
#endif
