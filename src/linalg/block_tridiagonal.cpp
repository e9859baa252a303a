// The block Thomas algorithm for a chain's symmetric block-tridiagonal system: root-free
// Cholesky pivots (factorBlockTridiagonal), and the twisted factorisation with explicit pivot
// inverses in two lanes (solveChain). See block_tridiagonal.hpp.
#include "linalg/block_tridiagonal.hpp"

#include <algorithm>
#include <cstring>

namespace tearables::detail {

/// The recursion is one dependency chain along the chain, bounded by the divider (the
/// pivots' three divisions). The solve with U uses the pivot's stored reciprocals
/// (Cholesky3::solve), and only the lower triangle of U^T W is formed: the factorisation
/// reads no more, and each entry is the same dot product as the full product's.
void factorBlockTridiagonal(std::size_t n, const Mat3* diag, const Mat3* off, Cholesky3* factor, Mat3* gain,
                            std::uint8_t* coupled_to) {
    factor[0].compute(diag[0]);
    coupled_to[0] = 0;
    for (std::size_t i = 1; i < n; ++i) {
        const Mat3& u = off[i - 1];  // couples i-1 and i
        Mat3 d = diag[i];
        const bool coupled = !u.isZero(0.0);
        coupled_to[i] = coupled;
        if (coupled) {
            const Mat3 w = factor[i - 1].solve(u);  // D'^-1 U
            // d -= U^T W, lower triangle only.
            for (int c = 0; c < 3; ++c)
                for (int r = c; r < 3; ++r) d(r, c) -= u.col(r).dot(w.col(c));
            gain[i] = w.transpose();
        } else {
            gain[i].setZero();
        }
        factor[i].compute(d);
    }
}

void solveFactored(std::size_t n, const Mat3* off, const Cholesky3* factor, const Mat3* gain, const std::uint8_t* coupled,
                   Vec3* rhs, std::size_t first) {
    solveFactoredColumns(n, off, factor, gain, coupled, &rhs, &first, 1);
}

void solveFactoredColumns(std::size_t n, const Mat3* off, const Cholesky3* factor, const Mat3* gain, const std::uint8_t* coupled,
                          Vec3* const* columns, const std::size_t* first, std::size_t count) {
    if (count == 0 || n == 0) return;
    const std::size_t start = *std::min_element(first, first + count);
    for (std::size_t i = start + 1; i < n; ++i) {
        if (!coupled[i]) continue;
        for (std::size_t c = 0; c < count; ++c)
            if (i > first[c]) columns[c][i] -= gain[i] * columns[c][i - 1];
    }
    for (std::size_t c = 0; c < count; ++c) columns[c][n - 1] = factor[n - 1].solve(columns[c][n - 1]);
    for (std::size_t i = n - 1; i-- > 0;)
        for (std::size_t c = 0; c < count; ++c)
            columns[c][i] = factor[i].solve(Vec3(columns[c][i] - off[i] * columns[c][i + 1]));
}

namespace {

/// solveChain's back substitution, outward from the middle particle, with the gains it
/// left in `gains` (pair layout).
void substituteChain(std::size_t n, Vec3* rhs, const Mat3* gain_blocks, const std::uint8_t* coupled_pairs) {
    const std::size_t mid = n / 2;
    const std::size_t below = n - 1 - mid;
    const double* gains = gain_blocks->data();
    if (below < mid) {
        double gain[9], x[3], next[3];
        std::memcpy(gain, gains + 18 * below, sizeof gain);
        chain::load(rhs[mid - 1], x);
        chain::load(rhs[mid], next);
        chain::substitute(gain, next, x);
        chain::store(x, rhs[mid - 1]);
    }
    if (below == 0) return;
    Lanes2 next[3];  // the pair's neighbours towards the middle: carried, not read back
    chain::load(rhs[below], rhs[mid], next);
    for (std::size_t p = below; p-- > 0;) {
        const std::size_t i = n - 1 - p;
        // Lane by lane, x = y where the pair's coupling block was zero (solveChain's
        // flags: then so are its gains, and the neighbour is not read, whatever it holds).
        // The gains are read straight from memory, so that the carried neighbour stays in
        // registers.
        Lanes2 x[3];
        chain::load(rhs[p], rhs[i], x);
        if (const int coupled = coupled_pairs[p]) {
            const LaneMask2 m = bitLanes(coupled);
            const double* g = gains + 18 * p;
            for (int r = 0; r < 3; ++r)
                x[r] = x[r] - maskLanes(m, loadLanes(g + 2 * r) * next[0] + loadLanes(g + 2 * (r + 3)) * next[1] +
                                              loadLanes(g + 2 * (r + 6)) * next[2]);
        }
        chain::store(x, rhs[p], rhs[i]);
        std::copy(x, x + 3, next);
    }
}

}  // namespace

void solveChain(std::size_t n, const Mat3* diag, const Mat3* off, Vec3* rhs, Mat3* gain_blocks, std::uint8_t* coupled,
                double* inverses) {
    if (n == 0) return;
    const std::size_t mid = n / 2;
    const std::size_t below = n - 1 - mid;  // particles the sweep from the far end takes
    double* gains = gain_blocks->data();
    chain::Carry<Lanes2> both;
    std::size_t t = 0;
    for (; t < below; ++t) {
        const std::size_t i = n - 1 - t;
        Lanes2 r[3], y[3], gain[9];
        chain::Sym<Lanes2> inv;
        chain::load(rhs[t], rhs[i], r);
        coupled[t] = static_cast<std::uint8_t>(
            laneBits(chain::eliminate(both, chain::lower(diag[t], diag[i]), r, chain::lower(off[t], off[i - 1]), y, gain, inv)));
        chain::store(y, rhs[t], rhs[i]);
        std::memcpy(gains + 18 * t, gain, sizeof gain);
        if (inverses) std::memcpy(inverses + 12 * t, inv.e, sizeof inv.e);
    }
    chain::Carry<double> top, bottom;
    chain::split(both, top, bottom);
    if (t < mid) {  // an even count leaves the top sweep one more, t = mid - 1
        double r[3], y[3], gain[9];
        chain::Sym<double> inv;
        chain::load(rhs[t], r);
        chain::eliminate(top, chain::lower(diag[t]), r, chain::lower(off[t]), y, gain, inv);
        chain::store(y, rhs[t]);
        std::memcpy(gains + 18 * t, gain, sizeof gain);
        if (inverses) std::memcpy(inverses + 12 * below, inv.e, sizeof inv.e);
    }
    chain::Sym<double> middle;
    chain::solveMiddle(top, bottom, diag[mid], rhs[mid], middle);
    if (inverses) std::memcpy(inverses + 12 * below + 6, middle.e, sizeof middle.e);
    substituteChain(n, rhs, gain_blocks, coupled);
}

void chordSolveChain(std::size_t n, const Mat3* off, Vec3* rhs, const Mat3* gains, const std::uint8_t* coupled,
                     const double* inverses) {
    if (n == 0) return;
    const std::size_t mid = n / 2;
    const std::size_t below = n - 1 - mid;
    chain::Carry<Lanes2> both;
    std::size_t t = 0;
    for (; t < below; ++t) {
        const std::size_t i = n - 1 - t;
        Lanes2 r[3], y[3];
        chain::Sym<Lanes2> inv;
        std::memcpy(inv.e, inverses + 12 * t, sizeof inv.e);
        chain::load(rhs[t], rhs[i], r);
        chain::eliminateAgain(both, inv, r, chain::lower(off[t], off[i - 1]), y);
        chain::store(y, rhs[t], rhs[i]);
    }
    chain::Carry<double> top, bottom;
    chain::split(both, top, bottom);
    if (t < mid) {
        double r[3], y[3];
        chain::Sym<double> inv;
        std::memcpy(inv.e, inverses + 12 * below, sizeof inv.e);
        chain::load(rhs[t], r);
        chain::eliminateAgain(top, inv, r, chain::lower(off[t]), y);
        chain::store(y, rhs[t]);
    }
    {
        chain::Carry<double> middle = chain::meet(top, bottom);
        chain::Sym<double> inv;
        std::memcpy(inv.e, inverses + 12 * below + 6, sizeof inv.e);
        double r[3], y[3];
        chain::load(rhs[mid], r);
        chain::eliminateAgain(middle, inv, r, chain::Sym<double>{}, y);
        chain::store(y, rhs[mid]);
    }
    substituteChain(n, rhs, gains, coupled);
}

void substituteHalf(std::size_t n, std::size_t mid, bool above, Vec3* rhs, const Mat3* gains) {
    double next[3], gain[9], x[3];
    chain::load(rhs[mid], next);
    const std::size_t count = above ? mid : n - 1 - mid;
    for (std::size_t k = 1; k <= count; ++k) {
        const std::size_t p = above ? mid - k : mid + k;
        std::memcpy(gain, gains[p].data(), sizeof gain);
        chain::load(rhs[p], x);
        chain::substitute(gain, next, x);
        chain::store(x, rhs[p]);
        std::copy(x, x + 3, next);
    }
}

}  // namespace tearables::detail
