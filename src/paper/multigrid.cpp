// Paper sheets: a smoothed aggregation multigrid preconditioner for the implicit solve
// (PaperSolver::Multigrid).
//
// The system W dv = b (implicit.cpp) is, on the free vertices,
//   W = M + A_lent + sum over live springs s of (e_a - e_b)(e_a - e_b)^T (x) B_s,
//   B_s = iso I + along d d^T,
// a graph Laplacian of the springs with 3x3 weights plus a small mass. A stiff sheet's
// masses are ~1e-6 of h^2 k, so its smooth modes (long waves, nearly translations of
// patches) have tiny eigenvalues that block-Jacobi does not touch. Smoothed aggregation
// (Vanek, Mandel and Brezina, "Algebraic multigrid by smoothed aggregation for second and
// fourth order elliptic problems", Computing 56, 1996) gives them coarse levels:
// - Aggregates: the vertices are grouped along the strong springs (structural, auxiliary
//   and hinge springs; bending springs are b = 0.05 of them, weak by the usual measure
//   |a_ij| / sqrt(a_ii a_jj) < 0.08, and left out), with the paper's three passes (a
//   vertex and its untaken neighbours; the rest join a neighbour's aggregate; what is left
//   makes its own). A torn sheet's pieces share no strong spring and so no aggregate.
//   Held vertices are Dirichlet rows: in no aggregate, zero rows of the prolongator.
// - Near-null space: the three translations (an aggregate's nodes move together), so the
//   prolongator is a scalar matrix times the 3x3 identity, P = p (x) I.
// - Smoothing of the tentative p: p = (I - omega D^-1 L) p_tent with L the strong springs'
//   scalar Laplacian weighted by stiffness (the "filtered matrix" of the paper, built from
//   the topology only: it does not change with the sheet's shape, so p is kept until the
//   springs or the held vertices change), omega = 4 / (3 rho), rho bounded by Gershgorin.
//   The next levels aggregate and smooth the Galerkin Laplacians p^T L p alike.
// - Coarse operators: Galerkin, A_{l+1} = P^T A_l P, recomputed each step from the step's
//   blocks (the spring terms are (p_a - p_b)(p_a - p_b)^T (x) B_s; the products' terms are
//   listed once per topology, so a step only multiplies and adds, and allocates nothing).
// - Smoothers: one block Gauss-Seidel sweep (3x3 blocks) before and one in the reverse
//   order after the coarse correction, at every level; the coarsest level (at most
//   kDenseNodes nodes) is solved by a dense Cholesky factor. The V-cycle is then a
//   symmetric positive definite operator (the pre- and post-smoother are each other's
//   adjoint, Gauss-Seidel converges on an SPD matrix, and P^T A P is SPD for P of full
//   column rank), as the conjugate gradient needs: the answer is the solve's to the
//   tolerance, whatever the hierarchy (a poor hierarchy only costs iterations).
#include "paper/sheet.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <utility>

namespace tearables::detail {

namespace {


/// The coarsest level is factorised dense when it has at most this many nodes (3 unknowns
/// each): (3 * 48)^3 / 3 = 1e6 flops a step.
constexpr std::size_t kDenseNodes = 48;
/// At most this many levels below the vertices.
constexpr int kMaxLevels = 8;
/// Strength of a coarse Laplacian's connection: |L_ij| >= theta sqrt(L_ii L_jj) (the
/// paper's epsilon = 0.08, halved per level).
constexpr double kStrength = 0.08;
/// Block Gauss-Seidel sweeps that stand in for the coarsest solve when it is too large to
/// factorise (the aggregation stalled: many disconnected pieces).
constexpr int kCoarsestSweeps = 4;

using SparseRow = Eigen::SparseMatrix<double, Eigen::RowMajor>;

/// Greedy aggregation (Vanek et al. 1996, Sec. 3) of the nodes with `in` set, along the
/// strong graph (CSR: start, adjacency, weight). Returns the aggregate count; agg[i] = -1
/// for nodes not in.
int aggregate(const std::vector<std::uint8_t>& in, const std::vector<int>& start, const std::vector<int>& adj,
              const std::vector<double>& weight, std::vector<int>& agg) {
    const int n = static_cast<int>(in.size());
    agg.assign(n, -1);
    int count = 0;
    // Pass 1: a node whose strong neighbours are all untaken makes an aggregate with them.
    for (int i = 0; i < n; ++i) {
        if (!in[i] || agg[i] >= 0) continue;
        bool free = true;
        for (int k = start[i]; k < start[i + 1] && free; ++k) free = agg[adj[k]] < 0;
        if (!free) continue;
        agg[i] = count;
        for (int k = start[i]; k < start[i + 1]; ++k) agg[adj[k]] = count;
        ++count;
    }
    // Pass 2: a node left joins the aggregate of its most strongly tied neighbour (as pass
    // 1 left them, so that aggregates do not grow in chains).
    const std::vector<int> first = agg;
    for (int i = 0; i < n; ++i) {
        if (!in[i] || agg[i] >= 0) continue;
        double best = -1.0;
        for (int k = start[i]; k < start[i + 1]; ++k)
            if (first[adj[k]] >= 0 && weight[k] > best) {
                best = weight[k];
                agg[i] = first[adj[k]];
            }
    }
    // Pass 3: what is left makes aggregates with its untaken neighbours.
    for (int i = 0; i < n; ++i) {
        if (!in[i] || agg[i] >= 0) continue;
        agg[i] = count;
        for (int k = start[i]; k < start[i + 1]; ++k)
            if (agg[adj[k]] < 0) agg[adj[k]] = count;
        ++count;
    }
    return count;
}

/// p = (I - omega D^-1 L) p_tent for a scalar symmetric L (row-major, diagonal present or
/// zero) and the aggregates agg (-1: a Dirichlet node, an empty row). omega = 4 / (3 rho),
/// rho the Gershgorin bound on D^-1 L. A node with no diagonal (isolated) keeps p_tent.
SparseRow smoothedProlongator(const SparseRow& L, const std::vector<int>& agg, int aggregates) {
    const int n = static_cast<int>(L.rows());
    std::vector<double> diag(n, 0.0);
    double rho = 0.0;
    for (int i = 0; i < n; ++i) {
        double off = 0.0;
        for (SparseRow::InnerIterator it(L, i); it; ++it)
            if (it.col() == i) diag[i] = it.value();
            else off += std::abs(it.value());
        if (agg[i] >= 0 && diag[i] > 0.0) rho = std::max(rho, 1.0 + off / diag[i]);
    }
    const double omega = rho > 0.0 ? 4.0 / (3.0 * rho) : 0.0;
    std::vector<Eigen::Triplet<double>> triplets;
    std::vector<std::pair<int, double>> row;
    for (int i = 0; i < n; ++i) {
        if (agg[i] < 0) continue;
        row.clear();
        row.emplace_back(agg[i], 1.0);
        if (diag[i] > 0.0) {
            // -omega / D_i (L p_tent)_i, with (L p_tent)_iI = sum_{j in I} L_ij (j = i too):
            // the own aggregate's sum is D_i + the ties inside it: zero (to rounding) for a
            // node tied only inside its aggregate, which then keeps exactly 1 (and the
            // springs inside an aggregate add nothing to the coarse operator).
            const double scale = omega / diag[i];
            double own_sum = diag[i];
            for (SparseRow::InnerIterator it(L, i); it; ++it) {
                const int j = static_cast<int>(it.col());
                if (j == i) continue;
                if (agg[j] == agg[i]) own_sum += it.value();
                else if (agg[j] >= 0) row.emplace_back(agg[j], -scale * it.value());
            }
            if (std::abs(own_sum) <= 1e-12 * diag[i]) own_sum = 0.0;
            row[0].second = 1.0 - scale * own_sum;
        }
        std::sort(row.begin(), row.end());
        for (std::size_t k = 0; k < row.size();) {
            std::size_t m = k;
            double w = 0.0;
            for (; m < row.size() && row[m].first == row[k].first; ++m) w += row[m].second;
            if (w != 0.0) triplets.emplace_back(i, row[k].first, w);
            k = m;
        }
    }
    SparseRow p(n, aggregates);
    p.setFromTriplets(triplets.begin(), triplets.end());
    return p;
}

/// The strong graph of a scalar Laplacian (coarse levels): |L_ij| >= theta sqrt(L_ii L_jj).
void strongGraph(const SparseRow& L, double theta, std::vector<int>& start, std::vector<int>& adj, std::vector<double>& weight) {
    const int n = static_cast<int>(L.rows());
    std::vector<double> diag(n, 0.0);
    for (int i = 0; i < n; ++i)
        for (SparseRow::InnerIterator it(L, i); it; ++it)
            if (it.col() == i) diag[i] = it.value();
    start.assign(n + 1, 0);
    adj.clear();
    weight.clear();
    for (int i = 0; i < n; ++i) {
        for (SparseRow::InnerIterator it(L, i); it; ++it) {
            const int j = static_cast<int>(it.col());
            if (j == i) continue;
            const double a = std::abs(it.value());
            if (a >= theta * std::sqrt(std::abs(diag[i] * diag[j])) && a > 0.0) {
                adj.push_back(j);
                weight.push_back(a);
            }
        }
        start[i + 1] = static_cast<int>(adj.size());
    }
}

/// A block pattern (per node, sorted distinct neighbour nodes) as a scalar row-major
/// matrix of 3x3 blocks, zero valued; diag_at is filled for each node.
void buildBlockMatrix(const std::vector<std::vector<int>>& blocks, PaperMultigridLevel& level) {
    const int nodes = static_cast<int>(blocks.size());
    std::vector<Eigen::Triplet<double>> triplets;
    for (int I = 0; I < nodes; ++I)
        for (int J : blocks[I])
            for (int r = 0; r < 3; ++r)
                for (int c = 0; c < 3; ++c) triplets.emplace_back(3 * I + r, 3 * J + c, 0.0);
    level.A.resize(3 * nodes, 3 * nodes);
    level.A.setFromTriplets(triplets.begin(), triplets.end());
    level.A.makeCompressed();
    level.diag_at.assign(nodes, 0);
    level.diag_inv.assign(nodes, Mat3::Identity());
    for (int I = 0; I < nodes; ++I) {
        const auto q = std::lower_bound(blocks[I].begin(), blocks[I].end(), I) - blocks[I].begin();
        level.diag_at[I] = static_cast<std::uint32_t>(level.A.outerIndexPtr()[3 * I] + 3 * q);
    }
    level.r.setZero(3 * nodes);
    level.e.setZero(3 * nodes);
    level.t.setZero(3 * nodes);
}

/// Value index of block (I, J) of a level built by buildBlockMatrix, and its row stride.
std::pair<std::uint32_t, std::uint32_t> blockAt(const PaperMultigridLevel& level, const std::vector<std::vector<int>>& blocks, int I, int J) {
    const auto q = std::lower_bound(blocks[I].begin(), blocks[I].end(), J) - blocks[I].begin();
    return {static_cast<std::uint32_t>(level.A.outerIndexPtr()[3 * I] + 3 * q), static_cast<std::uint32_t>(3 * blocks[I].size())};
}

void sortUnique(std::vector<int>& v) {
    std::sort(v.begin(), v.end());
    v.erase(std::unique(v.begin(), v.end()), v.end());
}

/// The hierarchy for the sheet's live springs and held vertices.
void buildHierarchy(PaperSheet& s) {
    PaperMultigrid& mg = s.mg;
    const int n = static_cast<int>(s.vertices());
    mg.prolong.clear();
    mg.levels.clear();
    mg.coarse_terms.clear();
    mg.levels.emplace_back();  // level 0: the vertices, matrix-free
    mg.t.assign(n, Vec3::Zero());
    mg.fixed = s.fixed;
    mg.rows_version = s.rows_version;
    mg.built = true;
    mg.coarsest_sweeps = 0;

    // The strong springs' scalar Laplacian on the free vertices (held ties on the diagonal).
    std::vector<std::uint8_t> in(n);
    for (int i = 0; i < n; ++i) in[i] = !s.fixed[i];
    std::vector<Eigen::Triplet<double>> triplets;
    for (const PaperSpring& sp : s.springs) {
        if (sp.broken || sp.kind == PaperSpringKind::Bending || sp.a == sp.b) continue;
        const double w = sp.stiffness;
        if (in[sp.a]) triplets.emplace_back(sp.a, sp.a, w);
        if (in[sp.b]) triplets.emplace_back(sp.b, sp.b, w);
        if (in[sp.a] && in[sp.b]) {
            triplets.emplace_back(sp.a, sp.b, -w);
            triplets.emplace_back(sp.b, sp.a, -w);
        }
    }
    SparseRow L(n, n);
    L.setFromTriplets(triplets.begin(), triplets.end());
    std::vector<int> start, adj, agg;
    std::vector<double> weight;
    {
        start.assign(n + 1, 0);
        for (int i = 0; i < n; ++i) {
            for (SparseRow::InnerIterator it(L, i); it; ++it)
                if (it.col() != i && it.value() != 0.0) {
                    adj.push_back(static_cast<int>(it.col()));
                    weight.push_back(-it.value());
                }
            start[i + 1] = static_cast<int>(adj.size());
        }
    }
    std::vector<std::vector<int>> prev_blocks;  // the block pattern of the level above (coarse levels)
    for (int l = 0; l < kMaxLevels; ++l) {
        const int fine_nodes = static_cast<int>(in.size());
        const int coarse = aggregate(in, start, adj, weight, agg);
        if (coarse == 0 || (l > 0 && coarse >= fine_nodes)) break;  // nothing free, or the aggregation stalled
        mg.prolong.push_back(smoothedProlongator(L, agg, coarse));
        const SparseRow& p = mg.prolong.back();
        // The coarse level's block pattern and the Galerkin terms into it.
        std::vector<std::vector<int>> blocks(coarse);
        auto rowOf = [&](int i, std::vector<std::pair<int, double>>& out) {
            out.clear();
            for (SparseRow::InnerIterator it(p, i); it; ++it) out.emplace_back(static_cast<int>(it.col()), it.value());
        };
        std::vector<std::pair<int, double>> pa, pb, g;
        auto difference = [&](int a, int b) {  // g = p_a - p_b, exact zeros dropped
            rowOf(a, pa);
            rowOf(b, pb);
            g.clear();
            std::size_t x = 0, y = 0;
            while (x < pa.size() || y < pb.size()) {
                if (y == pb.size() || (x < pa.size() && pa[x].first < pb[y].first)) g.push_back(pa[x++]);
                else if (x == pa.size() || pb[y].first < pa[x].first) {
                    g.emplace_back(pb[y].first, -pb[y].second);
                    ++y;
                } else {
                    const double w = pa[x].second - pb[y].second;
                    if (w != 0.0) g.emplace_back(pa[x].first, w);
                    ++x;
                    ++y;
                }
            }
        };
        PaperMultigridLevel level;
        if (l == 0) {
            for (const auto& [a, b] : s.link_ends) {
                difference(static_cast<int>(a), static_cast<int>(b));
                for (const auto& [I, wi] : g)
                    for (const auto& [J, wj] : g) blocks[I].push_back(J);
            }
            for (int i = 0; i < n; ++i) {
                rowOf(i, pa);
                for (const auto& [I, wi] : pa)
                    for (const auto& [J, wj] : pa) blocks[I].push_back(J);
            }
            for (auto& b : blocks) sortUnique(b);
            buildBlockMatrix(blocks, level);
            mg.spring_term_start.assign(s.link_ends.size() + 1, 0);
            mg.spring_terms.clear();
            for (std::size_t k = 0; k < s.link_ends.size(); ++k) {
                difference(static_cast<int>(s.link_ends[k][0]), static_cast<int>(s.link_ends[k][1]));
                for (const auto& [I, wi] : g)
                    for (const auto& [J, wj] : g) {
                        const auto [at, stride] = blockAt(level, blocks, I, J);
                        mg.spring_terms.push_back({at, stride, 0, 0, wi * wj});
                    }
                mg.spring_term_start[k + 1] = static_cast<std::uint32_t>(mg.spring_terms.size());
            }
            mg.mass_term_start.assign(n + 1, 0);
            mg.mass_terms.clear();
            for (int i = 0; i < n; ++i) {
                rowOf(i, pa);
                for (const auto& [I, wi] : pa)
                    for (const auto& [J, wj] : pa) {
                        const auto [at, stride] = blockAt(level, blocks, I, J);
                        mg.mass_terms.push_back({at, stride, 0, 0, wi * wj});
                    }
                mg.mass_term_start[i + 1] = static_cast<std::uint32_t>(mg.mass_terms.size());
            }
        } else {
            const PaperMultigridLevel& above = mg.levels[l];
            for (int i = 0; i < fine_nodes; ++i) {
                rowOf(i, pa);
                for (int j : prev_blocks[i]) {
                    rowOf(j, pb);
                    for (const auto& [I, wi] : pa)
                        for (const auto& [J, wj] : pb) blocks[I].push_back(J);
                }
            }
            for (auto& b : blocks) sortUnique(b);
            buildBlockMatrix(blocks, level);
            std::vector<PaperGalerkinTerm> terms;
            for (int i = 0; i < fine_nodes; ++i) {
                rowOf(i, pa);
                for (int j : prev_blocks[i]) {
                    rowOf(j, pb);
                    const auto [source, source_stride] = blockAt(above, prev_blocks, i, j);
                    for (const auto& [I, wi] : pa)
                        for (const auto& [J, wj] : pb) {
                            const auto [at, stride] = blockAt(level, blocks, I, J);
                            terms.push_back({at, stride, source, source_stride, wi * wj});
                        }
                }
            }
            mg.coarse_terms.resize(l + 1);
            mg.coarse_terms[l] = std::move(terms);
        }
        mg.levels.push_back(std::move(level));
        prev_blocks = std::move(blocks);
        if (static_cast<std::size_t>(coarse) <= kDenseNodes) break;
        // The next level's auxiliary Laplacian and strong graph.
        const SparseRow pt = p.transpose();
        const SparseRow Lp = L * p;
        L = SparseRow(pt * Lp);
        in.assign(coarse, 1);
        strongGraph(L, kStrength * std::pow(0.5, l + 1), start, adj, weight);
    }
    const std::size_t last = mg.levels.size() - 1;
    if (last >= 1) {
        const std::size_t nodes = mg.levels[last].A.rows() / 3;
        if (nodes <= kDenseNodes) {
            mg.dense.setZero(3 * nodes, 3 * nodes);
            mg.dense_llt = Eigen::LLT<Eigen::MatrixXd>(3 * static_cast<Eigen::Index>(nodes));
        } else {
            mg.coarsest_sweeps = kCoarsestSweeps;
        }
    }
}

/// Adds c B (B = iso I + along d d^T) into the block at `at` (row stride `stride`).
inline void addSpringBlock(double* values, std::uint32_t at, std::uint32_t stride, double c, double iso, double along, const Vec3& d) {
    const double ca = c * along;
    for (int r = 0; r < 3; ++r) {
        double* row = values + at + r * stride;
        const double u = ca * d[r];
        row[0] += u * d[0];
        row[1] += u * d[1];
        row[2] += u * d[2];
        row[r] += c * iso;
    }
}

inline void addBlock(double* values, std::uint32_t at, std::uint32_t stride, double c, const Mat3& m) {
    for (int r = 0; r < 3; ++r) {
        double* row = values + at + r * stride;
        row[0] += c * m(r, 0);
        row[1] += c * m(r, 1);
        row[2] += c * m(r, 2);
    }
}

/// The diagonal blocks' inverses of a level (block Gauss-Seidel).
void invertDiagonal(PaperMultigridLevel& level) {
    const double* values = level.A.valuePtr();
    const std::size_t nodes = level.diag_at.size();
    for (std::size_t I = 0; I < nodes; ++I) {
        const std::uint32_t at = level.diag_at[I];
        const std::uint32_t stride = static_cast<std::uint32_t>(level.A.outerIndexPtr()[3 * I + 1] - level.A.outerIndexPtr()[3 * I]);
        Mat3 m;
        for (int r = 0; r < 3; ++r)
            for (int c = 0; c < 3; ++c) m(r, c) = values[at + r * stride + c];
        level.diag_inv[I] = m.inverse();
    }
}

/// One block Gauss-Seidel sweep on a coarse level, A e = r, forward or backward:
/// e_I <- e_I + A_II^-1 (r_I - (A e)_I).
void coarseSweep(PaperMultigridLevel& level, bool forward) {
    const Eigen::Index nodes = static_cast<Eigen::Index>(level.diag_at.size());
    const int* outer = level.A.outerIndexPtr();
    const int* inner = level.A.innerIndexPtr();
    const double* values = level.A.valuePtr();
    double* e = level.e.data();
    const double* r = level.r.data();
    for (Eigen::Index step = 0; step < nodes; ++step) {
        const Eigen::Index I = forward ? step : nodes - 1 - step;
        Vec3 res;
        for (int row = 0; row < 3; ++row) {
            double sum = r[3 * I + row];
            for (int k = outer[3 * I + row]; k < outer[3 * I + row + 1]; ++k) sum -= values[k] * e[inner[k]];
            res[row] = sum;
        }
        const Vec3 de = level.diag_inv[I] * res;
        e[3 * I] += de[0];
        e[3 * I + 1] += de[1];
        e[3 * I + 2] += de[2];
    }
}

/// One block Gauss-Seidel sweep on the vertices, W e = r (matrix-free, the rows of
/// implicit.cpp; held rows stay zero), backward from the given e.
void fineSweepBackward(const PaperSheet& s, const std::vector<Vec3>& r, std::vector<Vec3>& e) {
    const std::size_t n = s.vertices();
    const std::uint32_t* const start = s.vertex_link_start.data();
    const JacobiQuad* const quads = s.row_quads.data();
    for (std::size_t step = 0; step < n; ++step) {
        const std::size_t i = n - 1 - step;
        if (s.fixed[i]) continue;
        Vec3 sum = r[i];  // r_i - sum_{j != i} W_ij e_j, W_ij = -(iso I + along d d^T)
        for (std::uint32_t j = start[i]; j < start[i + 1]; ++j) {
            const JacobiQuad& c = quads[j >> 2];
            const unsigned lane = j & 3u;
            const std::uint32_t other = c.other[lane];
            if (other == i) continue;  // a pad
            const Vec3 d(c.dir_x[lane], c.dir_y[lane], c.dir_z[lane]);
            const Vec3& o = e[other];
            sum += c.iso[lane] * o + (c.along[lane] * d.dot(o)) * d;
        }
        e[i] = s.diag_inv[i] * sum;
    }
}

/// The forward block Gauss-Seidel sweep from e = 0, and the residual it leaves,
/// res = r - W e, without a product with W: vertex i solves its row with the e_j, j < i,
/// of this sweep and zero for j > i, so W_ii e_i = r_i - sum_{j < i} W_ij e_j and
/// res_i = -sum_{j > i} W_ij e_j = sum_{j > i} B_ij e_j: each e_i, once known, is added
/// through its row's blocks into the residuals of its neighbours before it (B symmetric).
void fineSweepForwardFromZero(const PaperSheet& s, const std::vector<Vec3>& r, std::vector<Vec3>& e, std::vector<Vec3>& res) {
    const std::size_t n = s.vertices();
    const std::uint32_t* const start = s.vertex_link_start.data();
    const JacobiQuad* const quads = s.row_quads.data();
    for (std::size_t i = 0; i < n; ++i) {
        e[i].setZero();
        res[i].setZero();
    }
    for (std::size_t i = 0; i < n; ++i) {
        if (s.fixed[i]) continue;
        Vec3 sum = r[i];
        for (std::uint32_t j = start[i]; j < start[i + 1]; ++j) {
            const JacobiQuad& c = quads[j >> 2];
            const unsigned lane = j & 3u;
            const std::uint32_t other = c.other[lane];
            if (other >= i) continue;  // a pad, or e_other still zero
            const Vec3 d(c.dir_x[lane], c.dir_y[lane], c.dir_z[lane]);
            const Vec3& o = e[other];
            sum += c.iso[lane] * o + (c.along[lane] * d.dot(o)) * d;
        }
        const Vec3 x = s.diag_inv[i] * sum;
        e[i] = x;
        for (std::uint32_t j = start[i]; j < start[i + 1]; ++j) {
            const JacobiQuad& c = quads[j >> 2];
            const unsigned lane = j & 3u;
            const std::uint32_t other = c.other[lane];
            if (other >= i || s.fixed[other]) continue;
            const Vec3 d(c.dir_x[lane], c.dir_y[lane], c.dir_z[lane]);
            res[other] += c.iso[lane] * x + (c.along[lane] * d.dot(x)) * d;
        }
    }
}

/// The forward block Gauss-Seidel sweep from e = 0 on a coarse level, and the residual it
/// leaves in level.t, as on the vertices (fineSweepForwardFromZero): row I solves with the
/// e_J, J < I, of this sweep (the blocks right of the diagonal meet zeros and are skipped),
/// and its residual is then -sum_{J > I} A_IJ e_J, a pass over those blocks alone.
void coarseSweepForwardFromZero(PaperMultigridLevel& level) {
    const Eigen::Index nodes = static_cast<Eigen::Index>(level.diag_at.size());
    const int* outer = level.A.outerIndexPtr();
    const int* inner = level.A.innerIndexPtr();
    const double* values = level.A.valuePtr();
    double* e = level.e.data();
    const double* r = level.r.data();
    double* t = level.t.data();
    for (Eigen::Index I = 0; I < nodes; ++I) {
        Vec3 res;
        for (int row = 0; row < 3; ++row) {
            double sum = r[3 * I + row];
            for (int k = outer[3 * I + row]; k < outer[3 * I + row + 1] && inner[k] < 3 * I; ++k) sum -= values[k] * e[inner[k]];
            res[row] = sum;
        }
        const Vec3 x = level.diag_inv[I] * res;
        e[3 * I] = x[0];
        e[3 * I + 1] = x[1];
        e[3 * I + 2] = x[2];
    }
    for (Eigen::Index I = 0; I < nodes; ++I)
        for (int row = 0; row < 3; ++row) {
            double sum = 0.0;
            const int end = outer[3 * I + row + 1];
            // The three rows of a node have the same columns: the diagonal block sits as far
            // into each as into the first; start right of it.
            int k = outer[3 * I + row] + (static_cast<int>(level.diag_at[I]) - outer[3 * I]) + 3;
            for (; k < end; ++k) sum -= values[k] * e[inner[k]];
            t[3 * I + row] = sum;
        }
}

/// The V-cycle below the vertices, from level l (l >= 1): level.r given, level.e out.
void coarseCycle(PaperMultigrid& mg, std::size_t l) {
    PaperMultigridLevel& level = mg.levels[l];
    if (l + 1 == mg.levels.size()) {
        if (mg.coarsest_sweeps == 0 && mg.dense_ok) {
            level.e = level.r;
            mg.dense_llt.solveInPlace(level.e);
        } else {
            level.e.setZero();
            const int sweeps = std::max(mg.coarsest_sweeps, 1);
            for (int k = 0; k < sweeps; ++k) coarseSweep(level, true);
            for (int k = 0; k < sweeps; ++k) coarseSweep(level, false);
        }
        return;
    }
    coarseSweepForwardFromZero(level);
    PaperMultigridLevel& next = mg.levels[l + 1];
    const SparseRow& p = mg.prolong[l];
    next.r.setZero();
    for (Eigen::Index i = 0; i < p.rows(); ++i)
        for (SparseRow::InnerIterator it(p, i); it; ++it) next.r.segment<3>(3 * it.col()) += it.value() * level.t.segment<3>(3 * i);
    coarseCycle(mg, l + 1);
    for (Eigen::Index i = 0; i < p.rows(); ++i)
        for (SparseRow::InnerIterator it(p, i); it; ++it) level.e.segment<3>(3 * i) += it.value() * next.e.segment<3>(3 * it.col());
    coarseSweep(level, false);
}

}  // namespace

void multigridSetup(PaperSheet& s) {
    PaperMultigrid& mg = s.mg;
    if (!mg.built || mg.rows_version != s.rows_version || mg.fixed != s.fixed) buildHierarchy(s);
    if (mg.levels.size() < 2) return;
    // Level 1 = P^T W P from the springs' blocks (rows of implicit.cpp) and the masses.
    PaperMultigridLevel& first = mg.levels[1];
    double* values = first.A.valuePtr();
    std::fill(values, values + first.A.nonZeros(), 0.0);
    for (std::size_t k = 0; k < s.link_slot.size(); ++k) {
        const std::uint32_t slot = s.link_slot[k][0];
        const JacobiQuad& c = s.row_quads[slot >> 2];
        const unsigned lane = slot & 3u;
        const Vec3 d(c.dir_x[lane], c.dir_y[lane], c.dir_z[lane]);
        for (std::uint32_t t = mg.spring_term_start[k]; t < mg.spring_term_start[k + 1]; ++t) {
            const PaperGalerkinTerm& term = mg.spring_terms[t];
            addSpringBlock(values, term.target, term.target_stride, term.coef, c.iso[lane], c.along[lane], d);
        }
    }
    for (std::size_t i = 0; i < s.vertices(); ++i) {
        if (mg.mass_term_start[i] == mg.mass_term_start[i + 1]) continue;
        const Mat3 m = s.mass[i] * Mat3::Identity() + s.added_mass[i];
        for (std::uint32_t t = mg.mass_term_start[i]; t < mg.mass_term_start[i + 1]; ++t) {
            const PaperGalerkinTerm& term = mg.mass_terms[t];
            addBlock(values, term.target, term.target_stride, term.coef, m);
        }
    }
    invertDiagonal(first);
    for (std::size_t l = 1; l + 1 < mg.levels.size(); ++l) {
        const double* source = mg.levels[l].A.valuePtr();
        PaperMultigridLevel& next = mg.levels[l + 1];
        double* target = next.A.valuePtr();
        std::fill(target, target + next.A.nonZeros(), 0.0);
        for (const PaperGalerkinTerm& term : mg.coarse_terms[l])
            for (int r = 0; r < 3; ++r) {
                const double* from = source + term.source + r * term.source_stride;
                double* to = target + term.target + r * term.target_stride;
                to[0] += term.coef * from[0];
                to[1] += term.coef * from[1];
                to[2] += term.coef * from[2];
            }
        invertDiagonal(next);
    }
    if (mg.coarsest_sweeps == 0) {
        const PaperMultigridLevel& last = mg.levels.back();
        mg.dense.setZero();
        for (Eigen::Index i = 0; i < last.A.outerSize(); ++i)
            for (SparseRow::InnerIterator it(last.A, i); it; ++it) mg.dense(i, it.col()) = it.value();
        mg.dense_llt.compute(mg.dense);
        mg.dense_ok = mg.dense_llt.info() == Eigen::Success;
    }
}

void multigridPrecondition(PaperSheet& s, const std::vector<Vec3>& r, std::vector<Vec3>& z) {
    PaperMultigrid& mg = s.mg;
    const std::size_t n = s.vertices();
    fineSweepForwardFromZero(s, r, z, mg.t);
    if (mg.levels.size() >= 2) {
        PaperMultigridLevel& next = mg.levels[1];
        const SparseRow& p = mg.prolong[0];
        next.r.setZero();
        for (std::size_t i = 0; i < n; ++i)
            for (SparseRow::InnerIterator it(p, static_cast<Eigen::Index>(i)); it; ++it)
                next.r.segment<3>(3 * it.col()) += it.value() * mg.t[i];
        coarseCycle(mg, 1);
        for (std::size_t i = 0; i < n; ++i)
            for (SparseRow::InnerIterator it(p, static_cast<Eigen::Index>(i)); it; ++it)
                z[i] += it.value() * next.e.segment<3>(3 * it.col());
    }
    fineSweepBackward(s, r, z);
}

}  // namespace tearables::detail
