// Symmetric tridiagonal solve (Thomas algorithm), the O(n) direct kernel behind the chain
// tension solve and the twist solve.
#pragma once

#include "base/lanes.hpp"

#include <cstddef>
#include <vector>

namespace tearables::detail {

/// Solves A x = rhs in place for a symmetric tridiagonal A given by its diagonal `diag`
/// (n) and off-diagonal `off` (n, off[i] couples rows i and i+1; off[n-1] unused).
/// `scratch` is resized to n. The matrices we build are symmetric, weakly diagonally
/// dominant and positive definite (J W J^T plus a regularisation), for which the
/// algorithm is stable without pivoting. On return `rhs` holds x.
///
/// The elimination runs from both ends at once (a twisted factorisation), the two sweeps
/// in the two lanes of one register: a row's elimination is a chain of a product and a
/// division on the last row's (~19 cycles), and the two halves' chains take the time of
/// one. They meet at the middle row, which takes both sides' eliminations; the back
/// substitution runs outward from it. Row t of the top sweep and row n-1-t of the bottom
/// one share a step: scratch[t] and scratch[n-1-t] keep their gains (c'), rhs their d'.
inline void solveSymmetricTridiagonal(const std::vector<double>& diag, const std::vector<double>& off,
                                      std::vector<double>& rhs, std::vector<double>& scratch) {
    const std::size_t n = diag.size();
    if (n == 0) return;
    scratch.resize(n);
    const std::size_t mid = n / 2;
    const std::size_t below = n - 1 - mid;  // rows the bottom sweep takes
    // Row t couples to the row before it (t - 1 above, t + 1 below) by `in` and to the
    // next by `out`; gain and y of the row before are carried.
    Lanes2 gain = {0.0, 0.0}, y = {0.0, 0.0};
    std::size_t t = 0;
    for (; t < below; ++t) {
        const std::size_t i = n - 1 - t;
        const Lanes2 in = {t > 0 ? off[t - 1] : 0.0, t > 0 ? off[i] : 0.0};
        const Lanes2 out = {off[t], off[i - 1]};
        const Lanes2 denom = Lanes2{diag[t], diag[i]} - in * gain;
        gain = out / denom;
        y = (Lanes2{rhs[t], rhs[i]} - in * y) / denom;
        scratch[t] = gain[0];
        scratch[i] = gain[1];
        rhs[t] = y[0];
        rhs[i] = y[1];
    }
    double top_gain = gain[0], top_y = y[0];
    if (t < mid) {  // an even count leaves the top sweep one more, t = mid - 1
        const double in = t > 0 ? off[t - 1] : 0.0;
        const double denom = diag[t] - in * top_gain;
        top_gain = off[t] / denom;
        top_y = (rhs[t] - in * top_y) / denom;
        scratch[t] = top_gain;
        rhs[t] = top_y;
    }
    // The middle row: both neighbours eliminated into it.
    const double above = mid > 0 ? off[mid - 1] : 0.0;
    const double under = mid + 1 < n ? off[mid] : 0.0;
    const double denom = diag[mid] - above * top_gain - under * gain[1];
    rhs[mid] = (rhs[mid] - above * top_y - under * y[1]) / denom;
    // Back substitution, outward: x_t = y_t - c_t x_{t+1} above, x_i = y_i - c_i x_{i-1}
    // below, the two in lanes too (rows mid - 1 - k and mid + 1 + k; as two loops, the
    // second's chain waited for the first's).
    Lanes2 x = {rhs[mid], rhs[mid]};
    std::size_t k = 0;
    for (; k < below; ++k) {
        const std::size_t up = mid - 1 - k, down = mid + 1 + k;
        x = Lanes2{rhs[up], rhs[down]} - Lanes2{scratch[up], scratch[down]} * x;
        rhs[up] = x[0];
        rhs[down] = x[1];
    }
    if (k < mid) rhs[0] -= scratch[0] * rhs[1];  // an even count: the top's last row
}

}  // namespace tearables::detail
