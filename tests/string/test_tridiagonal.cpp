// The O(n) kernel (both sweeps of its twisted factorisation, odd and even sizes) against a
// dense solve.
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
