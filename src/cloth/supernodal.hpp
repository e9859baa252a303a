// A supernodal sparse Cholesky factorisation A = L L^T for the cloth's two solves (the
// strain limiter's Newton Hessian and the tension normal equations), without BLAS or threads.
//
// Eigen's SimplicialLDLT updates one column at a time with scalar, index-chasing loops.
// On a weave numbered in nested-dissection order (gridDissection) the columns of L come in
// runs with the same structure below the diagonal (supernodes: the separators, and the 3
// unknowns of a vertex); a supernode's columns are stored as one dense column-major panel,
// and every update from a descendant is one dense product scattered into the panel (our
// own kernel, updateProduct: Eigen's GEMM runs SSE2 in this build and its dispatch costs
// more than the arithmetic of the many narrow panels; the AVX2 variant is chosen at run
// time and gives the same bits), the panel's diagonal block a dense LLT and the rest a
// dense triangular solve (Eigen's):
// the standard left-looking supernodal method (Ng and Peyton 1993; Davis, "Direct Methods
// for Sparse Linear Systems", 2006, ch. 4 for the elimination tree and the row patterns).
//
// The symbolic analysis (elimination tree, pattern of L, supernodes, where each entry of A
// goes) depends on the pattern of A only and is kept while the pattern is the same. The
// matrix must be symmetric positive definite (both cloth matrices are: masses over h^2 or
// lambda' I plus positive semi-definite terms); factorize() says false otherwise, and the
// caller falls back to LDL^T. No pivoting: the order is the one given.
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

/// c (r x r1, column-major) = a b^T with a = the r x w block at `a` and b its first r1
/// rows (column-major, leading dimension `lda`). Every entry is the sum over the w
/// columns in column order, one multiply and one add at a time (no FMA), whatever the
/// kernel: the AVX2 one (four rows at once) and the portable one give the same bits.
template <bool kWide>
__attribute__((always_inline)) inline void updateProductBody(const double* a, int lda, int w, int r, int r1, double* c) {
    int i = 0;
    if constexpr (kWide) {
        for (; i + 4 <= r; i += 4) {
            int j = 0;
            for (; j + 4 <= r1; j += 4) {  // a 4 x 4 tile in four registers
                Lanes4 c0 = {0, 0, 0, 0}, c1 = c0, c2 = c0, c3 = c0;
                for (int k = 0; k < w; ++k) {
                    const double* column = a + static_cast<std::ptrdiff_t>(k) * lda;
                    Lanes4 x;
                    std::memcpy(&x, column + i, sizeof x);
                    c0 += x * column[j];
                    c1 += x * column[j + 1];
                    c2 += x * column[j + 2];
                    c3 += x * column[j + 3];
                }
                std::memcpy(c + static_cast<std::ptrdiff_t>(j) * r + i, &c0, sizeof c0);
                std::memcpy(c + static_cast<std::ptrdiff_t>(j + 1) * r + i, &c1, sizeof c1);
                std::memcpy(c + static_cast<std::ptrdiff_t>(j + 2) * r + i, &c2, sizeof c2);
                std::memcpy(c + static_cast<std::ptrdiff_t>(j + 3) * r + i, &c3, sizeof c3);
            }
            for (; j < r1; ++j) {
                Lanes4 acc = {0, 0, 0, 0};
                for (int k = 0; k < w; ++k) {
                    const double* column = a + static_cast<std::ptrdiff_t>(k) * lda;
                    Lanes4 x;
                    std::memcpy(&x, column + i, sizeof x);
                    acc += x * column[j];
                }
                std::memcpy(c + static_cast<std::ptrdiff_t>(j) * r + i, &acc, sizeof acc);
            }
        }
    }
    for (; i < r; ++i)
        for (int j = 0; j < r1; ++j) {
            double acc = 0.0;
            for (int k = 0; k < w; ++k) {
                const double* column = a + static_cast<std::ptrdiff_t>(k) * lda;
                acc += column[i] * column[j];
            }
            c[static_cast<std::ptrdiff_t>(j) * r + i] = acc;
        }
}

inline void updateProductPortable(const double* a, int lda, int w, int r, int r1, double* c) {
    updateProductBody<false>(a, lda, w, r, r1, c);
}

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
__attribute__((target("avx2"))) inline void updateProductAvx2(const double* a, int lda, int w, int r, int r1, double* c) {
    updateProductBody<true>(a, lda, w, r, r1, c);
}
inline bool haveAvx2() {
    static const bool have = __builtin_cpu_supports("avx2");
    return have;
}
#else
inline void updateProductAvx2(const double* a, int lda, int w, int r, int r1, double* c) {
    updateProductBody<false>(a, lda, w, r, r1, c);
}
inline bool haveAvx2() { return false; }
#endif

}  // namespace supernodal

/// See supernodal::updateProductBody.
inline void updateProduct(const double* a, int lda, int w, int r, int r1, double* c) {
    if (supernodal::haveAvx2())
        supernodal::updateProductAvx2(a, lda, w, r, r1, c);
    else
        supernodal::updateProductPortable(a, lda, w, r, r1, c);
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
        std::size_t scratch = 0;
        for (int s = 0; s < supernodes; ++s) {
            const std::size_t height = static_cast<std::size_t>(rows_start_[s + 1] - rows_start_[s]);
            scratch = std::max(scratch, height * height);
        }
        update_.resize(scratch);
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
                    // product is a single multiply, subtracted in place without the scratch
                    // (the kernel gives 0 + a_i a_j: the same bits, up to the sign of a zero).
                    const double* from = dpanel.data() + p1;
                    const int* at = drows + p1;
                    for (int jj = 0; jj < r1; ++jj) {
                        double* column = panel.data() + static_cast<std::ptrdiff_t>(at[jj] - f) * height;
                        const double aj = from[jj];
                        for (int ii = jj; ii < r; ++ii) column[where_[at[ii]]] -= from[ii] * aj;
                    }
                } else {
                    Eigen::Map<Eigen::MatrixXd> c(update_.data(), r, r1);
                    updateProduct(dpanel.data() + p1, dheight, dw, r, r1, c.data());
                    for (int jj = 0; jj < r1; ++jj) {
                        double* column = panel.data() + static_cast<std::ptrdiff_t>(drows[p1 + jj] - f) * height;
                        const double* from = c.data() + static_cast<std::ptrdiff_t>(jj) * r;
                        for (int ii = jj; ii < r; ++ii) column[where_[drows[p1 + ii]]] -= from[ii];
                    }
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
            if (w == 1) {  // most panels of the tension's matrix: what Eigen's kernels do, without their dispatch
                double* column = panel.data();
                if (!(column[0] > 0.0)) return false;
                column[0] = std::sqrt(column[0]);
                if (!std::isfinite(column[0])) return false;
                const double inverse = 1.0 / column[0];  // as Eigen's triangular solve: a multiply by the reciprocal
                inverse_diagonal_[f] = inverse;
                for (int r = 1; r < height; ++r) column[r] *= inverse;
                if (height > 1) {
                    cursor_[s] = 1;
                    const int t = snode_of_[rows[1]];
                    link_[s] = head_[t];
                    head_[t] = s;
                }
                continue;
            }
            auto diagonal = panel.topRows(w);
            if (Eigen::internal::llt_inplace<double, Eigen::Lower>::blocked(diagonal) >= 0) return false;
            for (int j = 0; j < w; ++j) {
                if (!(diagonal(j, j) > 0.0) || !std::isfinite(diagonal(j, j))) return false;
                inverse_diagonal_[f + j] = 1.0 / diagonal(j, j);
            }
            if (height > w) {
                auto below = panel.bottomRows(height - w);
                diagonal.adjoint().template triangularView<Eigen::Upper>().template solveInPlace<Eigen::OnTheRight>(below);
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
    std::vector<double> update_;      ///< scratch of one update product
    std::vector<double> inverse_diagonal_;  ///< per column: 1 / L_jj (solveInPlace)
    mutable std::vector<double> solve_scratch_;  ///< a panel's rows below its diagonal block (solveInPlace)
    std::vector<int> where_;          ///< per row: its position in the current panel
    std::vector<int> link_, head_, cursor_;  ///< left-looking: descendants waiting per supernode
};

}  // namespace tearables::detail
