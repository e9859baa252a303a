// Issue 9: the faster kernels give what the ones they replace gave: ChainTree (the
// string-string broad phase) against the brute-force search, also for strings side by
// side, where the chains are swept along another axis than x.
#include "collision/grid.hpp"

#include <gtest/gtest.h>

#include <algorithm>
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
            const auto base = static_cast<std::uint32_t>(x.size());
            Vec3 p = layout == 0 ? Vec3(u(rng), u(rng), u(rng)) * 0.1 : Vec3(0.0, 0.0, 0.012 * c);
            for (int i = 0; i <= per_chain; ++i) {
                x.push_back(p);
                p += layout == 0 ? randomUnit(rng) * 0.01 : Vec3(0.01, 0.002 * u(rng), 0.002 * u(rng));
            }
            for (int i = 0; i < per_chain; ++i) {
                detail::CollisionSegment s;
                s.a = base + static_cast<std::uint32_t>(i);
                s.b = s.a + 1;
                s.chain = static_cast<std::uint32_t>(c);
                s.index_in_chain = static_cast<std::uint32_t>(i);
                s.radius = 0.004 * (1.0 + (i % 7 == 0 ? 3.0 : 0.0));
                s.skip = (i % 29) == 5;
                segs.push_back(s);
            }
        }
        detail::ChainTree tree;
        std::vector<detail::SegmentPair> out;
        tree.findPairs(x.data(), segs, 0.0, out, 3);
        const auto expected = detail::bruteForcePairs(x.data(), x.size(), segs, 0.0, 3);
        ASSERT_GT(expected.size(), 10u) << layout;
        EXPECT_EQ(keys(out), keys(expected)) << layout;
    }
}

}  // namespace
