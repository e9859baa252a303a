// Stage: yarn tensions from momentum balance (Yarn, Sec. 3.2), extended from a yarn to
// a woven mesh.
//
// With forward Euler, a free vertex i of mass m_i whose strain-limited motion is x''_i
// must satisfy (papers/README.md: the equations lost in the extraction)
//     m_i (x''_i - x'_i) / h^2 = F_in_i + sum_e T_e s_ie e_e,      s_ie = +1 if i starts e, -1 if it ends it,
// where x'_i is its prediction (external forces already in it), F_in_i the soft shear and
// bending springs at x'' (internal forces, known), e_e the unit direction of yarn e at
// x'' and T_e its unknown tension. All free vertices stacked (3 rows each) give A T = b
// with b_i = m_i (x''_i - x'_i) / h^2 - F_in_i (newtons). Pinned vertices and vertices
// glued to a body carry an unknown support force and give no rows; a vertex a rigid body
// presses has its rows projected across the contact normals (P_i = I - sum n n^T over an
// orthonormal basis of the normals), where the unknown contact force acts.
//
// A mesh has more yarns per vertex than a chain; where the system is not determined
// (self-stress of a flat weave between pins) Yarn takes the Tikhonov-regularised least
// squares  min |A T - b|^2 + lambda |T|^2,  lambda = 1e-6. We scale lambda by the mean
// diagonal of A^T A (dimensionless here, about 2) and assemble the normal equations
// (A^T A + lambda' I) T = A^T b directly per vertex (each vertex couples the yarns that
// meet there: 7 non-zeros per column on a grid), with a pattern fixed per topology, so
// the sparse LDL^T (Eigen's SimplicialLDLT, AMD ordering) analyses once and only
// factorises each step.
//
// Choices where Yarn is vague:
//  - Self-stress. Momentum balance cannot see a stress state that is in equilibrium by
//    itself: a cloth stretched between two clamps, a yarn pulled at both ends by pins.
//    Those tensions lie in the null space of A, and "as small as possible" (Yarn's
//    regularisation towards zero) reports zero: a cloth pulled apart by its clamps would
//    never tear. We regularise towards a prior instead, the tensions the strain limiter's
//    stiff springs carry at x'' (k_e max(0, |d| - L)):
//        min |A T - b|^2 + lambda |T - T_spring|^2.
//    Where the motion determines T (the row space of A) the momentum answer wins, with
//    the bias below; in the null space the constitutive answer fills in.
//  - Bias. Plain Tikhonov pulls every tension towards the prior by about
//    lambda / sigma_min^2 (sigma_min the smallest singular value of A, about 1/n for a
//    chain of n yarns: 3e-4 relative for 20 yarns), so a regularised answer would
//    disagree with the exact one of a consistent system. We iterate the Tikhonov step
//    (iterated Tikhonov / proximal point),  T_{k+1} = (A^T A + lambda' I)^-1 (A^T b + lambda' T_k),
//    warm-started from the prior T_0 (the strain limiter's forces: at rest they already
//    are the answer; they are a better start than the last step's tensions after a tear or
//    a jerk). Each refinement is one back-substitution with the same factor and shrinks
//    the row-space bias by lambda' / (lambda' + sigma^2); the null-space part stays at the
//    prior's. The iteration converges to  T_LS(min norm) + P_null T_spring.
//
// Scaling: the factorisation of a q-yarn mesh costs about O(q^1.5) with nested-dissection
// like fill (AMD on a grid); 100 x 100 vertices (19800 yarns) takes a few milliseconds
// (BENCHMARKS.md). Beyond that, a preconditioned conjugate gradient warm-started from the
// last step would scale linearly per iteration.
#include "cloth/cloth_state.hpp"

#include <algorithm>
#include <cmath>

namespace tearables::detail {

namespace {

constexpr int kMaxRefinements = 12;
constexpr double kRefinementTolerance = 1e-12;

/// P = I - sum n n^T over an orthonormal basis of the normals pressing the vertex.
void pressProjector(ClothState& c) {
    std::fill(c.projector.begin(), c.projector.end(), Mat3::Identity());
    for (const VertexContact& vc : c.contacts) {
        if (!(vc.force > 0.0)) continue;
        Mat3& p = c.projector[vc.vertex];
        const Vec3 n = p * vc.normal;  // the part not yet removed
        const double len = n.norm();
        if (len < 1e-6) continue;
        const Vec3 u = n / len;
        p -= u * u.transpose();
    }
}

/// Builds the pattern of A^T A + lambda' I (lower triangle) for the current topology and
/// remembers, per vertex and pair of its yarns, where the product goes.
void buildPattern(ClothState& c) {
    const std::size_t m = c.edgeCount();
    c.columns.clear();
    for (std::size_t e = 0; e < m; ++e) {
        c.unknown[e] = c.broken[e] ? -1 : static_cast<int>(c.columns.size());
        if (!c.broken[e]) c.columns.push_back(static_cast<std::uint32_t>(e));
    }
    const int q = static_cast<int>(c.columns.size());
    std::vector<Eigen::Triplet<double>> triplets;
    triplets.reserve(static_cast<std::size_t>(q) * 7);
    for (int k = 0; k < q; ++k) triplets.emplace_back(k, k, 0.0);
    for (std::size_t p = 0; p < c.vertices(); ++p) {
        const auto& inc = c.vertex_edges[p];
        for (std::size_t a = 0; a < inc.size(); ++a)
            for (std::size_t b = 0; b < a; ++b) {
                const int ca = c.unknown[inc[a]], cb = c.unknown[inc[b]];
                if (ca < 0 || cb < 0) continue;
                triplets.emplace_back(std::max(ca, cb), std::min(ca, cb), 0.0);
            }
    }
    c.normal_matrix.resize(q, q);
    c.normal_matrix.setFromTriplets(triplets.begin(), triplets.end());
    c.normal_matrix.makeCompressed();
    c.vertex_value_index.assign(c.vertices(), {});
    const double* base = c.normal_matrix.valuePtr();
    for (std::size_t p = 0; p < c.vertices(); ++p) {
        const auto& inc = c.vertex_edges[p];
        auto& idx = c.vertex_value_index[p];
        idx.assign(inc.size() * inc.size(), -1);
        for (std::size_t a = 0; a < inc.size(); ++a)
            for (std::size_t b = 0; b <= a; ++b) {
                const int ca = c.unknown[inc[a]], cb = c.unknown[inc[b]];
                if (ca < 0 || cb < 0) continue;
                idx[a * inc.size() + b] = static_cast<int>(&c.normal_matrix.coeffRef(std::max(ca, cb), std::min(ca, cb)) - base);
            }
    }
    if (!c.tension_solver) c.tension_solver = std::make_unique<Eigen::SimplicialLDLT<SparseMatrix>>();
    c.tension_solver->analyzePattern(c.normal_matrix);
    c.rhs.resize(q);
    c.solution.resize(q);
    c.refine.resize(q);
    c.tension_topology = c.topology;
}

/// s_ie: +1 when vertex p starts edge e, -1 when it ends it.
double side(const ClothState& c, std::size_t p, std::uint32_t e) { return c.edges[e][0] == p ? 1.0 : -1.0; }

}  // namespace

void solveTensionLeastSquares(ClothState& c) {
    if (c.tension_topology != c.topology || c.unknown.size() != c.edgeCount()) buildPattern(c);
    const int q = static_cast<int>(c.columns.size());
    c.tension_iterations = 0;
    c.tension_residual = 0.0;
    if (q == 0) return;
    double* values = c.normal_matrix.valuePtr();
    std::fill(values, values + c.normal_matrix.nonZeros(), 0.0);
    c.rhs.setZero();
    double b_norm2 = 0.0;
    for (std::size_t p = 0; p < c.vertices(); ++p) {
        if (!c.has_row[p]) continue;
        const auto& inc = c.vertex_edges[p];
        const Mat3& proj = c.projector[p];
        const Vec3 b = proj * c.row_rhs[p];
        b_norm2 += b.squaredNorm();
        const auto& idx = c.vertex_value_index[p];
        for (std::size_t a = 0; a < inc.size(); ++a) {
            const std::uint32_t ea = inc[a];
            const int ca = c.unknown[ea];
            if (ca < 0) continue;
            const Vec3 pa = side(c, p, ea) * (proj * c.dir[ea]);
            c.rhs[ca] += pa.dot(b);
            for (std::size_t k = 0; k <= a; ++k) {
                const int at = idx[a * inc.size() + k];
                if (at < 0) continue;
                const std::uint32_t eb = inc[k];
                values[at] += pa.dot(side(c, p, eb) * (proj * c.dir[eb]));  // P symmetric and idempotent
            }
        }
    }
    double mean_diag = 0.0;
    for (int k = 0; k < q; ++k) mean_diag += c.normal_matrix.coeff(k, k);
    mean_diag /= q;
    // Tikhonov lambda relative to the mean diagonal; a column no row sees (a yarn between
    // two pins) is held at zero by a unit diagonal.
    const double reg = std::max(c.desc.lambda * (mean_diag > 0.0 ? mean_diag : 1.0), 1e-14);
    for (int k = 0; k < q; ++k) {
        double& d = c.normal_matrix.coeffRef(k, k);
        d = d > 0.0 ? d + reg : 1.0;
    }
    c.tension_solver->factorize(c.normal_matrix);
    if (c.tension_solver->info() != Eigen::Success) return;
    for (int k = 0; k < q; ++k) c.solution[k] = std::isfinite(c.tension[c.columns[k]]) ? c.tension[c.columns[k]] : 0.0;
    for (int it = 0; it < kMaxRefinements; ++it) {
        c.refine = c.rhs + reg * c.solution;
        c.refine = c.tension_solver->solve(c.refine);
        const double change = (c.refine - c.solution).lpNorm<Eigen::Infinity>();
        c.solution.swap(c.refine);
        c.tension_iterations = it + 1;
        if (change <= kRefinementTolerance * std::max(c.solution.lpNorm<Eigen::Infinity>(), 1e-300)) break;
    }
    for (std::size_t e = 0; e < c.edgeCount(); ++e) c.tension[e] = c.unknown[e] >= 0 ? c.solution[c.unknown[e]] : 0.0;
    // Residual |A T - b| / |b| of what was solved (zero for a consistent system).
    double r2 = 0.0;
    for (std::size_t p = 0; p < c.vertices(); ++p) {
        if (!c.has_row[p]) continue;
        const Mat3& proj = c.projector[p];
        Vec3 r = proj * c.row_rhs[p];
        for (std::uint32_t e : c.vertex_edges[p])
            if (!c.broken[e]) r -= c.tension[e] * side(c, p, e) * (proj * c.dir[e]);
        r2 += r.squaredNorm();
    }
    c.tension_residual = b_norm2 > 0.0 ? std::sqrt(r2 / b_norm2) : 0.0;
}

void softSpringForces(const ClothState& c, std::vector<Vec3>& out) {
    for (const SoftSpring& s : c.springs) {
        if (!s.alive) continue;
        const Vec3 d = c.x[s.b] - c.x[s.a];
        const double len = d.norm();
        if (!(len > 1e-15)) continue;
        const Vec3 f = s.stiffness * (len - s.rest) * (d / len);  // pulls a toward b when stretched
        out[s.a] += f;
        out[s.b] -= f;
    }
}

void solveClothTension(ClothState& c, const StepContext& ctx) {
    for (std::size_t e = 0; e < c.edgeCount(); ++e) {
        const Vec3 d = c.x[c.edges[e][1]] - c.x[c.edges[e][0]];
        const double len = d.norm();
        if (len > 1e-15) c.dir[e] = d / len;
    }
    pressProjector(c);
    const double inv_h2 = ctx.inv_h * ctx.inv_h;
    std::fill(c.row_rhs.begin(), c.row_rhs.end(), Vec3::Zero());
    softSpringForces(c, c.row_rhs);  // F_in, to be subtracted
    for (std::size_t p = 0; p < c.vertices(); ++p) {
        c.has_row[p] = c.hold[p].kind == ParticleHold::Kind::Free ? 1 : 0;
        c.row_rhs[p] = c.mass[p] * inv_h2 * (c.x[p] - c.x_pred[p]) - c.row_rhs[p];
    }
    // The prior and warm start: the stiff springs' forces at x''.
    for (std::size_t e = 0; e < c.edgeCount(); ++e) {
        if (c.broken[e]) continue;
        const double stretch = (c.x[c.edges[e][1]] - c.x[c.edges[e][0]]).norm() - c.rest_length[e];
        c.tension[e] = c.stiffness[e] * std::max(0.0, stretch);
    }
    solveTensionLeastSquares(c);
}

}  // namespace tearables::detail
