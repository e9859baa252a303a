// Chain shape matching kernel: rigid invariance, straightening, mass weighting, the O(1)
// per-region moment sums against a brute-force fit, and degenerate (collinear) regions.
#include "string/shape_matching.hpp"
#include "base/thread_pool.hpp"

#include <Eigen/Eigenvalues>
#include <Eigen/SVD>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <memory>
#include <random>
#include <utility>
#include <vector>

namespace {

using tearables::Mat3;
using tearables::Quat;
using tearables::Vec3;
using tearables::detail::chainShapeMatchingGoals;
using tearables::detail::csmRotation;
using tearables::detail::CsmScratch;
using tearables::detail::straightChainShapeMatchingGoals;

constexpr double kPi = 3.14159265358979323846;

Vec3 randomUnit(std::mt19937_64& rng) {
    std::normal_distribution<double> g(0.0, 1.0);
    Vec3 v;
    do v = Vec3(g(rng), g(rng), g(rng));
    while (v.norm() < 1e-3);
    return v.normalized();
}

Quat randomRotation(std::mt19937_64& rng) {
    std::normal_distribution<double> g(0.0, 1.0);
    Quat q(g(rng), g(rng), g(rng), g(rng));
    q.normalize();
    return q;
}

/// A random walk of n particles with segments of length 0.1 .. 1 starting at `start`.
std::vector<Vec3> randomChain(std::mt19937_64& rng, std::size_t n, const Vec3& start) {
    std::uniform_real_distribution<double> len(0.1, 1.0);
    std::vector<Vec3> p(n);
    if (n == 0) return p;
    p[0] = start;
    for (std::size_t i = 1; i < n; ++i) p[i] = p[i - 1] + len(rng) * randomUnit(rng);
    return p;
}

std::vector<double> randomMasses(std::mt19937_64& rng, std::size_t n) {
    std::uniform_real_distribution<double> u(0.5, 2.0);
    std::vector<double> m(n);
    for (double& v : m) v = u(rng);
    return m;
}

std::vector<Vec3> goalsOf(const std::vector<Vec3>& x, const std::vector<Vec3>& rest, const std::vector<double>& m,
                          int w) {
    CsmScratch scratch;
    std::vector<Vec3> g(x.size(), Vec3::Constant(std::nan("")));
    chainShapeMatchingGoals(x.data(), rest.data(), m.data(), 0, x.size() - 1, w, g.data(), scratch);
    return g;
}

/// Optimal rotation by Horn's quaternion method (independent of the kernel's SVD): the
/// unit quaternion maximising sum m (x-c) . R (x0-c0) is the top eigenvector of N(S),
/// S = A^T = sum m (x0-c0)(x-c)^T.
Mat3 hornRotation(const Mat3& a) {
    const Mat3 s = a.transpose();
    const double sxx = s(0, 0), sxy = s(0, 1), sxz = s(0, 2);
    const double syx = s(1, 0), syy = s(1, 1), syz = s(1, 2);
    const double szx = s(2, 0), szy = s(2, 1), szz = s(2, 2);
    Eigen::Matrix4d nm;
    nm << sxx + syy + szz, syz - szy, szx - sxz, sxy - syx,  //
        syz - szy, sxx - syy - szz, sxy + syx, szx + sxz,    //
        szx - sxz, sxy + syx, -sxx + syy - szz, syz + szy,   //
        sxy - syx, szx + sxz, syz + szy, -sxx - syy + szz;
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix4d> es(nm);
    const Eigen::Vector4d q = es.eigenvectors().col(3);  // largest eigenvalue
    return Quat(q(0), q(1), q(2), q(3)).normalized().toRotationMatrix();
}

/// Brute force: every region fitted from scratch with per-region masses m_i / N_i, goals
/// averaged over the regions containing each particle. Writes goal[first..last].
void bruteForceGoals(const std::vector<Vec3>& x, const std::vector<Vec3>& rest, const std::vector<double>& mass,
                     std::size_t first, std::size_t last, int w, std::vector<Vec3>& goal) {
    const long f = static_cast<long>(first), l = static_cast<long>(last);
    const auto lo = [&](long k) { return std::max(f, k - w); };
    const auto hi = [&](long k) { return std::min(l, k + w); };
    std::vector<Vec3> sum(x.size(), Vec3::Zero());
    std::vector<int> count(x.size(), 0);
    for (long k = f; k <= l; ++k) {
        double m = 0.0;
        Vec3 c = Vec3::Zero(), c0 = Vec3::Zero();
        for (long i = lo(k); i <= hi(k); ++i) {
            const double mi = mass[i] / static_cast<double>(hi(i) - lo(i) + 1);
            m += mi;
            c += mi * x[i];
            c0 += mi * rest[i];
        }
        c /= m;
        c0 /= m;
        Mat3 a = Mat3::Zero();
        for (long i = lo(k); i <= hi(k); ++i) {
            const double mi = mass[i] / static_cast<double>(hi(i) - lo(i) + 1);
            a += mi * (x[i] - c) * (rest[i] - c0).transpose();
        }
        const Mat3 r = hornRotation(a);
        for (long i = lo(k); i <= hi(k); ++i) {
            sum[i] += r * (rest[i] - c0) + c;
            ++count[i];
        }
    }
    for (long i = f; i <= l; ++i) goal[i] = sum[i] / count[i];
}

double bendAngle(const Vec3& a, const Vec3& b, const Vec3& c) {
    const Vec3 u = (b - a).normalized(), v = (c - b).normalized();
    return std::atan2(u.cross(v).norm(), u.dot(v));
}

/// Rest: n particles on the x axis, spacing 1. Current: bent by `angle` about z at `joint`.
void bentChain(std::size_t n, std::size_t joint, double angle, std::vector<Vec3>& rest, std::vector<Vec3>& x) {
    rest.resize(n);
    x.resize(n);
    const Mat3 r = Eigen::AngleAxisd(angle, Vec3::UnitZ()).toRotationMatrix();
    for (std::size_t i = 0; i < n; ++i) {
        rest[i] = Vec3(static_cast<double>(i), 0.0, 0.0);
        x[i] = i <= joint ? rest[i] : rest[joint] + r * (rest[i] - rest[joint]);
    }
}

}  // namespace

TEST(ChainShapeMatching, RigidMotionGivesGoalsEqualToPositions) {
    std::mt19937_64 rng(11);
    std::uniform_real_distribution<double> u(-10.0, 10.0);
    for (std::size_t n : {1, 2, 3, 4, 7, 20, 61, 200}) {
        for (int w : {1, 2, 3, 5, 9}) {
            for (int trial = 0; trial < 6; ++trial) {
                std::vector<Vec3> rest = randomChain(rng, n, Vec3(u(rng), u(rng), u(rng)));
                if (trial == 0)  // straight rest shape: every region is rank 1
                    for (std::size_t i = 0; i < n; ++i) rest[i] = Vec3(0.3 * i, 0.0, 1.0);
                const std::vector<double> m = randomMasses(rng, n);
                const Mat3 r = randomRotation(rng).toRotationMatrix();
                const Vec3 t(u(rng), u(rng), u(rng));
                std::vector<Vec3> x(n);
                for (std::size_t i = 0; i < n; ++i) x[i] = r * rest[i] + t;
                const std::vector<Vec3> g = goalsOf(x, rest, m, w);
                for (std::size_t i = 0; i < n; ++i)
                    ASSERT_LT((g[i] - x[i]).norm(), 1e-12) << "n=" << n << " w=" << w << " trial=" << trial << " i=" << i;
            }
        }
    }
}

TEST(ChainShapeMatching, BentChainGoalsAreStraighter) {
    std::vector<Vec3> rest, x;
    bentChain(11, 5, kPi / 3.0, rest, x);
    const std::vector<double> m(11, 1.0);
    for (int w = 1; w <= 4; ++w) {
        const std::vector<Vec3> g = goalsOf(x, rest, m, w);
        const double before = bendAngle(x[4], x[5], x[6]);
        const double after = bendAngle(g[4], g[5], g[6]);
        EXPECT_NEAR(before, kPi / 3.0, 1e-12);
        EXPECT_LT(after, 0.9 * before) << "w=" << w;
        // The chord across the joint lengthens as the chain straightens.
        EXPECT_GT((g[6] - g[4]).norm(), (x[6] - x[4]).norm() + 1e-3) << "w=" << w;
        // Particles none of whose regions holds the joint with both its neighbours stay put.
        const std::size_t reach = 2 * static_cast<std::size_t>(w);
        for (std::size_t i = 0; i < 11; ++i) {
            if (i + reach < 6 || i > 4 + reach) {
                EXPECT_LT((g[i] - x[i]).norm(), 1e-12) << "w=" << w << " i=" << i;
            }
        }
        // A bend in the x-y plane keeps the goals in that plane.
        for (const Vec3& p : g) EXPECT_NEAR(p.z(), 0.0, 1e-12);
    }
}

TEST(ChainShapeMatching, TranslationInvariance) {
    std::mt19937_64 rng(5);
    for (int w : {1, 2, 4}) {
        const std::size_t n = 40;
        const std::vector<Vec3> rest = randomChain(rng, n, Vec3::Zero());
        std::vector<Vec3> x = randomChain(rng, n, Vec3(1.0, 2.0, 3.0));
        const std::vector<double> m = randomMasses(rng, n);
        const std::vector<Vec3> g = goalsOf(x, rest, m, w);
        const Vec3 t(1234.5, -987.25, 3000.125), t0(-5000.0, 250.5, 77.0);
        std::vector<Vec3> xs(n), rs(n);
        for (std::size_t i = 0; i < n; ++i) {
            xs[i] = x[i] + t;
            rs[i] = rest[i] + t0;
        }
        const std::vector<Vec3> gs = goalsOf(xs, rs, m, w);
        for (std::size_t i = 0; i < n; ++i) EXPECT_LT((gs[i] - t - g[i]).norm(), 1e-10) << "w=" << w << " i=" << i;
    }
}

TEST(ChainShapeMatching, HeavierParticleMovesLessTowardItsGoal) {
    // A colliding particle is made 3x heavier (Strings Sec. 6) so that shape matching
    // barely moves it. Checked where the motion is large: the bent joint itself, and the
    // last particle of a chain bent next to its end.
    std::vector<Vec3> rest, x;
    for (int w = 1; w <= 4; ++w) {
        for (const auto& [joint, p] : {std::pair<std::size_t, std::size_t>{5, 5}, {9, 10}, {1, 0}}) {
            for (double angle : {0.05, 0.5, kPi / 3.0, 2.5}) {
                bentChain(11, joint, angle, rest, x);
                std::vector<double> m(11, 1.0);
                const double light = (goalsOf(x, rest, m, w)[p] - x[p]).norm();
                m[p] = 3.0;
                const double heavy = (goalsOf(x, rest, m, w)[p] - x[p]).norm();
                EXPECT_GT(light, 1e-4) << "w=" << w << " p=" << p << " angle=" << angle;
                EXPECT_LT(heavy, 0.9 * light) << "w=" << w << " p=" << p << " angle=" << angle;
            }
        }
    }
}

TEST(ChainShapeMatching, HeavierParticleIsFittedCloserInEveryRegion) {
    // Within each region the fit is a mass-weighted least-squares rigid match, so a heavier
    // particle's own residual |g_ik - x_i| shrinks in every region holding it. (Its blended
    // displacement, the mean of the residual vectors over its regions, usually shrinks too,
    // but not always: next to a joint the vectors partly cancel, and reweighting can change
    // the cancellation, e.g. w = 3, particle 4 of an 11-particle chain bent at 5.)
    std::vector<Vec3> rest, x;
    bentChain(11, 5, 0.7, rest, x);
    for (int w = 1; w <= 4; ++w) {
        for (std::size_t p = 0; p < 11; ++p) {
            std::vector<double> residual[2];
            for (int heavy = 0; heavy < 2; ++heavy) {
                std::vector<double> m(11, 1.0);
                if (heavy) m[p] = 3.0;
                CsmScratch scratch;
                std::vector<Vec3> g(11);
                chainShapeMatchingGoals(x.data(), rest.data(), m.data(), 0, 10, w, g.data(), scratch);
                for (std::size_t k = 0; k < 11; ++k) {
                    if (k + w < p || k > p + w) continue;  // region k does not hold p
                    const Vec3 gk = scratch.rotation[k] * (rest[p] - scratch.rest_centroid[k]) + scratch.centroid[k];
                    residual[heavy].push_back((gk - x[p]).norm());
                }
            }
            for (std::size_t r = 0; r < residual[0].size(); ++r) {
                if (residual[0][r] < 1e-9) continue;  // a rigid region: nothing to shrink
                EXPECT_LT(residual[1][r], residual[0][r]) << "w=" << w << " p=" << p << " region #" << r;
            }
        }
    }
}

TEST(ChainShapeMatching, GoalsConserveLinearMomentum) {
    std::mt19937_64 rng(3);
    for (int w : {1, 2, 3, 7}) {
        for (std::size_t n : {2, 3, 9, 50}) {
            const std::vector<Vec3> rest = randomChain(rng, n, Vec3::Zero());
            const std::vector<Vec3> x = randomChain(rng, n, Vec3(0.5, 0.0, -1.0));
            const std::vector<double> m = randomMasses(rng, n);
            const std::vector<Vec3> g = goalsOf(x, rest, m, w);
            Vec3 px = Vec3::Zero(), pg = Vec3::Zero();
            for (std::size_t i = 0; i < n; ++i) {
                px += m[i] * x[i];
                pg += m[i] * g[i];
            }
            EXPECT_LT((pg - px).norm(), 1e-11 * n) << "w=" << w << " n=" << n;
        }
    }
}

TEST(ChainShapeMatching, MomentSumsMatchBruteForceOnPieces) {
    std::mt19937_64 rng(2024);
    std::uniform_int_distribution<std::size_t> len(1, 200), pad(0, 17);
    CsmScratch scratch;  // reused across calls of different sizes on purpose
    const Vec3 sentinel(1e300, -1e300, 42.0);
    for (int trial = 0; trial < 120; ++trial) {
        const int w = 1 + trial % 8;
        const std::size_t n = trial < 8 ? static_cast<std::size_t>(1 + trial) : len(rng);
        const std::size_t before = pad(rng), after = pad(rng);
        const std::size_t total = before + n + after;
        const std::vector<Vec3> rest = randomChain(rng, total, Vec3(3.0, -2.0, 1.0));
        std::vector<Vec3> x = randomChain(rng, total, Vec3(-1.0, 4.0, 0.0));
        if (trial % 3 == 0)  // small deformations of the rest shape too, not only random shapes
            for (std::size_t i = 0; i < total; ++i) x[i] = rest[i] + 0.05 * randomUnit(rng);
        const std::vector<double> m = randomMasses(rng, total);
        const std::size_t first = before, last = before + n - 1;
        std::vector<Vec3> goal(total, sentinel), expected(total, sentinel);
        chainShapeMatchingGoals(x.data(), rest.data(), m.data(), first, last, w, goal.data(), scratch);
        bruteForceGoals(x, rest, m, first, last, w, expected);
        for (std::size_t i = 0; i < total; ++i) {
            if (i < first || i > last) {
                ASSERT_EQ(goal[i], sentinel) << "wrote outside the piece at " << i;
                continue;
            }
            ASSERT_TRUE(goal[i].allFinite());
            ASSERT_LT((goal[i] - expected[i]).norm(), 1e-9)
                << "trial=" << trial << " n=" << n << " w=" << w << " first=" << first << " i=" << i;
        }
    }
}

TEST(ChainShapeMatching, ScratchIsNotReallocatedWhenLargeEnough) {
    std::mt19937_64 rng(9);
    const std::vector<Vec3> rest = randomChain(rng, 100, Vec3::Zero());
    const std::vector<Vec3> x = randomChain(rng, 100, Vec3::Zero());
    const std::vector<double> m(100, 1.0);
    std::vector<Vec3> g(100);
    CsmScratch scratch;
    chainShapeMatchingGoals(x.data(), rest.data(), m.data(), 0, 99, 3, g.data(), scratch);
    const void* p0 = scratch.work.at(0).prefix.data();
    const void* p1 = scratch.rotation.data();
    chainShapeMatchingGoals(x.data(), rest.data(), m.data(), 10, 59, 2, g.data(), scratch);
    chainShapeMatchingGoals(x.data(), rest.data(), m.data(), 0, 99, 8, g.data(), scratch);
    EXPECT_EQ(scratch.work.at(0).prefix.data(), p0);
    EXPECT_EQ(scratch.rotation.data(), p1);
}

TEST(ChainShapeMatching, LongPiecesDoneInChunksMatchBruteForce) {
    // A long piece is done in chunks of about kCsmChunkParticles, each with the regions and
    // blocks beyond its ends computed again: the goals must be those of the brute-force
    // fit everywhere (chunk ends included), the regions reported must be every region's,
    // and the pool must give the same bits as one thread.
    using tearables::detail::kCsmChunkParticles;
    std::mt19937_64 rng(77);
    tearables::detail::ThreadPool pool;
    pool.setThreads(2);
    for (int w : {1, 2, 5, 8}) {
        for (std::size_t n : {kCsmChunkParticles - 1, kCsmChunkParticles + 1, 3 * kCsmChunkParticles + 7, std::size_t{9000}}) {
            const std::vector<Vec3> rest = randomChain(rng, n, Vec3(1.0, 2.0, 3.0));
            std::vector<Vec3> x = randomChain(rng, n, Vec3::Zero());
            for (std::size_t i = 0; i < n; i += 2) x[i] = rest[i] + 0.05 * randomUnit(rng);  // mixed shapes
            const std::vector<double> m = randomMasses(rng, n);
            std::vector<Vec3> serial(n), threaded(n), expected(n);
            CsmScratch scratch;
            chainShapeMatchingGoals(x.data(), rest.data(), m.data(), 0, n - 1, w, serial.data(), scratch);
            bruteForceGoals(x, rest, m, 0, n - 1, w, expected);
            for (std::size_t i = 0; i < n; ++i)
                ASSERT_LT((serial[i] - expected[i]).norm(), 1e-9) << "n=" << n << " w=" << w << " i=" << i;
            // Region k's reported fit gives its own centre particle the goal the brute force
            // gives it in region k: checked through the fitted rotation's orthogonality and
            // the centroid, which is the region's per-region-mass mean.
            for (std::size_t k = 0; k < n; ++k) {
                const std::size_t lo = k > static_cast<std::size_t>(w) ? k - w : 0, hi = std::min(n - 1, k + w);
                Vec3 c = Vec3::Zero();
                double mass = 0.0;
                for (std::size_t i = lo; i <= hi; ++i) {
                    const double share = m[i] / static_cast<double>(std::min(n - 1, i + w) - (i > static_cast<std::size_t>(w) ? i - w : 0) + 1);
                    c += share * x[i];
                    mass += share;
                }
                ASSERT_LT((scratch.centroid[k] - c / mass).norm(), 1e-9) << "n=" << n << " w=" << w << " k=" << k;
                ASSERT_LT((scratch.rotation[k].transpose() * scratch.rotation[k] - Mat3::Identity()).norm(), 1e-9);
            }
            CsmScratch other;
            chainShapeMatchingGoals(x.data(), rest.data(), m.data(), 0, n - 1, w, threaded.data(), other, &pool);
            for (std::size_t i = 0; i < n; ++i) ASSERT_EQ(threaded[i], serial[i]) << "n=" << n << " w=" << w << " i=" << i;
        }
    }
}

TEST(ChainShapeMatching, StraightRestKernelGivesTheGeneralKernelsGoals) {
    // Straight rest shapes (uneven segments, along a random direction, away from the
    // origin): the straight kernel's goals are the general kernel's to rounding, for
    // random current shapes, small deformations of the rest shape, a chain collapsed to a
    // point (A = 0: the identity) and one reversed along the line (R v = -v); it writes
    // only the piece, and gives the same bits on the pool as on one thread.
    using tearables::detail::kCsmChunkParticles;
    std::mt19937_64 rng(31);
    std::uniform_real_distribution<double> len(0.005, 0.02);
    tearables::detail::ThreadPool pool;
    pool.setThreads(2);
    const Vec3 sentinel(1e300, -1e300, 42.0);
    int trial = 0;
    for (std::size_t n : {std::size_t{3}, std::size_t{4}, std::size_t{11}, std::size_t{200}, kCsmChunkParticles + 1,
                          std::size_t{5000}}) {
        for (int w = 1; w <= 8; ++w, ++trial) {
            const Vec3 v = randomUnit(rng);
            const std::size_t before = 3, total = n + 6;
            std::vector<Vec3> rest(total);
            rest[0] = Vec3(2.0, -1.0, 0.5);
            for (std::size_t i = 1; i < total; ++i) rest[i] = rest[i - 1] + len(rng) * v;
            std::vector<Vec3> x;
            switch (trial % 4) {
                case 0: x = randomChain(rng, total, Vec3(0.3, 0.2, -0.1)); break;
                case 1:
                    x = rest;
                    for (Vec3& p : x) p += 0.002 * randomUnit(rng);
                    break;
                case 2: x.assign(total, Vec3(1.0, 1.0, 1.0)); break;
                default:
                    x = rest;
                    std::reverse(x.begin(), x.end());
                    break;
            }
            const std::vector<double> m = randomMasses(rng, total);
            std::vector<Vec3> general(total, sentinel), straight(total, sentinel), threaded(total, sentinel);
            CsmScratch a, b, c;
            chainShapeMatchingGoals(x.data(), rest.data(), m.data(), before, before + n - 1, w, general.data(), a);
            straightChainShapeMatchingGoals(x.data(), rest.data(), m.data(), before, before + n - 1, w, v, straight.data(), b);
            straightChainShapeMatchingGoals(x.data(), rest.data(), m.data(), before, before + n - 1, w, v, threaded.data(), c,
                                            &pool);
            for (std::size_t i = 0; i < total; ++i) {
                if (i < before || i >= before + n) {
                    ASSERT_EQ(straight[i], sentinel) << "wrote outside the piece at " << i;
                    continue;
                }
                ASSERT_TRUE(straight[i].allFinite());
                // Reversed, the general kernel turns a half turn through Eigen's
                // FromTwoVectors, good to ~1e-8 of the offsets; the straight one's R v = -v
                // is exact.
                const double tolerance = trial % 4 == 3 ? 1e-9 : 1e-12;
                ASSERT_LT((straight[i] - general[i]).norm(), tolerance) << "trial=" << trial << " n=" << n << " w=" << w << " i=" << i;
                ASSERT_EQ(threaded[i], straight[i]) << "n=" << n << " w=" << w << " i=" << i;
            }
        }
    }
    EXPECT_THROW(straightChainShapeMatchingGoals(nullptr, nullptr, nullptr, 0, 5, 0, Vec3::UnitX(), nullptr,
                                                 *std::make_unique<CsmScratch>()),
                 tearables::InvalidInput);
    EXPECT_THROW(straightChainShapeMatchingGoals(nullptr, nullptr, nullptr, 0, 5, 9, Vec3::UnitX(), nullptr,
                                                 *std::make_unique<CsmScratch>()),
                 tearables::InvalidInput);
}

TEST(ChainShapeMatching, StretchedStraightChainGivesFiniteGoalsOnTheLine) {
    // Rest straight along x; current straight and stretched 1.5x along x, or along an
    // arbitrary direction. Every region is collinear (rank-1 A): the rotation about the line
    // is undetermined and the kernel takes the one closest to identity.
    std::mt19937_64 rng(17);
    const std::size_t n = 30;
    std::vector<Vec3> rest(n);
    for (std::size_t i = 0; i < n; ++i) rest[i] = Vec3(0.1 * i, 0.0, 0.0);
    const std::vector<double> m(n, 0.01);
    for (int dirCase = 0; dirCase < 4; ++dirCase) {
        const Vec3 dir = dirCase == 0 ? Vec3::UnitX() : randomUnit(rng);
        const Vec3 origin(0.5, -0.25, 2.0);
        std::vector<Vec3> x(n);
        for (std::size_t i = 0; i < n; ++i) x[i] = origin + 0.15 * i * dir;
        for (int w : {1, 2, 5}) {
            CsmScratch scratch;
            std::vector<Vec3> g(n);
            chainShapeMatchingGoals(x.data(), rest.data(), m.data(), 0, n - 1, w, g.data(), scratch);
            for (std::size_t i = 0; i < n; ++i) {
                ASSERT_TRUE(g[i].allFinite()) << "i=" << i;
                const Vec3 rel = g[i] - origin;
                EXPECT_LT((rel - rel.dot(dir) * dir).norm(), 1e-12) << "goal off the line, i=" << i;
                // Each rotation takes the rest direction to the current one.
                EXPECT_LT((scratch.rotation[i] * Vec3::UnitX() - dir).norm(), 1e-12);
                EXPECT_NEAR(scratch.rotation[i].determinant(), 1.0, 1e-12);
            }
            if (dirCase == 0) {  // aligned: the closest rotation to identity is identity
                for (std::size_t k = 0; k < n; ++k)
                    EXPECT_LT((scratch.rotation[k] - Mat3::Identity()).norm(), 1e-12) << "k=" << k;
            } else {  // the smallest rotation: about x cross dir
                const Vec3 axis = Vec3::UnitX().cross(dir).normalized();
                for (std::size_t k = 0; k < n; ++k) EXPECT_LT((scratch.rotation[k] * axis - axis).norm(), 1e-12);
            }
            // The goals undo part of the stretch.
            EXPECT_LT((g[n - 1] - g[0]).norm(), (x[n - 1] - x[0]).norm());
        }
    }
}

TEST(ChainShapeMatching, CurvedRestPulledStraightKeepsItsPlane) {
    // Rest: a zigzag in the x-y plane; current: straight along x. A has rank 1; of the
    // optimal rotations the one closest to identity turns about z only, so the goals stay
    // in the rest plane (any other choice would tilt them out of it).
    const std::size_t n = 21;
    std::vector<Vec3> rest(n), x(n);
    for (std::size_t i = 0; i < n; ++i) {
        rest[i] = Vec3(0.1 * i + 0.003 * i * i, (i % 2 ? 0.04 : -0.04) + 0.002 * i, 0.0);
        x[i] = Vec3(0.12 * i, 0.0, 0.0);
    }
    std::vector<double> m(n, 1.0);
    m[7] = 3.0;
    for (int w : {1, 2, 4}) {
        CsmScratch scratch;
        std::vector<Vec3> g(n);
        chainShapeMatchingGoals(x.data(), rest.data(), m.data(), 0, n - 1, w, g.data(), scratch);
        for (std::size_t i = 0; i < n; ++i) {
            ASSERT_TRUE(g[i].allFinite());
            EXPECT_NEAR(g[i].z(), 0.0, 1e-12) << "w=" << w << " i=" << i;
            EXPECT_LT((scratch.rotation[i] * Vec3::UnitZ() - Vec3::UnitZ()).norm(), 1e-12);
        }
        // The zigzag comes back: goals leave the x axis.
        double off = 0.0;
        for (const Vec3& p : g) off = std::max(off, std::abs(p.y()));
        EXPECT_GT(off, 0.01) << "w=" << w;
    }
}

TEST(ChainShapeMatching, CoincidentParticlesAndTinyPieces) {
    const std::vector<Vec3> rest = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(1, 1, 0), Vec3(1, 1, 1)};
    const std::vector<double> m(4, 1.0);
    // All current particles at one point: A = 0, rotation identity, goals = rest shape
    // about the common centroid.
    const std::vector<Vec3> x(4, Vec3(2.0, 3.0, 4.0));
    for (int w : {1, 2, 3}) {
        const std::vector<Vec3> g = goalsOf(x, rest, m, w);
        for (const Vec3& p : g) EXPECT_TRUE(p.allFinite());
    }
    // One-particle piece: its goal is itself. Two-particle piece: the rest length returns.
    CsmScratch scratch;
    std::vector<Vec3> xs = {Vec3(5, 5, 5), Vec3(5, 5, 8)}, g(2);
    chainShapeMatchingGoals(xs.data(), rest.data(), m.data(), 1, 1, 3, g.data(), scratch);
    EXPECT_EQ(g[1], xs[1]);
    chainShapeMatchingGoals(xs.data(), rest.data(), m.data(), 0, 1, 1, g.data(), scratch);
    EXPECT_NEAR((g[1] - g[0]).norm(), 1.0, 1e-12);
    EXPECT_LT((0.5 * (g[0] + g[1]) - Vec3(5, 5, 6.5)).norm(), 1e-12);
    EXPECT_NEAR((g[1] - g[0]).normalized().dot(Vec3::UnitZ()), 1.0, 1e-12);
}

TEST(ChainShapeMatching, RejectsInvalidArguments) {
    const std::vector<Vec3> p(3, Vec3::Zero());
    const std::vector<double> m(3, 1.0);
    std::vector<Vec3> g(3);
    CsmScratch scratch;
    EXPECT_THROW(chainShapeMatchingGoals(p.data(), p.data(), m.data(), 0, 2, 0, g.data(), scratch),
                 tearables::InvalidInput);
    EXPECT_THROW(chainShapeMatchingGoals(p.data(), p.data(), m.data(), 2, 1, 1, g.data(), scratch),
                 tearables::InvalidInput);
}

namespace {

/// The rotation csmRotation documents, from Eigen's JacobiSVD (A = U S V^T): R = U diag(1,
/// 1, det(U V^T)) V^T, or for rank 1 (sigma_2 <= 1e-12 sigma_1) the smallest rotation taking
/// v_1 to u_1. `condition` = sigma_1 / (sigma_2 + det-signed sigma_3), the sensitivity of
/// R to a relative change of A (infinite where R is not unique).
struct SvdReference {
    Mat3 r;
    Vec3 u1, v1;
    bool rank_one = false;
    double condition = 0.0;
};

SvdReference svdReference(const Mat3& a) {
    const Eigen::JacobiSVD<Mat3> svd(a, Eigen::ComputeFullU | Eigen::ComputeFullV);
    const Vec3 s = svd.singularValues();
    SvdReference ref;
    ref.u1 = svd.matrixU().col(0);
    ref.v1 = svd.matrixV().col(0);
    const double sign = svd.matrixU().determinant() * svd.matrixV().determinant() < 0.0 ? -1.0 : 1.0;
    ref.condition = s(0) / (s(1) + sign * s(2));
    ref.rank_one = s(1) <= 1e-12 * s(0);
    if (ref.rank_one) {
        ref.r = Quat::FromTwoVectors(ref.v1, ref.u1).normalized().toRotationMatrix();
    } else {
        Mat3 u = svd.matrixU();
        u.col(2) *= sign;
        ref.r = u * svd.matrixV().transpose();
    }
    return ref;
}

/// U diag(s) V^T with random rotations U, V (s(2) < 0: a reflected A).
Mat3 withSingularValues(std::mt19937_64& rng, const Vec3& s) {
    return randomRotation(rng).toRotationMatrix() * s.asDiagonal() * randomRotation(rng).toRotationMatrix().transpose();
}

}  // namespace

// csmRotation's cheap paths (a power step for rank 1, a scaled Newton iteration for the
// polar factor, JacobiSVD only where neither is sure) agree with the SVD's rotation to
// rounding times the problem's own condition number, on matrices of every kind a region can
// give, at any scale.
TEST(ChainShapeMatching, RotationAgreesWithJacobiSvd) {
    std::mt19937_64 rng(77);
    std::uniform_real_distribution<double> u(-1.0, 1.0), unit(0.0, 1.0);
    const auto pow10 = [&](double lo, double hi) { return std::pow(10.0, lo + (hi - lo) * unit(rng)); };
    const auto sign = [&] { return u(rng) < 0.0 ? -1.0 : 1.0; };
    const std::vector<std::pair<const char*, std::function<Mat3()>>> kinds = {
        {"random entries",
         [&] {
             Mat3 a;
             for (int i = 0; i < 9; ++i) a(i) = u(rng);
             return a;
         }},
        {"well conditioned", [&] { return withSingularValues(rng, Vec3(1.0, 0.4 + 0.6 * unit(rng), sign() * (0.1 + 0.3 * unit(rng)))); }},
        {"planar", [&] { return withSingularValues(rng, Vec3(1.0, unit(rng), 0.0)); }},
        {"nearly planar", [&] { return withSingularValues(rng, Vec3(1.0, 0.01 + unit(rng), sign() * pow10(-15, -2))); }},
        {"nearly rank 1",
         [&] {
             const double s2 = pow10(-11.5, -1);
             return withSingularValues(rng, Vec3(1.0, s2, s2 * u(rng)));
         }},
        {"reflected, s3 ~ s2",
         [&] {
             const double s2 = pow10(-5, 0);
             return withSingularValues(rng, Vec3(1.0, s2, -s2 * (1.0 - pow10(-8, -1))));
         }},
        {"rank 1", [&] { return Mat3(randomUnit(rng) * randomUnit(rng).transpose()); }},
        {"rank 1 plus rounding", [&] { return withSingularValues(rng, Vec3(1.0, pow10(-17, -13), 0.0)); }},
        {"straight rest along x",
         [&] {
             Mat3 a = Mat3::Zero();
             a.col(0) = randomUnit(rng);
             return a;
         }},
    };
    for (const auto& [name, make] : kinds) {
        for (int trial = 0; trial < 4000; ++trial) {
            const double scale = std::pow(10.0, static_cast<double>(trial % 7) * 50.0 - 150.0);  // 1e-150 .. 1e150
            const Mat3 a = scale * make();
            const Mat3 r = csmRotation(a);
            const SvdReference ref = svdReference(a);
            ASSERT_TRUE(r.allFinite()) << name << " trial " << trial;
            ASSERT_LT((r.transpose() * r - Mat3::Identity()).norm(), 1e-14) << name << " trial " << trial;
            ASSERT_NEAR(r.determinant(), 1.0, 1e-14) << name << " trial " << trial;
            if (ref.rank_one) {
                // R v_1 = u_1, and R itself. Rounding in u_1 and v_1 is amplified by
                // 1 / sqrt(1 + u_1.v_1) near a half turn, where the smallest rotation's axis
                // becomes anyone's (Eigen's FromTwoVectors picks one below 1 + u.v = 1e-12).
                const double c = ref.v1.dot(ref.u1);
                if (c < -1.0 + 1e-10) continue;
                const double tolerance = 1e-14 / std::sqrt(1.0 + c);
                ASSERT_LT((r * ref.v1 - ref.u1).norm(), tolerance) << name << " trial " << trial << " u1.v1 " << c;
                ASSERT_LT((r - ref.r).norm(), tolerance) << name << " trial " << trial << " u1.v1 " << c;
                continue;
            }
            // Well-conditioned A: near machine precision; otherwise within rounding of A
            // times the condition number (the SVD's own R is no more accurate than that).
            const double tolerance = ref.condition < 1e3 ? 1e-12 : 2e-14 * ref.condition;
            ASSERT_LT((r - ref.r).norm(), tolerance) << name << " trial " << trial << " condition " << ref.condition;
        }
    }
}

// The polar factor exactly: A = R0 S with S symmetric positive definite gives R0, also when
// S is nearly singular (a nearly planar or nearly collinear region, turned by R0).
TEST(ChainShapeMatching, RotationOfRotatedSymmetricMatrixIsTheRotation) {
    std::mt19937_64 rng(78);
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    for (int trial = 0; trial < 3000; ++trial) {
        const double s3 = std::pow(10.0, -10.0 * unit(rng)), s2 = s3 + (1.0 - s3) * unit(rng);
        const Mat3 q = randomRotation(rng).toRotationMatrix();
        const Mat3 spd = q * Vec3(1.0, s2, s3).asDiagonal() * q.transpose();
        const Mat3 r0 = randomRotation(rng).toRotationMatrix();
        const Mat3 r = csmRotation(r0 * spd);
        EXPECT_LT((r - r0).norm(), 2e-14 * (1.0 + 1.0 / (s2 + s3))) << "trial " << trial << " s2 " << s2 << " s3 " << s3;
    }
}

TEST(ChainShapeMatching, RotationOfZeroOrNonFiniteMatrixIsIdentity) {
    EXPECT_EQ(csmRotation(Mat3::Zero()), Mat3::Identity());
    for (double bad : {std::nan(""), std::numeric_limits<double>::infinity()}) {
        Mat3 a = Mat3::Identity();
        a(1, 2) = bad;
        EXPECT_EQ(csmRotation(a), Mat3::Identity());
    }
}
