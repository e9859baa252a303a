// The root-free Cholesky factorisation (A = L D L^T) of a 3x3 symmetric positive definite
// block.
#pragma once

#include "tearables/types.hpp"

#include <limits>

namespace tearables::detail {

/// Root-free Cholesky factorisation A = L D L^T (L unit lower triangular) of a symmetric
/// positive definite 3x3 block, the pivot of the chain's block-tridiagonal solve. It keeps
/// the reciprocals of D, so that a solve is products only. Its recurrence along a chain
/// waits on three divisions a block, where the Cholesky factor's L L^T waits on three
/// square roots and three divisions; both are backward stable for a positive definite
/// block (Golub & Van Loan, Matrix Computations, 4th ed., 4.2.3 and 4.1.2), so a block far
/// stiffer in one direction (a contact) keeps its soft directions.
/// A block that is not positive definite gives NaN (the solve's callers drop non-finite
/// steps).
struct Cholesky3 {
    double l10 = 0.0, l20 = 0.0, l21 = 0.0;  ///< below the unit diagonal of L
    double r0 = 1.0, r1 = 1.0, r2 = 1.0;     ///< 1 / d_k

    void compute(const Mat3& a) {
        constexpr double nan = std::numeric_limits<double>::quiet_NaN();
        const double d0 = a(0, 0);
        r0 = d0 > 0.0 ? 1.0 / d0 : nan;
        l10 = a(1, 0) * r0;
        l20 = a(2, 0) * r0;
        const double d1 = a(1, 1) - l10 * a(1, 0);
        r1 = d1 > 0.0 ? 1.0 / d1 : nan;
        const double b21 = a(2, 1) - l20 * a(1, 0);  // d1 l21
        l21 = b21 * r1;
        const double d2 = a(2, 2) - l20 * a(2, 0) - l21 * b21;
        r2 = d2 > 0.0 ? 1.0 / d2 : nan;
    }
    /// A^-1 b: L y = b, z = D^-1 y, L^T x = z.
    Vec3 solve(const Vec3& b) const {
        const double y0 = b.x();
        const double y1 = b.y() - l10 * y0;
        const double y2 = b.z() - (l20 * y0 + l21 * y1);
        const double x2 = y2 * r2;
        const double x1 = y1 * r1 - l21 * x2;
        const double x0 = y0 * r0 - (l10 * x1 + l20 * x2);
        return Vec3(x0, x1, x2);
    }
    Mat3 solve(const Mat3& b) const {
        Mat3 x;
        for (int c = 0; c < 3; ++c) x.col(c) = solve(Vec3(b.col(c)));
        return x;
    }
};

}  // namespace tearables::detail
