// Ray tests against strings.
#include "tearables/queries.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

using tearables::Vec3;

TEST(RayTest, CapsuleAgainstBruteForceMarching) {
    std::mt19937_64 rng(3);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    int hits = 0;
    for (int trial = 0; trial < 2000; ++trial) {
        const Vec3 a(u(rng), u(rng), u(rng)), b(u(rng), u(rng), u(rng));
        const double r = 0.05 + 0.2 * std::abs(u(rng));
        // Rays through a point near the capsule (hits and near misses), from far away.
        const Vec3 target = a + 0.5 * (1.0 + u(rng)) * (b - a) + Vec3(u(rng), u(rng), u(rng)) * (1.5 * r);
        const Vec3 from = target + 3.0 * Vec3(u(rng), u(rng), u(rng));
        const Vec3 to = 2.0 * target - from;
        // Reference: march along the ray and test the distance to the segment.
        auto inside = [&](double t) {
            const Vec3 p = from + t * (to - from);
            const Vec3 ab = b - a;
            const double s = std::clamp((p - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
            return (p - (a + s * ab)).norm() <= r;
        };
        double first = -1.0;
        for (int k = 0; k <= 20000; ++k)
            if (inside(k / 20000.0)) {
                first = k / 20000.0;
                break;
            }
        const auto h = tearables::rayCapsule(from, to, a, b, r);
        if (first < 0.0) {
            // A miss, unless the ray only grazes the capsule between two marching samples.
            if (h) {
                const double t = h->first;
                const Vec3 p = from + t * (to - from);
                const Vec3 ab = b - a;
                const double s = std::clamp((p - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
                EXPECT_NEAR((p - (a + s * ab)).norm(), r, 1e-6) << trial;
            }
            continue;
        }
        ++hits;
        ASSERT_TRUE(h.has_value()) << trial;
        EXPECT_NEAR(h->first, first, 1e-4) << trial;
    }
    EXPECT_GT(hits, 500);
}

TEST(RayTest, FindsTheNearestStringAndSegment) {
    tearables::World world;
    auto d = tearables::StringDesc::straight({-1, 0, 0}, {1, 0, 0}, 20);
    d.radius = 0.01;
    const auto near = world.addString(d);
    d.points = tearables::StringDesc::straight({-1, 0, -1}, {1, 0, -1}, 20).points;
    world.addString(d);
    const auto hit = tearables::rayTest(world, {0.25, 0, 5}, {0.25, 0, -5});
    ASSERT_TRUE(hit.has_value());
    EXPECT_EQ(hit->string, near);
    EXPECT_EQ(hit->segment, 12);  // x = 0.25 lies in segment 12 (0.2 .. 0.3)
    EXPECT_NEAR(hit->point.z(), 0.01, 1e-9);
    EXPECT_NEAR(hit->normal.z(), 1.0, 1e-9);
    EXPECT_FALSE(tearables::rayTest(world, {0, 1, 5}, {0, 1, -5}).has_value());
}
