// Issue 9: the faster kernels give what the ones they replace gave (to rounding).
//  - csmRotation's rank-1 shortcut (no SVD for a straight rest shape) against the SVD
//    formula it replaces;
//  - ChainTree (the string-string broad phase) against the brute-force search, also for
//    strings side by side, where the chains are swept along another axis than x.
#include "collision/grid.hpp"
#include "string/shape_matching.hpp"

#include <Eigen/SVD>
#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <tuple>
#include <vector>

namespace {

using tearables::Mat3;
using tearables::Quat;
using tearables::Vec3;
namespace detail = tearables::detail;

/// The rotation of csmRotation as it was before the shortcut: always from the SVD.
Mat3 rotationBySvd(const Mat3& a) {
    const Eigen::JacobiSVD<Mat3, Eigen::NoQRPreconditioner> svd(a, Eigen::ComputeFullU | Eigen::ComputeFullV);
    const Vec3& sigma = svd.singularValues();
    if (!(sigma(0) > 0.0)) return Mat3::Identity();
    if (sigma(1) <= 1e-12 * sigma(0))
        return Quat::FromTwoVectors(svd.matrixV().col(0), svd.matrixU().col(0)).toRotationMatrix();
    Mat3 u = svd.matrixU();
    const Mat3& v = svd.matrixV();
    if (u.determinant() * v.determinant() < 0.0) u.col(2) = -u.col(2);
    return u * v.transpose();
}

Vec3 randomUnit(std::mt19937_64& rng) {
    std::normal_distribution<double> g;
    return Vec3(g(rng), g(rng), g(rng)).normalized();
}

// A region of a straight rest shape bent in any way: A = sum m (x - c)(x0 - c0)^T with
// all x0 on one line has rank 1 (to rounding). The shortcut gives the SVD's rotation.
TEST(StepKernels, CsmRotationOfCollinearRegionsMatchesTheSvd) {
    std::mt19937_64 rng(7);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    for (int trial = 0; trial < 2000; ++trial) {
        const Vec3 line = randomUnit(rng);
        const int count = 2 + trial % 15;
        std::vector<Vec3> x(count), x0(count);
        std::vector<double> m(count);
        for (int i = 0; i < count; ++i) {
            x0[i] = Vec3(0.3, -0.2, 1.0) + (0.01 * i) * line;
            x[i] = Vec3(u(rng), u(rng), u(rng)) * 0.02 + Vec3(5.0, 1.0, -2.0);
            m[i] = 0.001 * (1.0 + u(rng) * 0.5);
        }
        double mass = 0.0;
        Vec3 c = Vec3::Zero(), c0 = Vec3::Zero();
        for (int i = 0; i < count; ++i) mass += m[i], c += m[i] * x[i], c0 += m[i] * x0[i];
        c /= mass;
        c0 /= mass;
        Mat3 a = Mat3::Zero();
        for (int i = 0; i < count; ++i) a += m[i] * (x[i] - c) * (x0[i] - c0).transpose();
        const Mat3 fast = detail::csmRotation(a);
        const Mat3 reference = rotationBySvd(a);
        // The goals are R (x0 - c0): along the line, where the rotation about it is free.
        // Equal to rounding, and as orthonormal as the SVD's: both come from
        // Quat::FromTwoVectors, whose rounding grows where u_1 is nearly -v_1 (a region
        // turned half round).
        for (int i = 0; i < count; ++i)
            EXPECT_LT((fast * (x0[i] - c0) - reference * (x0[i] - c0)).norm(), 1e-12 * (x0[i] - c0).norm()) << trial;
        const double off_fast = (fast * fast.transpose() - Mat3::Identity()).norm();
        const double off_reference = (reference * reference.transpose() - Mat3::Identity()).norm();
        EXPECT_LT(off_fast, 10.0 * off_reference + 1e-13) << trial;
    }
}

// Everything else still goes through the SVD: the same bits.
TEST(StepKernels, CsmRotationOfFullRankMatricesIsTheSvds) {
    std::mt19937_64 rng(11);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    for (int trial = 0; trial < 2000; ++trial) {
        Mat3 a;
        for (int k = 0; k < 9; ++k) a(k / 3, k % 3) = u(rng);
        if (trial % 3 == 1) a.col(2) = 1e-6 * a.col(2);                                    // nearly planar
        if (trial % 3 == 2) a = a.col(0) * Vec3(u(rng), u(rng), u(rng)).transpose() + 1e-11 * a;  // near the rank-1 tolerance
        const Mat3 fast = detail::csmRotation(a);
        const Mat3 reference = rotationBySvd(a);
        EXPECT_TRUE(fast == reference) << trial << "\n" << a;
    }
    EXPECT_TRUE(detail::csmRotation(Mat3::Zero()) == Mat3::Identity());
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
