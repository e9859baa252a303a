// Stage: yarn tensions from momentum balance (Yarn, Sec. 3.2), extended from a yarn to a
// woven mesh. A free vertex i of mass m_i whose strain-limited motion is x''_i satisfies
// (papers/README.md: the equations lost in the extraction)
//     m_i (x''_i - x'_i) / h^2 = F_in_i + sum_e T_e s_ie e_e,   s_ie = +1 if i starts e, else -1,
// x'_i its prediction, F_in_i the soft shear and bending springs at x'', e_e yarn e's unit
// direction at x'', T_e its tension: A T = b, three rows per free vertex. Held vertices give
// no rows; a pressed vertex's rows are projected across the contact normals (P_i = I -
// sum n n^T), where the unknown contact force acts.
//
// Yarn regularises towards zero, min |A T - b|^2 + lambda |T|^2 (lambda = 1e-6). Self-stress
// (a cloth between two clamps) lies in A's null space and would read zero and never tear,
// so we regularise towards the strain limiter's spring forces T_spring (k_e max(0, |d| - L)):
//     min |A T - b|^2 + lambda' |T - T_spring|^2,   lambda' = lambda mean diag(A^T A),
// then remove the bias towards the prior by iterating (iteratedTikhonov). The normal
// equations are assembled per vertex, their pattern fixed per topology, and factored by the
// supernodal Cholesky (linalg/supernodal.hpp), yarns in nested-dissection order: O(q^1.5).
#include "cloth/cloth_state.hpp"
#include "base/lanes.hpp"

#include <Eigen/OrderingMethods>

#include <algorithm>
#include <cmath>

namespace tearables::detail {

namespace {

constexpr int kMaxRefinements = 12;
/// The strain solve lumps a cloth's bending blocks into its preconditioner where the vertex
/// graph's factorisation costs this many multiply-adds or more (clothVertexOrder).
constexpr double kLumpFrom = 1e6;
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

/// Builds the pattern of A^T A + lambda' I (lower triangle, columns in nested-dissection order) for the current topology and
/// remembers, per vertex and pair of its yarns, where the product goes.
void buildPattern(ClothState& c) {
    c.columns.clear();
    for (const std::uint32_t e : clothEdgeOrder(c)) {  // columns in nested-dissection order
        c.unknown[e] = c.broken[e] ? -1 : static_cast<int>(c.columns.size());
        if (!c.broken[e]) c.columns.push_back(e);
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
    c.tension_llt.analyze(c.normal_matrix);
    c.rhs.resize(q);
    c.solution.resize(q);
    c.refine.resize(q);
    c.cg_residual.resize(q);
    c.cg_direction.resize(q);
    c.cg_image.resize(q);
    std::size_t degree = 0;  // the most yarns at a vertex
    for (const auto& inc : c.vertex_edges) degree = std::max(degree, inc.size());
    c.tension_projected.resize(degree);
    c.tension_topology = c.topology;
}

/// s_ie: +1 when vertex p starts edge e, -1 when it ends it.
double side(const ClothState& c, std::size_t p, std::uint32_t e) { return c.edges[e][0] == p ? 1.0 : -1.0; }


/// True when a refinement whose last two changes (sup norm) were `change` and
/// `last_change` may stop: the change is below the tolerance, or the iteration converges
/// linearly (ratio rho of successive changes under 1/2) and the changes still to come,
/// about change * rho / (1 - rho), are (one back-substitution fewer, same accuracy).
bool refinementConverged(double change, double last_change, bool first, double solution_norm) {
    const double tolerance = kRefinementTolerance * std::max(solution_norm, 1e-300);
    if (change <= tolerance) return true;
    const double ratio = !first && last_change > 0.0 ? change / last_change : 1.0;
    return ratio < 0.5 && change * ratio / (1.0 - ratio) <= tolerance;
}

/// a . b in four partial sums (k mod 4), added pairwise at the end.
double dot(const Eigen::VectorXd& a, const Eigen::VectorXd& b) {
    const Eigen::Index n = a.size();
    double sum[4] = {0.0, 0.0, 0.0, 0.0};
    Eigen::Index k = 0;
    for (; k + 4 <= n; k += 4)
        for (int l = 0; l < 4; ++l) sum[l] += a[k + l] * b[k + l];
    for (; k < n; ++k) sum[0] += a[k] * b[k];
    return (sum[0] + sum[1]) + (sum[2] + sum[3]);
}

/// Iterated Tikhonov (proximal point) from the prior in c.solution: T <- M^-1 (A^T b +
/// lambda' T), M = A^T A + lambda' I the assembled matrix. Plain Tikhonov pulls every tension
/// towards the prior by about lambda' / sigma_min^2 (sigma_min ~ 1/n for a chain of n
/// yarns); each refinement, one back-substitution, shrinks that bias by lambda' / (lambda' +
/// sigma^2) and leaves the null-space part at the prior's: the limit is T_LS(min norm) +
/// P_null T_spring. The prior is a better start than the last step's tensions after a tear.
template <class Solve>
void iteratedTikhonov(ClothState& c, double reg, Solve&& solve) {
    const int q = static_cast<int>(c.columns.size());
    double last_change = 0.0;
    for (int it = 0; it < kMaxRefinements; ++it) {
        c.refine = c.rhs + reg * c.solution;
        solve(c.refine);
        double change = 0.0, norm = 0.0;  // |T_new - T|_inf and |T_new|_inf in one pass
        for (int k = 0; k < q; ++k) {
            change = std::max(change, std::abs(c.refine[k] - c.solution[k]));
            norm = std::max(norm, std::abs(c.refine[k]));
        }
        c.solution.swap(c.refine);
        ++c.tension_iterations;
        if (refinementConverged(change, last_change, it == 0, norm)) break;
        last_change = change;
    }
}

/// The same fixed point, N' T = A^T b with N' = M - lambda' I and the null-space part of
/// the prior in c.solution, by conjugate gradients preconditioned by M^-1 (the factor),
/// one back-substitution a step. No product with the matrix in the loop: for z = M^-1 r,
/// N' z = M z - lambda' z = r - lambda' z, and N' p follows by p's own recurrence (one
/// product with M at the start, for r_0). Where every mode the motion excites has sigma^2 >>
/// lambda' it takes fewer back-substitutions than iteratedTikhonov (the same Krylov space,
/// its best point). Returns false, c.solution spoilt, at a slow mode: a step more than half
/// the last (an eigenvalue of M^-1 N' = sigma^2 / (sigma^2 + lambda') well below 1, as for
/// the self-stress of a clamped weave). There the fixed point is ill-conditioned (converging
/// it moves tensions by newtons on round-off) and the caller falls back to the truncated
/// iteration, which keeps those modes at the prior.
template <class Solve>
bool conjugateGradients(ClothState& c, double reg, Solve&& solve) {
    const int q = static_cast<int>(c.columns.size());
    Eigen::VectorXd &t = c.solution, &r = c.cg_residual, &z = c.refine, &p = c.cg_direction, &image = c.cg_image;
    {  // r = A^T b - N' T = A^T b + lambda' T - M T (M's lower triangle stored)
        const int* outer = c.normal_matrix.outerIndexPtr();
        const int* inner = c.normal_matrix.innerIndexPtr();
        const double* values = c.normal_matrix.valuePtr();
        for (int k = 0; k < q; ++k) r[k] = c.rhs[k] + reg * t[k];
        for (int j = 0; j < q; ++j)
            for (int at = outer[j]; at < outer[j + 1]; ++at) {
                const int i = inner[at];
                r[i] -= values[at] * t[j];
                if (i != j) r[j] -= values[at] * t[i];
            }
    }
    double last_change = 0.0, rz_last = 0.0;
    for (int it = 0; it < kMaxRefinements; ++it) {
        z = r;
        solve(z);
        ++c.tension_iterations;
        // Three passes over the vectors a step (Eigen's expressions would take eight).
        const double rz = dot(r, z);
        const double beta = it == 0 ? 0.0 : rz / rz_last;
        double p_max = 0.0;
        for (int k = 0; k < q; ++k) {
            p[k] = it == 0 ? z[k] : z[k] + beta * p[k];
            image[k] = it == 0 ? r[k] - reg * z[k] : (r[k] - reg * z[k]) + beta * image[k];
            p_max = std::max(p_max, std::abs(p[k]));
        }
        const double pq = dot(p, image);
        if (!(rz > 0.0) || !(pq > 0.0)) return rz == 0.0;  // r = 0: solved; else round-off has the last word
        const double alpha = rz / pq;
        const double change = alpha * p_max;
        if (it > 0 && !(change <= 0.5 * last_change)) return false;  // a slow mode
        double t_max = 0.0;
        for (int k = 0; k < q; ++k) {
            t[k] += alpha * p[k];
            r[k] -= alpha * image[k];
            t_max = std::max(t_max, std::abs(t[k]));
        }
        rz_last = rz;
        if (refinementConverged(change, last_change, it == 0, t_max)) return true;
        last_change = change;
    }
    return true;  // at the cap, every step under half the last: reported as is
}

bool fullGrid(const ClothState& c) {
    return c.nu > 0 && c.nv > 0 && c.vertices() == static_cast<std::size_t>(c.nu) * static_cast<std::size_t>(c.nv);
}

std::vector<std::uint32_t> naturalOrder(std::size_t n) {
    std::vector<std::uint32_t> order(n);
    for (std::size_t i = 0; i < n; ++i) order[i] = static_cast<std::uint32_t>(i);
    return order;
}

/// The lower triangle of the vertex graph (yarns and soft springs; without the springs
/// between vertices of different cells when `lumped`, clothLumped) in `order`, as a pattern.
SparseMatrix vertexGraph(const ClothState& c, const std::vector<std::uint32_t>& order, bool lumped) {
    std::vector<int> position(c.vertices());
    for (std::size_t k = 0; k < order.size(); ++k) position[order[k]] = static_cast<int>(k);
    std::vector<Eigen::Triplet<double>> triplets;
    for (std::size_t p = 0; p < c.vertices(); ++p) triplets.emplace_back(static_cast<int>(p), static_cast<int>(p), 1.0);
    auto link = [&](std::uint32_t a, std::uint32_t b) {
        const int i = position[a], j = position[b];
        triplets.emplace_back(std::max(i, j), std::min(i, j), 1.0);
    };
    for (const auto& [a, b] : c.edges) link(a, b);
    for (const SoftSpring& s : c.springs)
        if (!lumped || !clothLumped(c, s.a, s.b)) link(s.a, s.b);
    SparseMatrix g(static_cast<Eigen::Index>(c.vertices()), static_cast<Eigen::Index>(c.vertices()));
    g.setFromTriplets(triplets.begin(), triplets.end());
    g.makeCompressed();
    return g;
}

}  // namespace

bool clothLumped(const ClothState& c, std::uint32_t a, std::uint32_t b) {
    if (c.nu <= 0) return false;
    const auto nu = static_cast<std::uint32_t>(c.nu);
    const std::uint32_t ia = a % nu, ib = b % nu, ja = a / nu, jb = b / nu;
    return std::max(ia, ib) - std::min(ia, ib) > 1 || std::max(ja, jb) - std::min(ja, jb) > 1;
}

const std::vector<std::uint32_t>& clothVertexOrder(ClothState& c) {
    if (c.vertex_order.size() == c.vertices()) return c.vertex_order;
    const std::vector<std::uint32_t> natural = naturalOrder(c.vertices());
    // The cheaper of two fill-reducing orders of a vertex graph (each vertex's 3 unknowns
    // stay together): nested dissection (best on large weaves) or AMD (Eigen's
    // AMDOrdering; better on small ones), with the factorisation's multiply-adds.
    auto cheapest = [&](bool lumped, int width, double& cost) {
        Eigen::AMDOrdering<int> amd;
        Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int> inverse;
        amd(SparseMatrix(vertexGraph(c, natural, lumped).selfadjointView<Eigen::Lower>()), inverse);
        std::vector<std::uint32_t> best(inverse.indices().data(), inverse.indices().data() + inverse.size());
        SupernodalLLT cost_amd;
        cost_amd.analyze(vertexGraph(c, best, lumped));
        cost = cost_amd.flops();
        if (fullGrid(c)) {
            std::vector<std::array<int, 2>> at(c.vertices());
            for (std::size_t p = 0; p < at.size(); ++p) at[p] = {static_cast<int>(p % c.nu), static_cast<int>(p / c.nu)};
            std::vector<std::uint32_t> dissection = gridDissection(at, width, 1, 0);
            SupernodalLLT cost_nd;
            cost_nd.analyze(vertexGraph(c, dissection, lumped));
            if (cost_nd.flops() < cost) {
                best.swap(dissection);
                cost = cost_nd.flops();
            }
        }
        return best;
    };
    // The whole graph (bending springs reach two cells: separators two columns wide), and
    // the preconditioner's without the bending links (one column). The preconditioned
    // solve pays once its factorisation saves more than its conjugate gradients cost:
    // measured, from about 28 x 28 vertices, where the graph's factorisation costs
    // kLumpFrom multiply-adds (BENCHMARKS.md, "Sheets, cloth and whole scenes").
    double full_cost = 0.0, lumped_cost = 0.0;
    std::vector<std::uint32_t> full = cheapest(false, 2, full_cost);
    c.lump_bending = full_cost >= kLumpFrom;
    return c.vertex_order = c.lump_bending ? cheapest(true, 1, lumped_cost) : std::move(full);
}

const std::vector<std::uint32_t>& clothEdgeOrder(ClothState& c) {
    if (c.edge_order.size() == c.edgeCount()) return c.edge_order;
    if (!fullGrid(c)) return c.edge_order = naturalOrder(c.edgeCount());
    std::vector<std::array<int, 2>> at(c.edgeCount());  // doubled midpoints: warp (2i + 1, 2j), weft (2i, 2j + 1)
    for (std::size_t e = 0; e < at.size(); ++e) {
        const auto [a, b] = c.edges[e];
        at[e] = {static_cast<int>(a % c.nu + b % c.nu), static_cast<int>(a / c.nu + b / c.nu)};
    }
    return c.edge_order = gridDissection(at, 1, 2, 1);
}

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
    std::vector<Vec3>& projected = c.tension_projected;  // sized in buildPattern: no allocation here
    for (std::size_t p = 0; p < c.vertices(); ++p) {
        if (!c.has_row[p]) continue;
        const auto& inc = c.vertex_edges[p];
        const Mat3& proj = c.projector[p];
        const bool pressed = proj != Mat3::Identity();  // most vertices touch nothing: P = I
        const Vec3 b = pressed ? Vec3(proj * c.row_rhs[p]) : c.row_rhs[p];
        b_norm2 += b.squaredNorm();
        const auto& idx = c.vertex_value_index[p];
        // projected[a]: s_ie P e_e of the yarns at p, once each
        for (std::size_t a = 0; a < inc.size(); ++a)
            projected[a] = side(c, p, inc[a]) * (pressed ? Vec3(proj * c.dir[inc[a]]) : c.dir[inc[a]]);
        for (std::size_t a = 0; a < inc.size(); ++a) {
            const int ca = c.unknown[inc[a]];
            if (ca < 0) continue;
            const Vec3& pa = projected[a];
            c.rhs[ca] += pa.dot(b);
            for (std::size_t k = 0; k <= a; ++k) {
                const int at = idx[a * inc.size() + k];
                if (at < 0) continue;
                values[at] += pa.dot(projected[k]);  // P symmetric and idempotent
            }
        }
    }
    double mean_diag = 0.0;
    const int* outer = c.normal_matrix.outerIndexPtr();  // a column's first entry is its diagonal (lower triangle, rows sorted)
    for (int k = 0; k < q; ++k) mean_diag += values[outer[k]];
    mean_diag /= q;
    // Tikhonov lambda relative to the mean diagonal; a column no row sees (a yarn between
    // two pins) is held at zero by a unit diagonal.
    const double reg = std::max(c.desc.lambda * (mean_diag > 0.0 ? mean_diag : 1.0), 1e-14);
    for (int k = 0; k < q; ++k) {
        double& d = values[outer[k]];
        d = d > 0.0 ? d + reg : 1.0;
    }
    const bool llt = c.tension_llt.factorize(c.normal_matrix);
    if (!llt) {  // not positive definite in round-off: LDL^T
        if (!c.tension_solver) c.tension_solver = std::make_unique<ClothLDLT>();
        c.tension_solver->compute(c.normal_matrix);
        if (c.tension_solver->info() != Eigen::Success) return;
    }
    auto solve = [&](Eigen::VectorXd& v) {
        if (llt)
            c.tension_llt.solveInPlace(v);
        else
            v = c.tension_solver->solve(v);
    };
    auto start = [&] {
        for (int k = 0; k < q; ++k) c.solution[k] = std::isfinite(c.tension[c.columns[k]]) ? c.tension[c.columns[k]] : 0.0;
    };
    start();
    if (!conjugateGradients(c, reg, solve)) {
        start();  // a slow mode: the plain iteration from the prior, as if CG had not been tried
        iteratedTikhonov(c, reg, solve);
    }
    for (std::size_t e = 0; e < c.edgeCount(); ++e) c.tension[e] = c.unknown[e] >= 0 ? c.solution[c.unknown[e]] : 0.0;
    // Residual |A T - b| / |b| of what was solved (zero for a consistent system).
    double r2 = 0.0;
    for (std::size_t p = 0; p < c.vertices(); ++p) {
        if (!c.has_row[p]) continue;
        const Mat3& proj = c.projector[p];
        const bool pressed = proj != Mat3::Identity();
        Vec3 r = pressed ? Vec3(proj * c.row_rhs[p]) : c.row_rhs[p];
        for (std::uint32_t e : c.vertex_edges[p])
            if (!c.broken[e]) r -= c.tension[e] * side(c, p, e) * (pressed ? Vec3(proj * c.dir[e]) : c.dir[e]);
        r2 += r.squaredNorm();
    }
    c.tension_residual = b_norm2 > 0.0 ? std::sqrt(r2 / b_norm2) : 0.0;
}

void softSpringForces(const ClothState& c, std::vector<Vec3>& out) {
    auto apply = [&](const SoftSpring& s, double len, const Vec3& unit) {
        if (!s.alive || !(len > 1e-15)) return;
        const Vec3 f = s.stiffness * (len - s.rest) * unit;  // pulls a toward b when stretched
        out[s.a] += f;
        out[s.b] -= f;
    };
    // Two springs at a time, their roots and divisions in the two lanes of one register
    // (unitPair: the bits of the scalar expressions; the divider bounds this loop),
    // applied in spring order.
    const std::size_t n = c.springs.size();
    std::size_t i = 0;
    for (; i + 1 < n; i += 2) {
        const SoftSpring &s0 = c.springs[i], &s1 = c.springs[i + 1];
        const UnitPair u = unitPair(c.x[s0.b] - c.x[s0.a], c.x[s1.b] - c.x[s1.a]);
        apply(s0, u.length[0], u.unit[0]);
        apply(s1, u.length[1], u.unit[1]);
    }
    if (i < n) {
        const SoftSpring& s = c.springs[i];
        const Vec3 d = c.x[s.b] - c.x[s.a];
        const double len = d.norm();
        apply(s, len, len > 1e-15 ? Vec3(d / len) : Vec3::Zero());
    }
}

void solveClothTension(ClothState& c, const StepContext& ctx) {
    // Directions, and the prior and warm start: the stiff springs' forces at x''.
    auto yarn = [&](std::size_t e, double len, const Vec3& unit) {
        if (len > 1e-15) c.dir[e] = unit;
        if (!c.broken[e]) c.tension[e] = c.stiffness[e] * std::max(0.0, len - c.rest_length[e]);
    };
    const std::size_t m = c.edgeCount();
    std::size_t e = 0;
    for (; e + 1 < m; e += 2) {  // two yarns at a time, as softSpringForces
        const UnitPair u = unitPair(c.x[c.edges[e][1]] - c.x[c.edges[e][0]], c.x[c.edges[e + 1][1]] - c.x[c.edges[e + 1][0]]);
        yarn(e, u.length[0], u.unit[0]);
        yarn(e + 1, u.length[1], u.unit[1]);
    }
    if (e < m) {
        const Vec3 d = c.x[c.edges[e][1]] - c.x[c.edges[e][0]];
        const double len = d.norm();
        yarn(e, len, len > 1e-15 ? Vec3(d / len) : Vec3::Zero());
    }
    pressProjector(c);
    const double inv_h2 = ctx.inv_h * ctx.inv_h;
    std::fill(c.row_rhs.begin(), c.row_rhs.end(), Vec3::Zero());
    softSpringForces(c, c.row_rhs);  // F_in, to be subtracted
    for (std::size_t p = 0; p < c.vertices(); ++p) {
        c.has_row[p] = c.hold[p].kind == ParticleHold::Kind::Free ? 1 : 0;
        c.row_rhs[p] = c.mass[p] * inv_h2 * (c.x[p] - c.x_pred[p]) - c.row_rhs[p];
    }
    solveTensionLeastSquares(c);
}

}  // namespace tearables::detail
