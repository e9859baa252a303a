// A supernodal sparse Cholesky factorisation A = L L^T (the cloth's Newton Hessian, the
// cloth's and the paper's tension normal equations), without BLAS or threads: the
// standard left-looking supernodal method (Ng and Peyton 1993; Davis, "Direct Methods for
// Sparse Linear Systems", 2006, ch. 4 for the elimination tree and the row patterns).
//
// In nested-dissection order (gridDissection) the columns of L come in runs with the same
// structure below the diagonal (supernodes: the separators, and the 3 unknowns of a
// vertex); a supernode is one dense column-major panel, every update from a descendant a
// dense product subtracted where its rows land (updateScatter), then the panel is
// factorised in place (panelCholesky). The kernels are our own: the panels are narrow (a
// few columns), where Eigen's GEMM and LLT dispatch costs more than the arithmetic. An
// AVX2 variant of each is chosen at run time and gives the same bits.
//
// The symbolic analysis (elimination tree, pattern of L, supernodes, where each entry of A
// goes) depends on the pattern of A only and is kept while the pattern is the same. The
// matrix must be symmetric positive definite (all three are: masses over h^2 or lambda' I
// plus positive semi-definite terms); factorize() says false otherwise, and the caller
// falls back (LDL^T, or conjugate gradients for the paper). No pivoting: the order is the one given.
#pragma once

#include <Eigen/Dense>
#include <Eigen/SparseCore>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <vector>

namespace tearables::detail {

namespace supernodal {

typedef double Lanes4 __attribute__((vector_size(32)));

/// Dense Cholesky of a supernode's panel in place: its top w x w block becomes L11 (lower),
/// the rows below L21 = A21 L11^-T; inverse[j] = 1 / L_jj. Left-looking, a column at a
/// time: column j less its products with the columns before it (four at a time, subtracted
/// in column order), then the root of its diagonal and a multiply of the rest by its
/// reciprocal. False at a pivot that is not positive or a root that is not finite.
template <bool kWide>
__attribute__((always_inline)) inline bool panelCholeskyBody(double* p, int h, int w, double* inverse) {
    for (int j = 0; j < w; ++j) {
        double* cj = p + static_cast<std::ptrdiff_t>(j) * h;
        int k = 0;
        for (; k + 4 <= j; k += 4) {
            const double* c0 = p + static_cast<std::ptrdiff_t>(k) * h;
            const double *c1 = c0 + h, *c2 = c1 + h, *c3 = c2 + h;
            const double a0 = c0[j], a1 = c1[j], a2 = c2[j], a3 = c3[j];
            int r = j;
            if constexpr (kWide) {
                for (; r + 4 <= h; r += 4) {
                    Lanes4 x, y0, y1, y2, y3;
                    std::memcpy(&x, cj + r, sizeof x);
                    std::memcpy(&y0, c0 + r, sizeof y0);
                    std::memcpy(&y1, c1 + r, sizeof y1);
                    std::memcpy(&y2, c2 + r, sizeof y2);
                    std::memcpy(&y3, c3 + r, sizeof y3);
                    x = (((x - y0 * a0) - y1 * a1) - y2 * a2) - y3 * a3;
                    std::memcpy(cj + r, &x, sizeof x);
                }
            }
            for (; r < h; ++r) cj[r] = (((cj[r] - c0[r] * a0) - c1[r] * a1) - c2[r] * a2) - c3[r] * a3;
        }
        for (; k < j; ++k) {
            const double* ck = p + static_cast<std::ptrdiff_t>(k) * h;
            const double a = ck[j];
            int r = j;
            if constexpr (kWide) {
                for (; r + 4 <= h; r += 4) {
                    Lanes4 x, y;
                    std::memcpy(&x, cj + r, sizeof x);
                    std::memcpy(&y, ck + r, sizeof y);
                    x = x - y * a;
                    std::memcpy(cj + r, &x, sizeof x);
                }
            }
            for (; r < h; ++r) cj[r] -= ck[r] * a;
        }
        if (!(cj[j] > 0.0)) return false;
        const double root = std::sqrt(cj[j]);
        if (!std::isfinite(root)) return false;
        cj[j] = root;
        const double inv = 1.0 / root;
        inverse[j] = inv;
        for (int r = j + 1; r < h; ++r) cj[r] *= inv;
    }
    return true;
}

inline bool panelCholeskyPortable(double* p, int h, int w, double* inverse) {
    return panelCholeskyBody<false>(p, h, w, inverse);
}

/// c[m] = the sums over the w columns of a_(i..i+3) a_(j+m), m < 4 (updateScatterBody's
/// 4 x 4 tile: from zero, one multiply and one add at a time, in column order).
__attribute__((always_inline)) inline void tile4x4(const double* a, int lda, int w, int i, int j, Lanes4 (&c)[4]) {
    c[0] = c[1] = c[2] = c[3] = Lanes4{0, 0, 0, 0};
    for (int k = 0; k < w; ++k) {
        const double* column = a + static_cast<std::ptrdiff_t>(k) * lda;
        Lanes4 x;
        std::memcpy(&x, column + i, sizeof x);
        c[0] += x * column[j];
        c[1] += x * column[j + 1];
        c[2] += x * column[j + 2];
        c[3] += x * column[j + 3];
    }
}

/// The update of a descendant, subtracted from the panel where it lands: for the r rows
/// i and first r1 rows j (i >= j) of the r x w block at `a` (column-major, leading
/// dimension lda), panel[rel[i]] of target column cols[j] less sum_k a_ik a_jk. Each sum
/// runs over the w columns in order, one multiply and one add at a time from zero (the AVX2
/// kernel and the portable one give the same bits). Four columns at a time: the tile on
/// their diagonal, then eight rows at a time in eight registers, then four; the products
/// go straight to the panel (no scratch product).
template <bool kWide>
__attribute__((always_inline)) inline void updateScatterBody(const double* a, int lda, int w, int r, int r1, const int* rel,
                                                             double* const* cols) {
    int j = 0;
    if constexpr (kWide) {
        for (; j + 4 <= r1; j += 4) {
            double *t0 = cols[j], *t1 = cols[j + 1], *t2 = cols[j + 2], *t3 = cols[j + 3];
            int i = j;
            if (j + 4 <= r) {  // the tile on the diagonal: its lower triangle
                Lanes4 c[4];
                tile4x4(a, lda, w, i, j, c);
                for (int l = 0; l < 4; ++l) {
                    const int at = rel[i + l];
                    t0[at] -= c[0][l];
                    if (l >= 1) t1[at] -= c[1][l];
                    if (l >= 2) t2[at] -= c[2][l];
                    if (l >= 3) t3[at] -= c[3][l];
                }
                i += 4;
            }
            for (; i + 8 <= r; i += 8) {  // eight rows below it: eight registers
                Lanes4 c0 = {0, 0, 0, 0}, c1 = c0, c2 = c0, c3 = c0, d0 = c0, d1 = c0, d2 = c0, d3 = c0;
                for (int k = 0; k < w; ++k) {
                    const double* column = a + static_cast<std::ptrdiff_t>(k) * lda;
                    Lanes4 x, y;
                    std::memcpy(&x, column + i, sizeof x);
                    std::memcpy(&y, column + i + 4, sizeof y);
                    const double b0 = column[j], b1 = column[j + 1], b2 = column[j + 2], b3 = column[j + 3];
                    c0 += x * b0;
                    c1 += x * b1;
                    c2 += x * b2;
                    c3 += x * b3;
                    d0 += y * b0;
                    d1 += y * b1;
                    d2 += y * b2;
                    d3 += y * b3;
                }
                for (int l = 0; l < 4; ++l) {
                    const int at = rel[i + l], bt = rel[i + 4 + l];
                    t0[at] -= c0[l];
                    t1[at] -= c1[l];
                    t2[at] -= c2[l];
                    t3[at] -= c3[l];
                    t0[bt] -= d0[l];
                    t1[bt] -= d1[l];
                    t2[bt] -= d2[l];
                    t3[bt] -= d3[l];
                }
            }
            for (; i + 4 <= r; i += 4) {  // below it, four rows
                Lanes4 c[4];
                tile4x4(a, lda, w, i, j, c);
                for (int l = 0; l < 4; ++l) {
                    const int at = rel[i + l];
                    t0[at] -= c[0][l];
                    t1[at] -= c[1][l];
                    t2[at] -= c[2][l];
                    t3[at] -= c[3][l];
                }
            }
            for (; i < r; ++i)
                for (int m = 0; m < 4 && j + m <= i; ++m) {
                    double acc = 0.0;
                    for (int k = 0; k < w; ++k) {
                        const double* column = a + static_cast<std::ptrdiff_t>(k) * lda;
                        acc += column[i] * column[j + m];
                    }
                    cols[j + m][rel[i]] -= acc;
                }
        }
    }
    for (; j < r1; ++j) {
        double* t = cols[j];
        int i = j;
        if constexpr (kWide) {
            for (; i + 4 <= r; i += 4) {
                Lanes4 acc = {0, 0, 0, 0};
                for (int k = 0; k < w; ++k) {
                    const double* column = a + static_cast<std::ptrdiff_t>(k) * lda;
                    Lanes4 x;
                    std::memcpy(&x, column + i, sizeof x);
                    acc += x * column[j];
                }
                for (int l = 0; l < 4; ++l) t[rel[i + l]] -= acc[l];
            }
        }
        for (; i < r; ++i) {
            double acc = 0.0;
            for (int k = 0; k < w; ++k) {
                const double* column = a + static_cast<std::ptrdiff_t>(k) * lda;
                acc += column[i] * column[j];
            }
            t[rel[i]] -= acc;
        }
    }
}

inline void updateScatterPortable(const double* a, int lda, int w, int r, int r1, const int* rel, double* const* cols) {
    updateScatterBody<false>(a, lda, w, r, r1, rel, cols);
}

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
__attribute__((target("avx2"))) inline bool panelCholeskyAvx2(double* p, int h, int w, double* inverse) {
    return panelCholeskyBody<true>(p, h, w, inverse);
}
__attribute__((target("avx2"))) inline void updateScatterAvx2(const double* a, int lda, int w, int r, int r1, const int* rel,
                                                               double* const* cols) {
    updateScatterBody<true>(a, lda, w, r, r1, rel, cols);
}
inline bool haveAvx2() {
    static const bool have = __builtin_cpu_supports("avx2");
    return have;
}
#else
inline bool panelCholeskyAvx2(double* p, int h, int w, double* inverse) {
    return panelCholeskyBody<false>(p, h, w, inverse);
}
inline void updateScatterAvx2(const double* a, int lda, int w, int r, int r1, const int* rel, double* const* cols) {
    updateScatterBody<false>(a, lda, w, r, r1, rel, cols);
}
inline bool haveAvx2() { return false; }
#endif

}  // namespace supernodal

/// See supernodal::updateScatterBody.
inline void updateScatter(const double* a, int lda, int w, int r, int r1, const int* rel, double* const* cols) {
    if (supernodal::haveAvx2())
        supernodal::updateScatterAvx2(a, lda, w, r, r1, rel, cols);
    else
        supernodal::updateScatterPortable(a, lda, w, r, r1, rel, cols);
}

/// See supernodal::panelCholeskyBody.
inline bool panelCholesky(double* p, int h, int w, double* inverse) {
    return supernodal::haveAvx2() ? supernodal::panelCholeskyAvx2(p, h, w, inverse)
                                  : supernodal::panelCholeskyPortable(p, h, w, inverse);
}

class SupernodalLLT {
public:
    using Matrix = Eigen::SparseMatrix<double>;  // column-major, compressed

    /// Symbolic analysis of the pattern of `a` (square; its lower triangle is read, an
    /// upper one, if stored, is ignored).
    void analyze(const Matrix& a) {
        const int n = static_cast<int>(a.cols());
        n_ = n;
        nnz_ = static_cast<int>(a.nonZeros());
        pattern_outer_.assign(a.outerIndexPtr(), a.outerIndexPtr() + n + 1);
        pattern_inner_.assign(a.innerIndexPtr(), a.innerIndexPtr() + nnz_);
        // Strictly lower entries (i, j), i > j, grouped by row i: the upper columns.
        std::vector<int> row_start(n + 1, 0), row_cols;
        forEntry(a, [&](int i, int j, int) {
            if (i > j) ++row_start[i + 1];
        });
        for (int i = 0; i < n; ++i) row_start[i + 1] += row_start[i];
        row_cols.resize(row_start[n]);
        {
            std::vector<int> fill(row_start.begin(), row_start.end() - 1);
            forEntry(a, [&](int i, int j, int) {
                if (i > j) row_cols[fill[i]++] = j;
            });
        }
        // Elimination tree (Liu's algorithm with path compression).
        parent_.assign(n, -1);
        std::vector<int> ancestor(n, -1);
        for (int k = 0; k < n; ++k)
            for (int p = row_start[k]; p < row_start[k + 1]; ++p)
                for (int i = row_cols[p]; i != -1 && i < k;) {
                    const int next = ancestor[i];
                    ancestor[i] = k;
                    if (next == -1) parent_[i] = k;
                    i = next;
                }
        // Pattern of L below the diagonal, column by column (row k of L is the part of the
        // elimination tree reached from the entries of row k of A): counts, then rows.
        std::vector<int> mark(n, -1), count(n, 0);
        auto rowPattern = [&](auto&& visit) {
            std::fill(mark.begin(), mark.end(), -1);
            for (int k = 0; k < n; ++k) {
                mark[k] = k;
                for (int p = row_start[k]; p < row_start[k + 1]; ++p)
                    for (int i = row_cols[p]; mark[i] != k; i = parent_[i]) {
                        visit(i, k);
                        mark[i] = k;
                    }
            }
        };
        rowPattern([&](int i, int) { ++count[i]; });
        std::vector<int> col_start(n + 1, 0), col_rows;
        for (int j = 0; j < n; ++j) col_start[j + 1] = col_start[j] + count[j];
        col_rows.resize(col_start[n]);
        {
            std::vector<int> fill(col_start.begin(), col_start.end() - 1);
            rowPattern([&](int i, int k) { col_rows[fill[i]++] = k; });  // increasing k: sorted
        }
        flops_ = 0.0;
        for (int j = 0; j < n; ++j) flops_ += (count[j] + 1.0) * (count[j] + 1.0);
        // Supernodes: runs j, j + 1, ... where j + 1 is j's parent and has j's pattern less
        // j (fundamental), relaxed (Ashcraft and Grimes 1989): a run also takes its parent
        // column when the panel stays narrow and at most a quarter of it is explicit zeros
        // (column j of a run f .. e has e - j + count[e] entries below its diagonal where
        // it needs count[j]): fewer, larger panels, less bookkeeping per flop.
        first_.clear();
        for (int j = 0; j < n;) {
            int end = j + 1;
            while (end < n && parent_[end - 1] == end) {
                if (count[end - 1] != count[end] + 1) {
                    if (end + 1 - j > kRelaxedWidth) break;
                    double zeros = 0.0, entries = 0.0;
                    for (int c = j; c <= end; ++c) {
                        zeros += end - c + count[end] - count[c];
                        entries += end - c + 1 + count[end];
                    }
                    if (zeros > kRelaxedZeros * entries) break;
                }
                ++end;
            }
            first_.push_back(j);
            j = end;
        }
        const int supernodes = static_cast<int>(first_.size());
        first_.push_back(n);
        snode_of_.resize(n);
        rows_start_.assign(supernodes + 1, 0);
        value_start_.assign(supernodes + 1, 0);
        rows_.clear();
        for (int s = 0; s < supernodes; ++s) {
            const int f = first_[s], w = first_[s + 1] - f;
            for (int j = f; j < f + w; ++j) snode_of_[j] = s;
            for (int j = f; j < f + w; ++j) rows_.push_back(j);
            const int last = f + w - 1;
            rows_.insert(rows_.end(), col_rows.begin() + col_start[last], col_rows.begin() + col_start[last + 1]);
            rows_start_[s + 1] = static_cast<int>(rows_.size());
            value_start_[s + 1] = value_start_[s] + static_cast<std::size_t>(rows_start_[s + 1] - rows_start_[s]) * w;
        }
        values_.assign(value_start_[supernodes], 0.0);
        // Where each entry of A goes in the panels.
        std::vector<int> where(n, -1);
        map_.assign(nnz_, -1);
        for (int s = 0; s < supernodes; ++s) {
            const int f = first_[s], w = first_[s + 1] - f;
            const int height = rows_start_[s + 1] - rows_start_[s];
            for (int r = 0; r < height; ++r) where[rows_[rows_start_[s] + r]] = r;
            lowerColumn(a, f, f + w, [&](int i, int j, int p) {
                map_[p] = static_cast<std::ptrdiff_t>(value_start_[s] + static_cast<std::size_t>(j - f) * height + where[i]);
            });
        }
        std::size_t tallest = 0;
        for (int s = 0; s < supernodes; ++s) tallest = std::max(tallest, static_cast<std::size_t>(rows_start_[s + 1] - rows_start_[s]));
        rel_.assign(tallest, 0);
        target_.assign(tallest, nullptr);
        solve_scratch_.assign(n, 0.0);
        inverse_diagonal_.assign(n, 0.0);
        where_.assign(n, 0);
        link_.assign(supernodes, -1);
        head_.assign(supernodes, -1);
        cursor_.assign(supernodes, 0);
        analysed_ = true;
    }

    /// True when `a` has the pattern analyze() saw.
    bool samePattern(const Matrix& a) const {
        return analysed_ && a.cols() == n_ && a.nonZeros() == nnz_ &&
               std::equal(pattern_outer_.begin(), pattern_outer_.end(), a.outerIndexPtr()) &&
               std::equal(pattern_inner_.begin(), pattern_inner_.end(), a.innerIndexPtr());
    }

    /// Numeric factorisation of `a` (the analysed pattern). False when a pivot is not
    /// positive (not positive definite in this order) or not finite.
    bool factorize(const Matrix& a) {
        std::fill(values_.begin(), values_.end(), 0.0);
        const double* ax = a.valuePtr();
        for (int p = 0; p < nnz_; ++p)
            if (map_[p] >= 0) values_[static_cast<std::size_t>(map_[p])] = ax[p];
        const int supernodes = static_cast<int>(first_.size()) - 1;
        std::fill(head_.begin(), head_.end(), -1);
        for (int s = 0; s < supernodes; ++s) {
            const int f = first_[s], w = first_[s + 1] - f;
            const int* rows = rows_.data() + rows_start_[s];
            const int height = rows_start_[s + 1] - rows_start_[s];
            for (int r = 0; r < height; ++r) where_[rows[r]] = r;
            Panel panel(values_.data() + value_start_[s], height, w);
            // Updates from every descendant d with rows in columns f .. f + w - 1.
            for (int d = head_[s]; d != -1;) {
                const int next_d = link_[d];
                const int dw = first_[d + 1] - first_[d];
                const int* drows = rows_.data() + rows_start_[d];
                const int dheight = rows_start_[d + 1] - rows_start_[d];
                const int p1 = cursor_[d];
                int p2 = p1;
                while (p2 < dheight && drows[p2] < f + w) ++p2;
                const int r = dheight - p1, r1 = p2 - p1;
                ConstPanel dpanel(values_.data() + value_start_[d], dheight, dw);
                if (dw == 1) {
                    // A one-column descendant (most of the tension's): every entry of its
                    // product is a single multiply (updateScatter would give 0 + a_i a_j: the
                    // same bits, up to the sign of a zero), without the kernel's tiles.
                    const double* from = dpanel.data() + p1;
                    const int* at = drows + p1;
                    for (int jj = 0; jj < r1; ++jj) {
                        double* column = panel.data() + static_cast<std::ptrdiff_t>(at[jj] - f) * height;
                        const double aj = from[jj];
                        for (int ii = jj; ii < r; ++ii) column[where_[at[ii]]] -= from[ii] * aj;
                    }
                } else {
                    for (int ii = 0; ii < r; ++ii) rel_[ii] = where_[drows[p1 + ii]];
                    for (int jj = 0; jj < r1; ++jj) target_[jj] = panel.data() + static_cast<std::ptrdiff_t>(drows[p1 + jj] - f) * height;
                    updateScatter(dpanel.data() + p1, dheight, dw, r, r1, rel_.data(), target_.data());
                }
                cursor_[d] = p2;
                if (p2 < dheight) {
                    const int t = snode_of_[drows[p2]];
                    link_[d] = head_[t];
                    head_[t] = d;
                }
                d = next_d;
            }
            // The panel: dense Cholesky of its diagonal block, then L21 = A21 L11^-T.
            if (!panelCholesky(panel.data(), height, w, inverse_diagonal_.data() + f)) return false;
            if (height > w) {
                cursor_[s] = w;
                const int t = snode_of_[rows[w]];
                link_[s] = head_[t];
                head_[t] = s;
            }
        }
        return true;
    }

    /// x <- A^-1 x with the factors. The solves multiply by the reciprocals of L's diagonal
    /// (a division, ~15 cycles, sat on their critical path; within an ulp of it). Per
    /// panel, the rows below its diagonal block are gathered (or scattered) once, and the
    /// dense parts are plain loops over contiguous columns with independent partial sums
    /// (most panels are narrow: the dispatch of Eigen's dense kernels would cost more than
    /// their arithmetic).
    void solveInPlace(Eigen::VectorXd& x) const {
        const int supernodes = static_cast<int>(first_.size()) - 1;
        double* const v = x.data();
        double* const below = solve_scratch_.data();
        const double* const inverse = inverse_diagonal_.data();
        for (int s = 0; s < supernodes; ++s) {  // L y = b
            const int f = first_[s], w = first_[s + 1] - f;
            const int* rows = rows_.data() + rows_start_[s];
            const int height = rows_start_[s + 1] - rows_start_[s], tail = height - w;
            const double* panel = values_.data() + value_start_[s];
            if (w == 1) {  // the same arithmetic without the scratch (0 + c y = c y)
                const double y = v[f] *= inverse[f];
                for (int r = 1; r < height; ++r) v[rows[r]] -= panel[r] * y;
                continue;
            }
            std::fill(below, below + tail, 0.0);
            for (int j = 0; j < w; ++j) {
                const double* column = panel + static_cast<std::ptrdiff_t>(j) * height;
                const double y = v[f + j] *= inverse[f + j];
                for (int r = j + 1; r < w; ++r) v[f + r] -= column[r] * y;
                for (int r = 0; r < tail; ++r) below[r] += column[w + r] * y;
            }
            for (int r = 0; r < tail; ++r) v[rows[w + r]] -= below[r];
        }
        for (int s = supernodes - 1; s >= 0; --s) {  // L^T x = y
            const int f = first_[s], w = first_[s + 1] - f;
            const int* rows = rows_.data() + rows_start_[s];
            const int height = rows_start_[s + 1] - rows_start_[s], tail = height - w;
            const double* panel = values_.data() + value_start_[s];
            for (int r = 0; r < tail; ++r) below[r] = v[rows[w + r]];
            for (int j = w - 1; j >= 0; --j) {
                const double* column = panel + static_cast<std::ptrdiff_t>(j) * height;
                double sum[4] = {v[f + j], 0.0, 0.0, 0.0};
                int r = 0;
                for (; r + 4 <= tail; r += 4)
                    for (int k = 0; k < 4; ++k) sum[k] -= column[w + r + k] * below[r + k];
                for (; r < tail; ++r) sum[0] -= column[w + r] * below[r];
                for (int q = j + 1; q < w; ++q) sum[1] -= column[q] * v[f + q];
                v[f + j] = ((sum[0] + sum[1]) + (sum[2] + sum[3])) * inverse[f + j];
            }
        }
    }

    /// Multiply-adds of the factorisation (sum over the columns of L of their squared
    /// counts): what an order costs.
    double flops() const { return flops_; }

    bool analysed() const { return analysed_; }
    void reset() { analysed_ = false; }
    /// Non-zeros of L (diagonal included, panels' explicit zeros too).
    std::size_t factorSize() const { return values_.size(); }

private:
    static constexpr int kRelaxedWidth = 32;
    static constexpr double kRelaxedZeros = 0.25;
    using Panel = Eigen::Map<Eigen::MatrixXd>;
    using ConstPanel = Eigen::Map<const Eigen::MatrixXd>;

    /// Calls f(i, j, p) for every entry of the matrix's lower triangle (i >= j), p its
    /// index in a's values.
    template <class F>
    void forEntry(const Matrix& a, F&& f) const {
        const int* outer = a.outerIndexPtr();
        const int* inner = a.innerIndexPtr();
        for (int col = 0; col < a.cols(); ++col)
            for (int p = outer[col]; p < outer[col + 1]; ++p) {
                const int row = inner[p];
                if (row >= col) f(row, col, p);
            }
    }

    /// The entries (i, j, p) of the columns j in [begin, end) of the lower triangle.
    template <class F>
    static void lowerColumn(const Matrix& a, int begin, int end, F&& f) {
        const int* outer = a.outerIndexPtr();
        const int* inner = a.innerIndexPtr();
        for (int col = begin; col < end; ++col)
            for (int p = outer[col]; p < outer[col + 1]; ++p)
                if (inner[p] >= col) f(inner[p], col, p);
    }

    int n_ = 0, nnz_ = 0;
    bool analysed_ = false;
    double flops_ = 0.0;
    std::vector<int> pattern_outer_, pattern_inner_;
    std::vector<int> parent_;
    std::vector<int> first_;          ///< per supernode + 1: first column
    std::vector<int> snode_of_;       ///< per column: its supernode
    std::vector<int> rows_start_;     ///< per supernode + 1: first entry of its rows in rows_
    std::vector<int> rows_;           ///< per supernode: its rows (its own columns first), sorted
    std::vector<std::size_t> value_start_;  ///< per supernode + 1: its panel in values_
    std::vector<double> values_;      ///< the panels of L, column-major
    std::vector<std::ptrdiff_t> map_; ///< per entry of A: its place in values_, or -1 (other triangle)
    std::vector<double> inverse_diagonal_;  ///< per column: 1 / L_jj (solveInPlace)
    mutable std::vector<double> solve_scratch_;  ///< a panel's rows below its diagonal block (solveInPlace)
    std::vector<int> rel_;            ///< a descendant's rows: their positions in the current panel
    std::vector<double*> target_;     ///< a descendant's first rows: their columns in the current panel
    std::vector<int> where_;          ///< per row: its position in the current panel
    std::vector<int> link_, head_, cursor_;  ///< left-looking: descendants waiting per supernode
};

}  // namespace tearables::detail
