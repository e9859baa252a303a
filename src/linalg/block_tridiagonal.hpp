// The symmetric block-tridiagonal solve of a chain of particles (3x3 blocks, particle i
// coupled to i + 1): the block Thomas algorithm, O(n), no pivoting (the blocks are
// symmetric positive definite). Two forms:
//  - factorBlockTridiagonal / solveFactored: root-free Cholesky pivots (Cholesky3, L D L^T),
//    for systems with stiff contact blocks, which an explicit inverse would lose a
//    direction of;
//  - solveChain / chordSolveChain: each pivot inverted explicitly (three divisions) and run
//    from both ends at once (a twisted factorisation), the two sweeps in the two lanes of
//    one register; the pivots' inverses can be kept for chord solves.
// The arrays are the caller's: diag (n), off (n - 1 or more; off[i] couples i and i + 1),
// rhs (n, the solution on return) and the factorisation's storage.
#pragma once

#include "base/lanes.hpp"
#include "linalg/cholesky3.hpp"
#include "tearables/types.hpp"

#include <cstddef>
#include <cstdint>

namespace tearables::detail {

/// Factorises the block tridiagonal (diag, off) of n blocks: root-free Cholesky pivots into
/// `factor`, gains U_{i-1}^T D'_{i-1}^-1 into `gain` (entry 0 unused) and whether particle
/// i couples to i - 1 into `coupled`.
void factorBlockTridiagonal(std::size_t n, const Mat3* diag, const Mat3* off, Cholesky3* factor, Mat3* gain,
                            std::uint8_t* coupled);
/// Solves the system factorised by factorBlockTridiagonal for `rhs` (n) in place. With
/// `first`, rhs is zero above row `first`: the forward substitution starts there (the rows
/// above stay exactly zero through it; the same bits as from row 0).
void solveFactored(std::size_t n, const Mat3* off, const Cholesky3* factor, const Mat3* gain, const std::uint8_t* coupled,
                   Vec3* rhs, std::size_t first = 0);

/// solveFactored for `count` right-hand sides at once, `columns[c]` (n each) in place,
/// column c zero above row `first[c]` (solveFactored is its one-column case). Each column
/// gets the operations it would alone; interleaved, their sweeps' dependency chains overlap
/// in the pipeline instead of running one after another.
void solveFactoredColumns(std::size_t n, const Mat3* off, const Cholesky3* factor, const Mat3* gain, const std::uint8_t* coupled,
                          Vec3* const* columns, const std::size_t* first, std::size_t count);

/// Solves (diag, off) x = rhs in place by the twisted factorisation: each sweep folds
/// factor, forward substitution and y_i = D_i^-1 r_i into one pass; the two meet at the
/// middle particle, whose pivot takes both sides' Schur complements, and the back
/// substitution x_i = y_i - W_i x_{i+-1} runs outward from there. The coupling blocks are
/// symmetric (their lower triangle is read). The pair of particles (t, n-1-t), lane by lane:
/// its gains W go into `gains` at doubles [18 t, 18 t + 18) (9 n doubles in all), whether
/// each couples onward into bits 0 and 1 of `coupled[t]`, and where `inverses` is given
/// (6 n + 12 doubles), its pivots' inverses at [12 t, 12 t + 12), the top sweep's last one
/// and the middle one's after them, for chordSolveChain.
///
/// The pivots are inertia m/h^2 plus springs: conditioned ~k h^2 / m, so the explicit
/// inverse is good to ~1e-10 relative, which a Newton iteration with an exact gradient does
/// not notice. Blocks far stiffer in one direction (contacts) need the Cholesky form.
void solveChain(std::size_t n, const Mat3* diag, const Mat3* off, Vec3* rhs, Mat3* gains, std::uint8_t* coupled,
                double* inverses = nullptr);
/// A chord solve: the system solveChain factorised last (its coupling blocks `off`, its
/// `gains`, `coupled` flags and pivots' `inverses`) for a new right-hand side `rhs`, in
/// place. Only products: no pivot, no division.
void chordSolveChain(std::size_t n, const Mat3* off, Vec3* rhs, const Mat3* gains, const std::uint8_t* coupled,
                     const double* inverses);
/// The back substitution of one sweep of a twisted factorisation run as two single sweeps
/// (chain::eliminate per particle, its gain W per particle in `gains`), outward from the
/// middle particle `mid`: x_t = y_t - W_t x_{t+1} above it (`above`, t < mid), or
/// x_i = y_i - W_i x_{i-1} below it (i > mid). The last x is carried in registers, not
/// read back from rhs.
void substituteHalf(std::size_t n, std::size_t mid, bool above, Vec3* rhs, const Mat3* gains);

// The kernels of solveChain's sweeps, written once for a lane type T: double for one
// sweep, Lanes2 for two (the sweep from the top in lane 0). Each lane computes exactly what
// the scalar code computes (no FMA on the default x86-64 target), so a chain split into two
// single sweeps on two threads gives the bits of the two-lane solve.
namespace chain {

/// v where m holds, else 0 (also where v is not finite).
inline double keep(bool m, double v) { return m ? v : 0.0; }
inline Lanes2 keep(LaneMask2 m, Lanes2 v) { return maskLanes(m, v); }
/// Whether any of the n values is not zero, lane by lane. One sweep stops at the first
/// (a predictable branch).
template <int n> inline bool anyNonzero(const double* v) {
    for (int k = 0; k < n; ++k)
        if (v[k] != 0.0) return true;
    return false;
}
template <int n> inline LaneMask2 anyNonzero(const Lanes2* v) {
    LaneMask2 m = nonzeroLanes(v[0]);
    for (int k = 1; k < n; ++k) m = eitherLane(m, nonzeroLanes(v[k]));
    return m;
}
/// Whether no lane of m holds.
inline bool none(bool m) { return !m; }
inline bool none(LaneMask2 m) { return noLane(m); }

/// A symmetric 3x3 matrix by its lower triangle: 00 10 20 11 21 22.
template <class T> struct Sym {
    T e[6];
    T operator()(int r, int c) const { return e[kIndex[r][c]]; }
    static constexpr int kIndex[3][3] = {{0, 1, 2}, {1, 3, 4}, {2, 4, 5}};
};
inline Sym<double> lower(const Mat3& a) { return {{a(0, 0), a(1, 0), a(2, 0), a(1, 1), a(2, 1), a(2, 2)}}; }
inline Sym<Lanes2> lower(const Mat3& a, const Mat3& b) {
    Sym<Lanes2> m;
    for (int c = 0, k = 0; c < 3; ++c)
        for (int r = c; r < 3; ++r) m.e[k++] = Lanes2{a(r, c), b(r, c)};
    return m;
}

/// What a sweep carries to the next particle: the Schur complement U^T D^-1 U of the
/// particle it eliminated (D its pivot, U its coupling block) and U^T y, both zero where
/// U is zero (nothing crosses it: a pin, a broken segment), whatever D^-1 holds.
template <class T> struct Carry {
    Sym<T> schur{};
    T rhs[3] = {};
};

/// The inverse of a symmetric positive definite 3x3 matrix from its root-free Cholesky
/// factorisation A = L D L^T: A^-1 = L^-T D^-1 L^-1, three divisions. As accurate as the
/// Cholesky solve, where an adjugate inverse loses ~cond(A) of the digits.
template <class T> [[gnu::always_inline]] inline Sym<T> inverseSymmetric(const Sym<T>& a) {
    const T one = T{} + 1.0;
    const T r0 = one / a.e[0];
    const T l10 = a.e[1] * r0, l20 = a.e[2] * r0;
    const T r1 = one / (a.e[3] - l10 * a.e[1]);
    const T b21 = a.e[4] - l20 * a.e[1];
    const T l21 = b21 * r1;
    const T r2 = one / (a.e[5] - l20 * a.e[2] - l21 * b21);
    const T m20 = l10 * l21 - l20;  // row 2 of L^-1: (m20, -l21, 1)
    const T i20 = r2 * m20, i21 = -r2 * l21;
    const T i10 = -r1 * l10 + i21 * m20;
    return {{r0 + r1 * l10 * l10 + i20 * m20, i10, i20, r1 + i21 * -l21, i21, r2}};
}

/// The forward substitution of one particle, its pivot's inverse `inv` given: y = D^-1 (rhs
/// less the carry's U^T y), and the carry's U^T y for the next particle (zero, with the
/// Schur complement, where the symmetric coupling block `out` = U is zero). Part of
/// eliminate, and alone a chord iteration's forward step (chordSolveChain).
/// Returns whether `out` couples, lane by lane.
template <class T>
[[gnu::always_inline]] inline auto eliminateAgain(Carry<T>& carry, const Sym<T>& inv, const T (&rhs)[3], const Sym<T>& out, T (&y)[3]) {
    T r[3];
    for (int i = 0; i < 3; ++i) r[i] = rhs[i] - carry.rhs[i];
    for (int i = 0; i < 3; ++i) y[i] = inv(i, 0) * r[0] + inv(i, 1) * r[1] + inv(i, 2) * r[2];
    const auto coupled = anyNonzero<6>(out.e);
    if (none(coupled)) {
        carry = Carry<T>{};
        return coupled;
    }
    for (int i = 0; i < 3; ++i) carry.rhs[i] = keep(coupled, out(i, 0) * y[0] + out(i, 1) * y[1] + out(i, 2) * y[2]);
    return coupled;
}

/// Eliminates one particle: its block `diag` and right-hand side `rhs`, less what the
/// carry brings from the particle before, give the pivot D; y = D^-1 r, D^-1 into `inv`
/// and the gain W = D^-1 U (column-major) towards the next particle, coupled by the
/// symmetric block `out` = U; the carry is then this particle's, for the next.
template <class T>
[[gnu::always_inline]] inline auto eliminate(Carry<T>& carry, const Sym<T>& diag, const T (&rhs)[3], const Sym<T>& out, T (&y)[3], T (&gain)[9], Sym<T>& inv) {
    Sym<T> pivot;
    for (int k = 0; k < 6; ++k) pivot.e[k] = diag.e[k] - carry.schur.e[k];
    inv = inverseSymmetric(pivot);
    for (int c = 0; c < 3; ++c)
        for (int i = 0; i < 3; ++i) gain[i + 3 * c] = inv(i, 0) * out(0, c) + inv(i, 1) * out(1, c) + inv(i, 2) * out(2, c);
    const auto coupled = eliminateAgain(carry, inv, rhs, out, y);
    if (none(coupled)) return coupled;
    for (int c = 0; c < 3; ++c)
        for (int i = c; i < 3; ++i)
            carry.schur.e[Sym<T>::kIndex[i][c]] = keep(coupled, out(i, 0) * gain[3 * c] + out(i, 1) * gain[1 + 3 * c] + out(i, 2) * gain[2 + 3 * c]);
    return coupled;
}

/// Back substitution of one particle: x = y - W x_next, where the gain W is not zero (a
/// zero gain, nothing crossing, leaves y whatever x_next holds).
template <class T> [[gnu::always_inline]] inline void substitute(const T (&gain)[9], const T (&next)[3], T (&x)[3]) {
    const auto coupled = anyNonzero<9>(gain);
    if (none(coupled)) return;
    for (int i = 0; i < 3; ++i) x[i] = x[i] - keep(coupled, gain[i] * next[0] + gain[i + 3] * next[1] + gain[i + 6] * next[2]);
}

/// A particle's vector into a sweep's lanes (one, or the top's and the bottom's), and back.
inline void load(const Vec3& v, double (&out)[3]) {
    for (int i = 0; i < 3; ++i) out[i] = v[i];
}
inline void load(const Vec3& a, const Vec3& b, Lanes2 (&out)[3]) {
    for (int i = 0; i < 3; ++i) out[i] = Lanes2{a[i], b[i]};
}
inline void store(const double (&v)[3], Vec3& out) {
    for (int i = 0; i < 3; ++i) out[i] = v[i];
}
inline void store(const Lanes2 (&v)[3], Vec3& a, Vec3& b) {
    for (int i = 0; i < 3; ++i) {
        a[i] = v[i][0];
        b[i] = v[i][1];
    }
}

/// The middle particle, where the two sweeps meet: its block less both sides' Schur
/// complements, solved into x.
inline Carry<double> meet(const Carry<double>& top, const Carry<double>& bottom) {
    Carry<double> both;
    for (int k = 0; k < 6; ++k) both.schur.e[k] = top.schur.e[k] + bottom.schur.e[k];
    for (int i = 0; i < 3; ++i) both.rhs[i] = top.rhs[i] + bottom.rhs[i];
    return both;
}
inline void solveMiddle(const Carry<double>& top, const Carry<double>& bottom, const Mat3& diag, Vec3& rhs, Sym<double>& inv) {
    Carry<double> both = meet(top, bottom);
    double r[3], x[3], unused[9];
    load(rhs, r);
    eliminate(both, lower(diag), r, Sym<double>{}, x, unused, inv);
    store(x, rhs);
}

/// The lanes of a carry, as the two sweeps' own.
inline void split(const Carry<Lanes2>& both, Carry<double>& top, Carry<double>& bottom) {
    for (int k = 0; k < 6; ++k) {
        top.schur.e[k] = both.schur.e[k][0];
        bottom.schur.e[k] = both.schur.e[k][1];
    }
    for (int k = 0; k < 3; ++k) {
        top.rhs[k] = both.rhs[k][0];
        bottom.rhs[k] = both.rhs[k][1];
    }
}

}  // namespace chain

}  // namespace tearables::detail
