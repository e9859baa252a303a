// The Cholesky factorisation of a 3x3 symmetric positive definite block.
#pragma once

#include "tearables/types.hpp"

#include <Eigen/Cholesky>

#include <cmath>

namespace tearables::detail {

/// Cholesky factor L (A = L L^T) of a symmetric positive definite 3x3 block, the pivot
/// of the chain's block-tridiagonal solve: the same algorithm as Eigen::LLT (column by
/// column, from the lower triangle, the same operations in the same order, so the same
/// bits), written out so that the compiler keeps it in registers instead of going
/// through Eigen's general triangular solver.
/// A block that is not positive definite gives NaN (the solve's callers drop non-finite
/// steps).
struct Cholesky3 {
    double l00 = 1.0, l10 = 0.0, l20 = 0.0, l11 = 1.0, l21 = 0.0, l22 = 1.0;  ///< lower triangle of L
    double i00 = 1.0, i11 = 1.0, i22 = 1.0;                                 ///< 1 / l_kk

    void compute(const Mat3& a) {
        const double p0 = a(0, 0);
        if (p0 > 0.0) {
            l00 = std::sqrt(p0);
            i00 = 1.0 / l00;
            l10 = a(1, 0) / l00;
            l20 = a(2, 0) / l00;
            const double p1 = a(1, 1) - l10 * l10;
            if (p1 > 0.0) {
                l11 = std::sqrt(p1);
                i11 = 1.0 / l11;
                l21 = (a(2, 1) - l20 * l10) / l11;
                const double p2 = a(2, 2) - (l20 * l20 + l21 * l21);
                if (p2 > 0.0) {
                    l22 = std::sqrt(p2);
                    i22 = 1.0 / l22;
                    return;
                }
            }
        }
        // Not positive definite (a degenerate contact or body block): what Eigen::LLT
        // leaves behind, so that such steps behave exactly as before.
        const Eigen::LLT<Mat3> llt(a);
        const Mat3& l = llt.matrixLLT();
        l00 = l(0, 0), l10 = l(1, 0), l20 = l(2, 0), l11 = l(1, 1), l21 = l(2, 1), l22 = l(2, 2);
        i00 = 1.0 / l00, i11 = 1.0 / l11, i22 = 1.0 / l22;
    }
    /// A^-1 b: L y = b, then L^T x = y.
    Vec3 solve(const Vec3& b) const {
        // The operations in Eigen's order (forward by columns, backward by columns), with
        // its divisions, so that the results are those of Eigen::LLT::solve to the bit.
        const double y0 = b.x() / l00;
        const double y1 = (b.y() - l10 * y0) / l11;
        const double y2 = (b.z() - (l20 * y0 + l21 * y1)) / l22;
        const double x2 = y2 / l22;
        const double x1 = (y1 - l21 * x2) / l11;
        const double x0 = (y0 - (l10 * x1 + l20 * x2)) / l00;
        return Vec3(x0, x1, x2);
    }
    /// A^-1 b with the stored reciprocals of the diagonal for its six divisions: products
    /// only, within an ulp or two of solve(b) (each division rounded once, a product by
    /// a rounded reciprocal twice).
    Vec3 solveByReciprocals(const Vec3& b) const {
        const double y0 = b.x() * i00;
        const double y1 = (b.y() - l10 * y0) * i11;
        const double y2 = (b.z() - (l20 * y0 + l21 * y1)) * i22;
        const double x2 = y2 * i22;
        const double x1 = (y1 - l21 * x2) * i11;
        const double x0 = (y0 - (l10 * x1 + l20 * x2)) * i00;
        return Vec3(x0, x1, x2);
    }
    Mat3 solve(const Mat3& b) const {
        // Eigen's solver for several right-hand sides multiplies by the reciprocal of
        // the diagonal instead, and sums differently (checked bit for bit). The
        // reciprocals are the stored ones (the same divisions, done once).
        const double r0 = i00, r1 = i11, r2 = i22;
        Mat3 x;
        for (int c = 0; c < 3; ++c) {
            const double y0 = b(0, c) * r0;
            const double y1 = (b(1, c) - y0 * l10) * r1;
            const double y2 = ((b(2, c) - y0 * l20) - y1 * l21) * r2;
            const double x2 = y2 * r2;
            const double x1 = (y1 - x2 * l21) * r1;
            x(0, c) = (y0 - (l10 * x1 + l20 * x2)) * r0;
            x(1, c) = x1;
            x(2, c) = x2;
        }
        return x;
    }
};

}  // namespace tearables::detail
