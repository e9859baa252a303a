// The O(n) kernels against dense solves: the scalar tridiagonal (both sweeps of its twisted
// factorisation, odd and even sizes) and the factorised 3x3-block chain with its pivots.
#include "linalg/block_tridiagonal.hpp"
#include "linalg/tridiagonal.hpp"

#include <Eigen/Dense>
#include <gtest/gtest.h>

#include <limits>
#include <random>

TEST(Tridiagonal, MatchesDenseSolveOnRandomDiagonallyDominantSystems) {
    std::mt19937_64 rng(7);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    for (int trial = 0; trial < 200; ++trial) {
        const int n = 1 + trial % 40;
        std::vector<double> diag(n), off(n, 0.0), rhs(n), scratch;
        Eigen::MatrixXd a = Eigen::MatrixXd::Zero(n, n);
        for (int i = 0; i + 1 < n; ++i) {
            off[i] = u(rng);
            a(i, i + 1) = a(i + 1, i) = off[i];
        }
        for (int i = 0; i < n; ++i) {
            diag[i] = std::abs(i > 0 ? off[i - 1] : 0.0) + std::abs(off[i]) + 0.01 + std::abs(u(rng));
            a(i, i) = diag[i];
            rhs[i] = u(rng);
        }
        const Eigen::VectorXd b = Eigen::Map<Eigen::VectorXd>(rhs.data(), n);
        const Eigen::VectorXd expected = a.ldlt().solve(b);
        off[n - 1] = std::numeric_limits<double>::quiet_NaN();  // unused: read, it would spread
        tearables::detail::solveSymmetricTridiagonal(diag, off, rhs, scratch);
        for (int i = 0; i < n; ++i) EXPECT_NEAR(rhs[i], expected[i], 1e-9 * (1.0 + std::abs(expected[i])));
    }
}

// The root-free Cholesky pivot of the factorised chain solve: backward stable on positive
// definite blocks, however stiff one direction is against the others (a contact's penalty
// on a particle's inertia), so its relative residual stays at rounding; a block that is not
// positive definite gives no finite answer.
TEST(Tridiagonal, PivotSolvesStiffPositiveDefiniteBlocksToRounding) {
    std::mt19937_64 rng(11);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    for (int trial = 0; trial < 500; ++trial) {
        const Eigen::Matrix3d q = Eigen::Matrix3d::NullaryExpr([&] { return u(rng); }).householderQr().householderQ();
        const double stiff = std::pow(10.0, trial % 10);  // up to 1e9 against 1
        const Eigen::Vector3d eigen(1.0 + std::abs(u(rng)), 1.0 + std::abs(u(rng)), stiff);
        const tearables::Mat3 a = q * eigen.asDiagonal() * q.transpose();
        const tearables::Vec3 b(u(rng), u(rng), u(rng));
        tearables::detail::Cholesky3 pivot;
        pivot.compute(a);
        const tearables::Vec3 x = pivot.solve(b);
        EXPECT_LT((a * x - b).norm(), 1e-13 * a.norm() * x.norm()) << "trial " << trial;
        const tearables::Mat3 xs = pivot.solve(tearables::Mat3(b * b.transpose()));
        for (int c = 0; c < 3; ++c) EXPECT_EQ(tearables::Vec3(xs.col(c)), pivot.solve(tearables::Vec3(b * b[c])));
    }
    tearables::detail::Cholesky3 pivot;
    pivot.compute((tearables::Mat3() << 1, 2, 0, 2, 1, 0, 0, 0, 1).finished());  // eigenvalues 3, -1, 1
    EXPECT_FALSE(pivot.solve(tearables::Vec3(1, 1, 1)).allFinite());
}

// The factorised chain (root-free Cholesky pivots) against a dense solve, and its columns
// solved together against each alone: the same operations, so the same bits.
TEST(Tridiagonal, FactorisedBlockChainMatchesDenseAndColumnsMatchSingleSolves) {
    using tearables::Mat3;
    using tearables::Vec3;
    std::mt19937_64 rng(5);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    for (int trial = 0; trial < 50; ++trial) {
        const std::size_t n = 2 + static_cast<std::size_t>(trial) % 30;
        std::vector<Mat3> diag(n), off(n, Mat3::Zero());
        Eigen::MatrixXd dense = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(3 * n), static_cast<Eigen::Index>(3 * n));
        for (std::size_t i = 0; i + 1 < n; ++i) {
            const Vec3 e = Vec3(u(rng), u(rng), u(rng)).normalized();
            off[i] = -(1e4 * e * e.transpose() + 10.0 * Mat3::Identity());  // a spring: stiff along e
            if (trial % 5 == 0 && i == n / 2) off[i].setZero();              // a broken segment
            dense.block<3, 3>(static_cast<Eigen::Index>(3 * i), static_cast<Eigen::Index>(3 * i + 3)) = off[i];
            dense.block<3, 3>(static_cast<Eigen::Index>(3 * i + 3), static_cast<Eigen::Index>(3 * i)) = off[i].transpose();
        }
        for (std::size_t i = 0; i < n; ++i) {
            diag[i] = Mat3::Identity();  // inertia
            if (i > 0) diag[i] -= off[i - 1];
            if (i + 1 < n) diag[i] -= off[i];
            dense.block<3, 3>(static_cast<Eigen::Index>(3 * i), static_cast<Eigen::Index>(3 * i)) = diag[i];
        }
        std::vector<tearables::detail::Cholesky3> factor(n);
        std::vector<Mat3> gain(n);
        std::vector<std::uint8_t> coupled(n);
        tearables::detail::factorBlockTridiagonal(n, diag.data(), off.data(), factor.data(), gain.data(), coupled.data());
        std::vector<Vec3> rhs(n);
        for (Vec3& r : rhs) r = Vec3(u(rng), u(rng), u(rng));
        const Eigen::VectorXd expected = dense.ldlt().solve(Eigen::Map<const Eigen::VectorXd>(rhs[0].data(), static_cast<Eigen::Index>(3 * n)));
        std::vector<Vec3> single = rhs;
        tearables::detail::solveFactored(n, off.data(), factor.data(), gain.data(), coupled.data(), single.data());
        for (std::size_t i = 0; i < n; ++i)
            for (int k = 0; k < 3; ++k)
                EXPECT_NEAR(single[i][k], expected[static_cast<Eigen::Index>(3 * i) + k], 1e-9 * (1.0 + expected.cwiseAbs().maxCoeff()));
        // Unit columns at two rows and the right-hand side, solved together.
        const std::size_t rows[2] = {n / 3, n - 1};
        std::vector<std::vector<Vec3>> columns(7, std::vector<Vec3>(n, Vec3::Zero()));
        std::vector<Vec3*> pointers;
        std::vector<std::size_t> firsts;
        columns[0] = rhs;
        pointers.push_back(columns[0].data());
        firsts.push_back(0);
        for (int r = 0; r < 2; ++r)
            for (int c = 0; c < 3; ++c) {
                std::vector<Vec3>& column = columns[static_cast<std::size_t>(1 + 3 * r + c)];
                column[rows[r]][c] = 1.0;
                pointers.push_back(column.data());
                firsts.push_back(rows[r]);
            }
        std::vector<std::vector<Vec3>> alone = columns;
        tearables::detail::solveFactoredColumns(n, off.data(), factor.data(), gain.data(), coupled.data(), pointers.data(),
                                               firsts.data(), pointers.size());
        for (std::size_t k = 0; k < alone.size(); ++k) {
            tearables::detail::solveFactored(n, off.data(), factor.data(), gain.data(), coupled.data(), alone[k].data(), firsts[k]);
            for (std::size_t i = 0; i < n; ++i) EXPECT_EQ(alone[k][i], columns[k][i]) << "trial " << trial << " column " << k;
        }
    }
}
