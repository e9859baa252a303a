// Symmetric tridiagonal solve (Thomas algorithm), the O(n) direct kernel behind the chain
// strain limiter and the chain tension solve.
#pragma once

#include <cstddef>
#include <vector>

namespace tearables::detail {

/// Solves A x = rhs in place for a symmetric tridiagonal A given by its diagonal `diag`
/// (n) and off-diagonal `off` (n, off[i] couples rows i and i+1; off[n-1] unused).
/// `scratch` is resized to n. The matrices we build are symmetric, weakly diagonally
/// dominant and positive definite (J W J^T plus a regularisation), for which the
/// algorithm is stable without pivoting. On return `rhs` holds x.
inline void solveSymmetricTridiagonal(const std::vector<double>& diag, const std::vector<double>& off,
                                      std::vector<double>& rhs, std::vector<double>& scratch) {
    const std::size_t n = diag.size();
    if (n == 0) return;
    scratch.resize(n);
    // Forward sweep: scratch[i] = c'_i, rhs[i] = d'_i.
    double denom = diag[0];
    scratch[0] = off[0] / denom;
    rhs[0] /= denom;
    for (std::size_t i = 1; i < n; ++i) {
        denom = diag[i] - off[i - 1] * scratch[i - 1];
        scratch[i] = (i + 1 < n) ? off[i] / denom : 0.0;
        rhs[i] = (rhs[i] - off[i - 1] * rhs[i - 1]) / denom;
    }
    // Back substitution.
    for (std::size_t i = n - 1; i-- > 0;) rhs[i] -= scratch[i] * rhs[i + 1];
}

}  // namespace tearables::detail
