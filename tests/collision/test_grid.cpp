// The capsule narrow phase against a dense-sampling reference, and the hash-grid broad
// phase against brute force, including the configurations around cell edges and corners
// that decide whether a neighbour stencil is complete (Strings, Sec. 6).
#include <gtest/gtest.h>

#include <algorithm>
#include <tuple>
#include <cmath>
#include <cstdint>
#include <iostream>
#include <random>
#include <vector>

#include "collision/capsule.hpp"
#include "collision/grid.hpp"
#include "collision/reference_grid.hpp"

namespace {

using tearables::InvalidInput;
using tearables::Vec3;
using namespace tearables::detail;
using namespace tearables::reference;
using tearables::reference::SegmentGrid;

Vec3 randomUnit(std::mt19937_64& rng) {
    std::normal_distribution<double> n;
    for (;;) {
        const Vec3 v(n(rng), n(rng), n(rng));
        if (v.squaredNorm() > 1e-12) return v.normalized();
    }
}

// ---------------------------------------------------------------------------------------
// closestPointsOfSegments
// ---------------------------------------------------------------------------------------

double pointSegmentDistance(const Vec3& x, const Vec3& q0, const Vec3& q1) {
    const Vec3 d = q1 - q0;
    const double e = d.squaredNorm();
    const double t = e > 0.0 ? std::clamp((x - q0).dot(d) / e, 0.0, 1.0) : 0.0;
    return (x - (q0 + t * d)).norm();
}

// Reference: G(s) = distance from P(s) to the second segment is convex in s. Sample it
// densely, then refine by ternary search in the bracket around the best sample.
double referenceDistance(const Vec3& p0, const Vec3& p1, const Vec3& q0, const Vec3& q1) {
    const int n = 2000;
    auto g = [&](double s) { return pointSegmentDistance(p0 + s * (p1 - p0), q0, q1); };
    int best = 0;
    double best_d = g(0.0);
    for (int k = 1; k <= n; ++k) {
        const double d = g(static_cast<double>(k) / n);
        if (d < best_d) best_d = d, best = k;
    }
    double lo = std::max(0, best - 1) / static_cast<double>(n);
    double hi = std::min(n, best + 1) / static_cast<double>(n);
    for (int it = 0; it < 200; ++it) {
        const double m1 = lo + (hi - lo) / 3.0;
        const double m2 = hi - (hi - lo) / 3.0;
        if (g(m1) <= g(m2))
            hi = m2;
        else
            lo = m1;
    }
    return std::min(best_d, g(0.5 * (lo + hi)));
}

void expectClosestConsistent(const Vec3& p0, const Vec3& p1, const Vec3& q0, const Vec3& q1, const char* what) {
    const SegmentClosest c = closestPointsOfSegments(p0, p1, q0, q1);
    const double scale = std::max({(p1 - p0).norm(), (q1 - q0).norm(), (p0 - q0).norm(), 1e-300});
    const double tol = 1e-10 * scale;
    ASSERT_TRUE(std::isfinite(c.s) && std::isfinite(c.t) && std::isfinite(c.distance)) << what;
    EXPECT_GE(c.s, 0.0) << what;
    EXPECT_LE(c.s, 1.0) << what;
    EXPECT_GE(c.t, 0.0) << what;
    EXPECT_LE(c.t, 1.0) << what;
    EXPECT_LE((c.p - (p0 + c.s * (p1 - p0))).norm(), 1e-12 * scale) << what;
    EXPECT_LE((c.q - (q0 + c.t * (q1 - q0))).norm(), 1e-12 * scale) << what;
    EXPECT_NEAR(c.distance, (c.p - c.q).norm(), 1e-12 * scale) << what;
    const double ref = referenceDistance(p0, p1, q0, q1);
    EXPECT_NEAR(c.distance, ref, tol) << what;
    // Each point is the closest point to the other one on its own segment.
    EXPECT_NEAR(pointSegmentDistance(c.p, q0, q1), c.distance, tol) << what;
    EXPECT_NEAR(pointSegmentDistance(c.q, p0, p1), c.distance, tol) << what;
    // Symmetric in the two segments.
    EXPECT_NEAR(closestPointsOfSegments(q0, q1, p0, p1).distance, c.distance, tol) << what;
}

TEST(CapsuleClosestPoints, MatchesDenseSamplingOnRandomSegments) {
    std::mt19937_64 rng(11);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    for (int trial = 0; trial < 400; ++trial) {
        const Vec3 p0(u(rng), u(rng), u(rng)), p1(u(rng), u(rng), u(rng));
        const Vec3 q0(u(rng), u(rng), u(rng)), q1(u(rng), u(rng), u(rng));
        expectClosestConsistent(p0, p1, q0, q1, "random");
        // Crossing segments (distance ~0) through a common point.
        const Vec3 x(u(rng), u(rng), u(rng));
        const Vec3 d1 = randomUnit(rng), d2 = randomUnit(rng);
        const double s = 0.5 * (u(rng) + 1.0), t = 0.5 * (u(rng) + 1.0);
        expectClosestConsistent(x - s * d1, x + (1 - s) * d1, x - t * d2, x + (1 - t) * d2, "crossing");
        EXPECT_LT(closestPointsOfSegments(x - s * d1, x + (1 - s) * d1, x - t * d2, x + (1 - t) * d2).distance, 1e-12);
    }
}

TEST(CapsuleClosestPoints, ParallelAntiParallelCollinearAndNearlyParallel) {
    std::mt19937_64 rng(12);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    for (int trial = 0; trial < 400; ++trial) {
        const Vec3 d = randomUnit(rng) * (0.1 + std::abs(u(rng)));
        const Vec3 p0(u(rng), u(rng), u(rng));
        const Vec3 off =
            (trial % 4 == 0) ? Vec3(Vec3::Zero()) : Vec3(Vec3(u(rng), u(rng), u(rng)) * 0.3);  // collinear or not
        const double shift = 2.0 * u(rng), k = (trial % 2 ? 1.0 : -1.0) * (0.2 + std::abs(u(rng)));
        const Vec3 q0 = p0 + off + shift * d;
        expectClosestConsistent(p0, p0 + d, q0, q0 + k * d, "parallel");
        // Nearly parallel: a tilt of 1e-14 .. 1e-4 rad (both sides of the parallel test).
        const double tilt = std::pow(10.0, -14.0 + 10.0 * 0.5 * (u(rng) + 1.0));
        const Vec3 perp = d.unitOrthogonal() * d.norm() * tilt;
        expectClosestConsistent(p0, p0 + d, q0, q0 + k * d + perp, "nearly parallel");
    }
}

TEST(CapsuleClosestPoints, ParallelOverlapReturnsTheMiddleOfTheOverlap) {
    // Along x: [0, 4] and [1, 2] at height 1 -> the overlap is [1, 2], its middle x = 1.5.
    const SegmentClosest c = closestPointsOfSegments({0, 0, 0}, {4, 0, 0}, {2, 1, 0}, {1, 1, 0});
    EXPECT_NEAR(c.distance, 1.0, 1e-15);
    EXPECT_NEAR(c.p.x(), 1.5, 1e-15);
    EXPECT_NEAR(c.q.x(), 1.5, 1e-15);
    EXPECT_NEAR(c.s, 0.375, 1e-15);
    EXPECT_NEAR(c.t, 0.5, 1e-15);
    // Disjoint parallel segments: the nearest ends.
    const SegmentClosest d = closestPointsOfSegments({0, 0, 0}, {1, 0, 0}, {3, 1, 0}, {2, 1, 0});
    EXPECT_NEAR(d.distance, std::sqrt(2.0), 1e-15);
    EXPECT_EQ(d.s, 1.0);
    EXPECT_EQ(d.t, 1.0);
}

TEST(CapsuleClosestPoints, DegenerateSegments) {
    std::mt19937_64 rng(13);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    for (int trial = 0; trial < 200; ++trial) {
        const Vec3 p0(u(rng), u(rng), u(rng)), q0(u(rng), u(rng), u(rng)), q1(u(rng), u(rng), u(rng));
        expectClosestConsistent(p0, p0, q0, q1, "first is a point");
        expectClosestConsistent(q0, q1, p0, p0, "second is a point");
        expectClosestConsistent(p0, p0, q0, q0, "two points");
        expectClosestConsistent(p0, p0, p0, p0, "one point");
        // A point on the other segment, and an almost-point (length 1e-20).
        const double t = 0.5 * (u(rng) + 1.0);
        const Vec3 on = q0 + t * (q1 - q0);
        EXPECT_LT(closestPointsOfSegments(on, on, q0, q1).distance, 1e-15);
        expectClosestConsistent(p0, p0 + Vec3(1e-20, 0, 0), q0, q1, "tiny");
    }
    const SegmentClosest z = closestPointsOfSegments({1, 2, 3}, {1, 2, 3}, {1, 2, 3}, {1, 2, 3});
    EXPECT_EQ(z.s, 0.0);
    EXPECT_EQ(z.t, 0.0);
    EXPECT_EQ(z.distance, 0.0);
}

// ---------------------------------------------------------------------------------------
// Configurations
// ---------------------------------------------------------------------------------------

struct Config {
    std::vector<Vec3> x;
    std::vector<CollisionSegment> segs;
    double margin = 0.0;
    std::uint32_t skip_neighbours = 1;
};

struct GenParams {
    double l = 1.0;  // nominal segment length (the longest)
    double r_min = 0.05, r_max = 0.4;
    double box = 6.0;  // random walks start in [0, box)^3 (shifted by `origin`)
    Vec3 origin = Vec3::Zero();
    int chains = 4;
    int max_chain_segments = 30;
    int isolated = 6;       // isolated segments
    int corner_chains = 6;  // short chains grown from points near cell edges / corners
    double h_hint = 1.0;    // the cell size the corner chains aim at
};

// Adds a chain of n segments starting at x0 (a persistent random walk with step lengths
// in [0.5 l, l], sometimes 0 (a degenerate segment)).
void addChain(Config& c, std::mt19937_64& rng, const GenParams& g, Vec3 x0, int n, std::uint32_t chain) {
    std::uniform_real_distribution<double> u(0.0, 1.0);
    Vec3 dir = randomUnit(rng);
    const auto first = static_cast<std::uint32_t>(c.x.size());
    c.x.push_back(x0);
    for (int k = 0; k < n; ++k) {
        dir = (dir + 0.9 * randomUnit(rng)).normalized();
        const double len = u(rng) < 0.03 ? 0.0 : g.l * (0.5 + 0.5 * u(rng));
        c.x.push_back(c.x.back() + len * dir);
        CollisionSegment s;
        s.a = first + static_cast<std::uint32_t>(k);
        s.b = s.a + 1;
        s.chain = chain;
        s.index_in_chain = static_cast<std::uint32_t>(k);
        s.radius = g.r_min + (g.r_max - g.r_min) * u(rng);
        s.skip = u(rng) < 0.03;  // broken
        c.segs.push_back(s);
    }
}

Config randomConfig(std::mt19937_64& rng, const GenParams& g) {
    std::uniform_real_distribution<double> u(0.0, 1.0);
    std::uniform_int_distribution<int> lattice(-2, 2);
    Config c;
    std::uint32_t chain = 0;
    for (int k = 0; k < g.chains; ++k) {
        const Vec3 x0 = g.origin + g.box * Vec3(u(rng), u(rng), u(rng));
        addChain(c, rng, g, x0, 1 + static_cast<int>(u(rng) * g.max_chain_segments), chain++);
    }
    for (int k = 0; k < g.isolated; ++k) {
        const Vec3 x0 = g.origin + g.box * Vec3(u(rng), u(rng), u(rng));
        addChain(c, rng, g, x0, 1, chain++);
    }
    // The hard cases: short chains whose particles sit near a cell edge or corner (within a
    // radius of it), several around the same one so that they overlap across it.
    const Vec3 anchor = g.origin + g.h_hint * Vec3(lattice(rng), lattice(rng), lattice(rng));
    for (int k = 0; k < g.corner_chains; ++k) {
        Vec3 x0 = anchor + g.r_max * 1.5 * Vec3(u(rng) - 0.5, u(rng) - 0.5, u(rng) - 0.5);
        if (k % 2) x0.z() = anchor.z() + g.h_hint * (u(rng) - 0.5);  // near the edge along z
        // Start half a segment back so the anchor is mid-segment as often as at an end.
        const Vec3 dir = randomUnit(rng);
        if (k % 3 == 0) x0 -= 0.5 * g.l * u(rng) * dir;
        addChain(c, rng, g, x0, 1 + static_cast<int>(u(rng) * 3), chain++);
    }
    c.margin = u(rng) < 0.5 ? 0.0 : 0.1 * g.l * u(rng);
    c.skip_neighbours = static_cast<std::uint32_t>(u(rng) * 4);  // 0 .. 3
    return c;
}

bool samePairs(const std::vector<SegmentPair>& a, const std::vector<SegmentPair>& b) {
    if (a.size() != b.size()) return false;
    for (std::size_t k = 0; k < a.size(); ++k) {
        if (a[k].first != b[k].first || a[k].second != b[k].second || a[k].s != b[k].s || a[k].t != b[k].t ||
            a[k].distance != b[k].distance || a[k].normal != b[k].normal)
            return false;
    }
    return true;
}

// Whether some endpoint pair of the two segments lies in cells the stencil connects.
bool endpointsInStencil(const Config& c, const SegmentPair& p, double h, bool seven) {
    const double inv = 1.0 / h;
    const CollisionSegment& si = c.segs[p.first];
    const CollisionSegment& sj = c.segs[p.second];
    for (std::uint32_t u : {si.a, si.b})
        for (std::uint32_t v : {sj.a, sj.b}) {
            const CellCoord cu = cellOf(c.x[u], inv), cv = cellOf(c.x[v], inv);
            const int dx = std::abs(cu.x - cv.x), dy = std::abs(cu.y - cv.y), dz = std::abs(cu.z - cv.z);
            if (seven ? dx + dy + dz <= 1 : std::max({dx, dy, dz}) <= 1) return true;
        }
    return false;
}

void expectValidOutput(const Config& c, const std::vector<SegmentPair>& out) {
    for (std::size_t k = 0; k < out.size(); ++k) {
        const SegmentPair& p = out[k];
        ASSERT_LT(p.first, p.second);
        if (k > 0) {
            ASSERT_TRUE(out[k - 1].first < p.first || (out[k - 1].first == p.first && out[k - 1].second < p.second));
        }
        const CollisionSegment& si = c.segs[p.first];
        const CollisionSegment& sj = c.segs[p.second];
        ASSERT_FALSE(si.skip || sj.skip);
        // Adjacent segments (sharing a particle) are never reported, nor near chain neighbours.
        ASSERT_FALSE(si.a == sj.a || si.a == sj.b || si.b == sj.a || si.b == sj.b);
        if (si.chain == sj.chain) {
            ASSERT_GT(std::max(si.index_in_chain, sj.index_in_chain) - std::min(si.index_in_chain, sj.index_in_chain),
                      c.skip_neighbours);
        }
        ASSERT_LT(p.distance, si.radius + sj.radius + c.margin);
        ASSERT_NEAR(p.normal.norm(), 1.0, 1e-12);
    }
}

// ---------------------------------------------------------------------------------------
// The grid against brute force
// ---------------------------------------------------------------------------------------

TEST(SegmentGrid, TwentySevenEqualsBruteForceAndSevenIsItsStencilSubset) {
    std::mt19937_64 rng(2024);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    SegmentGrid grid;  // one grid for all configurations: also checks reuse
    std::vector<SegmentPair> out27, out7;
    std::size_t total = 0, missed7 = 0, configs_with_miss7 = 0, configs = 0;
    double deepest_miss7 = 0.0;  // largest penetration (r1 + r2 + margin - distance) / (r1 + r2) missed
    for (int trial = 0; trial < 3000; ++trial) {
        GenParams g;
        g.l = 0.5 + u(rng);
        const bool thin = u(rng) < 0.3;
        g.r_min = thin ? 0.0 : 0.02 * g.l;
        g.r_max = thin ? 0.05 * g.l : (0.1 + 0.5 * u(rng)) * g.l;
        g.box = g.l * (2.0 + 4.0 * u(rng));
        g.origin = Vec3(u(rng) - 0.5, u(rng) - 0.5, u(rng) - 0.5) * 20.0 * g.l;  // negative cells too
        g.chains = 1 + static_cast<int>(u(rng) * 5);
        g.isolated = static_cast<int>(u(rng) * 8);
        g.corner_chains = 2 + static_cast<int>(u(rng) * 8);
        // The cell size: exactly the required one (the hard case), or larger.
        const double factor = trial % 3 == 0 ? 1.0 : (trial % 3 == 1 ? 1.0 + 0.5 * u(rng) : 2.0 + 2.0 * u(rng));
        g.h_hint = factor * requiredCellSize(g.l, g.r_max, 0.1 * g.l);
        Config c = randomConfig(rng, g);
        const double required = requiredCellSize(c.x.data(), c.x.size(), c.segs, c.margin);
        const double h = trial % 3 == 0 ? required : std::max(required, g.h_hint);

        const std::vector<SegmentPair> brute =
            bruteForcePairs(c.x.data(), c.x.size(), c.segs, c.margin, c.skip_neighbours);
        grid.findPairs(c.x.data(), c.x.size(), c.segs, h, c.margin, NeighbourSearch::TwentySeven, out27,
                       c.skip_neighbours);
        ASSERT_TRUE(samePairs(out27, brute))
            << "trial " << trial << ": 27-cell search " << out27.size() << " pairs, brute force " << brute.size();
        expectValidOutput(c, brute);

        // Seven: exactly the brute-force pairs that have an endpoint pair in the 7-cell stencil.
        grid.findPairs(c.x.data(), c.x.size(), c.segs, h, c.margin, NeighbourSearch::Seven, out7, c.skip_neighbours);
        std::vector<SegmentPair> expected7;
        for (const SegmentPair& p : brute) {
            if (endpointsInStencil(c, p, h, true)) {
                expected7.push_back(p);
            } else {
                ++missed7;
                const double rr = c.segs[p.first].radius + c.segs[p.second].radius;
                if (rr > 0) deepest_miss7 = std::max(deepest_miss7, (rr + c.margin - p.distance) / rr);
            }
            ASSERT_TRUE(endpointsInStencil(c, p, h, false));  // the lemma, pair by pair
        }
        ASSERT_TRUE(samePairs(out7, expected7)) << "trial " << trial;
        configs_with_miss7 += expected7.size() != brute.size();
        total += brute.size();
        ++configs;
    }
    EXPECT_GT(total, 10000u);  // the configurations do collide
    std::cout << "[ info ] " << configs << " configurations, " << total
              << " overlapping pairs; the 7-cell search missed " << missed7 << " (" << 100.0 * missed7 / total
              << "%) in " << configs_with_miss7 << " configurations, up to " << 100.0 * deepest_miss7
              << "% of r1+r2 deep\n";
}

TEST(SegmentGrid, DenseClustersAndManyParticlesPerCell) {
    // Many chains crumpled into a small box: dozens of particles per cell, many pairs.
    std::mt19937_64 rng(5);
    SegmentGrid grid;
    std::vector<SegmentPair> out;
    for (int trial = 0; trial < 20; ++trial) {
        GenParams g;
        g.l = 1.0;
        g.r_min = 0.05;
        g.r_max = 0.3;
        g.box = 1.5;
        g.chains = 12;
        g.max_chain_segments = 25;
        g.corner_chains = 10;
        g.h_hint = requiredCellSize(g.l, g.r_max, 0.1);
        Config c = randomConfig(rng, g);
        const double h = requiredCellSize(c.x.data(), c.x.size(), c.segs, c.margin) * (trial % 2 ? 1.0 : 3.0);
        const auto brute = bruteForcePairs(c.x.data(), c.x.size(), c.segs, c.margin, c.skip_neighbours);
        grid.findPairs(c.x.data(), c.x.size(), c.segs, h, c.margin, NeighbourSearch::TwentySeven, out,
                       c.skip_neighbours);
        ASSERT_TRUE(samePairs(out, brute)) << trial;
        EXPECT_GT(brute.size(), 20u);
    }
}

TEST(SegmentGrid, LargeRopePilesMatchBruteForce) {
    // Thousands of segments: big tables, hash blocks of many cells, runs of cells.
    std::mt19937_64 rng(77);
    SegmentGrid grid;
    std::vector<SegmentPair> out;
    for (int trial = 0; trial < 3; ++trial) {
        GenParams g;
        g.l = 0.01;
        g.r_min = 0.001;
        g.r_max = 0.004;
        g.box = 0.08 + 0.1 * trial;
        g.origin = Vec3(-0.05, 0.02, -0.3) * trial;
        g.chains = 40;
        g.max_chain_segments = 120;
        g.isolated = 50;
        g.corner_chains = 10;
        g.h_hint = requiredCellSize(g.l, g.r_max, 0.001);
        Config c = randomConfig(rng, g);
        const auto brute = bruteForcePairs(c.x.data(), c.x.size(), c.segs, c.margin, c.skip_neighbours);
        EXPECT_GT(brute.size(), 50u);
        for (double factor : {1.0, 1.7}) {
            const double h = factor * requiredCellSize(c.x.data(), c.x.size(), c.segs, c.margin);
            grid.findPairs(c.x.data(), c.x.size(), c.segs, h, c.margin, NeighbourSearch::TwentySeven, out,
                           c.skip_neighbours);
            ASSERT_TRUE(samePairs(out, brute)) << trial << " " << factor;
        }
    }
}

TEST(SegmentGrid, AdjacentSegmentsOfAChainAreNeverReported) {
    // A tightly folded zig-zag: every segment overlaps its neighbours and the ones after.
    std::vector<Vec3> x;
    std::vector<CollisionSegment> segs;
    for (int k = 0; k <= 20; ++k) x.emplace_back(0.1 * k, (k % 2) * 1.0, 0.0);
    for (std::uint32_t k = 0; k < 20; ++k) segs.push_back({k, k + 1, 7, k, 0.3, false});
    SegmentGrid grid;
    std::vector<SegmentPair> out;
    const double h = requiredCellSize(x.data(), x.size(), segs, 0.0);
    for (std::uint32_t skip = 0; skip < 4; ++skip) {
        grid.findPairs(x.data(), x.size(), segs, h, 0.0, NeighbourSearch::TwentySeven, out, skip);
        EXPECT_FALSE(out.empty());
        for (const SegmentPair& p : out) EXPECT_GT(p.second - p.first, std::max(1u, skip));
        EXPECT_TRUE(samePairs(out, bruteForcePairs(x.data(), x.size(), segs, 0.0, skip)));
    }
    // Another chain id with the same indices: the same geometry, now all non-adjacent pairs
    // of different chains count, but segments sharing a particle still never do.
    for (std::size_t k = 0; k < segs.size(); k += 2) segs[k].chain = 8;
    grid.findPairs(x.data(), x.size(), segs, h, 0.0, NeighbourSearch::TwentySeven, out, 3);
    for (const SegmentPair& p : out) EXPECT_GE(p.second - p.first, 2u);
}

TEST(SegmentGrid, DeterministicAndAllocationFreeAfterWarmUp) {
    std::mt19937_64 rng(99);
    GenParams g;
    g.chains = 8;
    g.box = 4.0;
    Config c = randomConfig(rng, g);
    const double h = requiredCellSize(c.x.data(), c.x.size(), c.segs, c.margin);
    SegmentGrid a, b;
    std::vector<SegmentPair> out_a, out_b;
    a.findPairs(c.x.data(), c.x.size(), c.segs, h, c.margin, NeighbourSearch::TwentySeven, out_a, c.skip_neighbours);
    ASSERT_FALSE(out_a.empty());
    // A grid that saw a bigger and a different problem first gives the identical output.
    Config big = randomConfig(rng, GenParams{1.0, 0.05, 0.4, 10.0, Vec3(-5, 3, 1), 20, 40, 10, 10, 1.0});
    b.findPairs(big.x.data(), big.x.size(), big.segs, 2.0, big.margin, NeighbourSearch::Seven, out_b);
    b.findPairs(c.x.data(), c.x.size(), c.segs, h, c.margin, NeighbourSearch::TwentySeven, out_b, c.skip_neighbours);
    EXPECT_TRUE(samePairs(out_a, out_b));
    // Repeated calls: identical output, no growth of the working memory or the output.
    const std::size_t bytes = a.reservedBytes();
    const std::size_t cap = out_a.capacity();
    const SegmentPair* data = out_a.data();
    for (int k = 0; k < 5; ++k) {
        a.findPairs(c.x.data(), c.x.size(), c.segs, h, c.margin, NeighbourSearch::TwentySeven, out_b,
                    c.skip_neighbours);
        EXPECT_TRUE(samePairs(out_a, out_b));
        a.findPairs(c.x.data(), c.x.size(), c.segs, h, c.margin, NeighbourSearch::TwentySeven, out_a,
                    c.skip_neighbours);
        EXPECT_EQ(a.reservedBytes(), bytes);
        EXPECT_EQ(out_a.capacity(), cap);
        EXPECT_EQ(out_a.data(), data);
    }
}

// ---------------------------------------------------------------------------------------
// The cell-size condition: counterexamples and tightness
// ---------------------------------------------------------------------------------------

TEST(SegmentGrid, PaperSevenCellClaimFailsForCapsulesAtCellSizeEqualSegmentLength) {
    // h = l = 1, r = 0.05: two unit segments inside the cells (0,0,0) and (1,1,0), which
    // share only the edge x = y = 1; the axes are 0.085 apart (< 2 r). Every endpoint pair
    // is in cells that differ in x and y, so the 7-cell search cannot see them.
    const double d = 1.0 / std::sqrt(2.0);
    const std::vector<Vec3> x = {
        {0.97, 0.97, 0.5}, {0.97 - d, 0.97 - d, 0.5}, {1.03, 1.03, 0.5}, {1.03 + d, 1.03 + d, 0.5}};
    const std::vector<CollisionSegment> segs = {{0, 1, 0, 0, 0.05, false}, {2, 3, 1, 0, 0.05, false}};
    const auto brute = bruteForcePairs(x.data(), x.size(), segs, 0.0);
    ASSERT_EQ(brute.size(), 1u);
    EXPECT_NEAR(brute[0].distance, 0.06 * std::sqrt(2.0), 1e-12);
    SegmentGrid grid;
    std::vector<SegmentPair> out;
    // The same holds for every cell size >= l: the segments stay inside their cells.
    for (double h : {1.0, 1.5, 3.0, 10.0}) {
        std::vector<Vec3> xs = x;
        for (Vec3& p : xs) p = (p - Vec3(1, 1, 0.5)) + Vec3(h, h, 0.5 * h);  // keep the edge at x = y = h
        grid.findPairs(xs.data(), xs.size(), segs, h, 0.0, NeighbourSearch::Seven, out);
        EXPECT_TRUE(out.empty()) << h;
        grid.findPairs(xs.data(), xs.size(), segs, h, 0.0, NeighbourSearch::TwentySeven, out);
        EXPECT_EQ(out.size(), 1u) << h;
    }
}

TEST(SegmentGrid, PaperSevenCellClaimFailsEvenForIntersectingThinSegments) {
    // Zero radius, h = 1 >= both lengths (0.735, 0.942): the segments intersect exactly at
    // (0.02, 0.1, 0.3), yet their endpoints lie in the cells (0,-1,0), (0,0,-1) and
    // (0,0,1), (-1,0,0): every cross pair differs in two coordinates (or by 2 in z).
    const std::vector<Vec3> x = {{0.02, -0.1, 0.5}, {0.02, 0.42, -0.02}, {0.1, 0.1, 1.02}, {-0.004, 0.1, 0.084}};
    const std::vector<CollisionSegment> segs = {{0, 1, 0, 0, 0.0, false}, {2, 3, 1, 0, 0.0, false}};
    const double margin = 1e-9;
    const auto brute = bruteForcePairs(x.data(), x.size(), segs, margin);
    ASSERT_EQ(brute.size(), 1u);
    EXPECT_LT(brute[0].distance, 1e-12);
    EXPECT_LE((x[1] - x[0]).norm(), 1.0);
    EXPECT_LE((x[3] - x[2]).norm(), 1.0);
    SegmentGrid grid;
    std::vector<SegmentPair> out;
    grid.findPairs(x.data(), x.size(), segs, 1.0, margin, NeighbourSearch::Seven, out);
    EXPECT_TRUE(out.empty());
    grid.findPairs(x.data(), x.size(), segs, 1.0, margin, NeighbourSearch::TwentySeven, out);
    EXPECT_EQ(out.size(), 1u);
}

TEST(SegmentGrid, RequiredCellSizeIsTightForThinCapsules) {
    // Two unit segments crossing at their midpoints along the diagonals of an axis-aligned
    // square of side 1/sqrt(2): every cross endpoint pair is a side of the square. With a
    // cell 1% below 1/sqrt(2) and the grid placed so that each side spans three cells, no
    // endpoint pair is in the 27-cell stencil although the segments intersect.
    const double side = 1.0 / std::sqrt(2.0);
    const double h = 0.99 * side;
    const Vec3 c(1.5 * h, 1.5 * h, 0.5 * h);  // the square [c - side/2, c + side/2] spans cells 0..2
    const double k = 0.5 * side;
    Config cfg;
    cfg.x = {c + Vec3(-k, -k, 0), c + Vec3(k, k, 0), c + Vec3(-k, k, 0), c + Vec3(k, -k, 0)};
    cfg.segs = {{0, 1, 0, 0, 0.0, false}, {2, 3, 1, 0, 0.0, false}};
    const auto brute = bruteForcePairs(cfg.x.data(), cfg.x.size(), cfg.segs, 1e-9);
    ASSERT_EQ(brute.size(), 1u);
    EXPECT_FALSE(endpointsInStencil(cfg, brute[0], h, false));
    // The grid refuses that cell size, and finds the pair at the required one.
    EXPECT_NEAR(requiredCellSize(cfg.x.data(), cfg.x.size(), cfg.segs, 1e-9), side, 1e-8);
    SegmentGrid grid;
    std::vector<SegmentPair> out;
    EXPECT_THROW(grid.findPairs(cfg.x.data(), cfg.x.size(), cfg.segs, h, 1e-9, NeighbourSearch::TwentySeven, out),
                 InvalidInput);
    grid.findPairs(cfg.x.data(), cfg.x.size(), cfg.segs, side + 1e-8, 1e-9, NeighbourSearch::TwentySeven, out);
    EXPECT_EQ(out.size(), 1u);
}

TEST(SegmentGrid, RejectsInvalidInput) {
    const std::vector<Vec3> x = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 0}};
    std::vector<CollisionSegment> segs = {{0, 1, 0, 0, 0.1, false}, {2, 3, 1, 0, 0.1, false}};
    SegmentGrid grid;
    std::vector<SegmentPair> out;
    const double h = requiredCellSize(1.0, 0.1, 0.0);
    EXPECT_NO_THROW(grid.findPairs(x.data(), x.size(), segs, h, 0.0, NeighbourSearch::TwentySeven, out));
    auto fieldOf = [&](auto call) -> std::string {
        try {
            call();
        } catch (const InvalidInput& e) {
            return e.field();
        }
        return "";
    };
    auto find = [&](const std::vector<CollisionSegment>& s, double cell, double margin) {
        return fieldOf([&] { grid.findPairs(x.data(), x.size(), s, cell, margin, NeighbourSearch::Seven, out); });
    };
    EXPECT_EQ(find(segs, 0.99 * h, 0.0), "cell_size");
    EXPECT_EQ(find(segs, h, 0.01), "cell_size");  // a margin raises the requirement
    EXPECT_EQ(find(segs, std::nan(""), 0.0), "cell_size");
    EXPECT_EQ(find(segs, h, -1.0), "margin");
    auto bad = segs;
    bad[1].b = 4;
    EXPECT_EQ(find(bad, h, 0.0), "segments[1].b");
    bad = segs;
    bad[0].b = 0;
    EXPECT_EQ(find(bad, h, 0.0), "segments[0].b");
    bad = segs;
    bad[0].radius = -0.1;
    EXPECT_EQ(find(bad, h, 0.0), "segments[0].radius");
    bad[0].skip = true;  // skipped segments are not checked, nor counted in the requirement
    EXPECT_EQ(find(bad, h, 0.0), "");
    std::vector<Vec3> far = x;
    far[2] = Vec3(1e12, 1, 0);  // 5e11 cells of size 2 from the origin
    far[3] = Vec3(1e12 + 1, 1, 0);
    EXPECT_EQ(fieldOf([&] { grid.findPairs(far.data(), far.size(), segs, 2.0, 0.0, NeighbourSearch::Seven, out); }),
              "positions");
    far[3] = Vec3(std::nan(""), 0, 0);
    EXPECT_EQ(fieldOf([&] { grid.findPairs(far.data(), far.size(), segs, 2.0, 0.0, NeighbourSearch::Seven, out); }),
              "positions");
    // Empty input: no pairs.
    grid.findPairs(x.data(), 0, {}, 1.0, 0.0, NeighbourSearch::TwentySeven, out);
    EXPECT_TRUE(out.empty());
}

}  // namespace

// The box tree per chain (World's string-string search) finds exactly the grid's pairs,
// with the same closest points and normals, on the random piles of the grid tests
// (chains of mixed radii, degenerate and broken segments, neighbour skips, margins).
TEST(ChainTree, FindsExactlyTheGridsPairs) {
    std::mt19937_64 rng(77);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    tearables::reference::SegmentGrid grid;
    ChainTree tree;
    std::vector<SegmentPair> from_grid, from_tree;
    std::size_t total = 0;
    for (int trial = 0; trial < 2000; ++trial) {
        GenParams g;
        g.l = 0.5 + u(rng);
        g.r_min = 0.02 * g.l;
        g.r_max = (0.1 + 2.0 * u(rng)) * g.l;  // up to swept capsules far thicker than long
        g.box = g.l * (2.0 + 4.0 * u(rng));
        g.origin = Vec3(u(rng) - 0.5, u(rng) - 0.5, u(rng) - 0.5) * 20.0 * g.l;
        g.chains = 1 + static_cast<int>(u(rng) * 5);
        g.max_chain_segments = 1 + static_cast<int>(u(rng) * 60);
        g.isolated = static_cast<int>(u(rng) * 8);
        g.corner_chains = static_cast<int>(u(rng) * 8);
        const Config c = randomConfig(rng, g);
        const double cell = requiredCellSize(c.x.data(), c.x.size(), c.segs, c.margin);
        grid.findPairs(c.x.data(), c.x.size(), c.segs, cell, c.margin, NeighbourSearch::TwentySeven, from_grid,
                       c.skip_neighbours);
        tree.findPairs(c.x.data(), c.segs, c.margin, from_tree, c.skip_neighbours);
        std::sort(from_tree.begin(), from_tree.end(),
                  [](const SegmentPair& a, const SegmentPair& b) { return std::tie(a.first, a.second) < std::tie(b.first, b.second); });
        ASSERT_TRUE(samePairs(from_grid, from_tree)) << "trial " << trial << ": grid " << from_grid.size() << " pairs, tree "
                                                     << from_tree.size();
        total += from_grid.size();
    }
    EXPECT_GT(total, 2000u);
}
