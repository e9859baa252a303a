// Paper sheets: edge tensions, the stress that tears a sheet.
//
// Stretch: T_e = k (l - l0), the spring's own force (exact for this mass-spring model).
//
// Momentum (Yarn Sec. 3.2, the cloth case; papers/README.md has the lost equations): a free
// vertex i of mass m_i joined by edges e satisfies
//   m_i (v''_i - v_i) / h = F_ext_i + F_in_i + sum_e T_e e_ie,
// v'' the velocity after the step's solve, F_ext gravity and user forces, F_in the
// non-structural springs (bending, auxiliary, hinge), e_ie the unit vector from i along e.
// Held vertices, those touching a body and those carrying a body's mass give no rows. The
// tensions minimise |A T - b|^2 + lambda |T - T_k|^2 (lambda = 1e-6, Yarn's), regularised
// toward the spring forces T_k = k (l - l0) so that an edge the balance cannot see keeps
// its elastic tension. The normal equations are solved by the supernodal Cholesky
// (linalg/supernodal.hpp; AMD order, or nested dissection on a rectangle's grid where
// cheaper), the analysis kept while the structural springs stay; conjugate gradients
// answer in the steps where they changed or the factorisation fails. Directions and
// forces are those of the step's start (what the solve linearised about).
#include "linalg/dissection.hpp"
#include "paper/sheet.hpp"

#include <Eigen/OrderingMethods>

#include <algorithm>
#include <cmath>
#include <limits>

namespace tearables::detail {

namespace {

constexpr double kLambda = 1e-6;
constexpr int kCgIterations = 60;
constexpr double kCgTolerance = 1e-8;

/// An entry of TensionScratch::incident: its unknown, and the unit vector along its spring
/// away from the vertex (the spring's direction where the vertex is its end a).
int unknownOf(int entry) { return entry < 0 ? ~entry : entry; }
Vec3 awayFrom(int entry, const std::vector<Vec3>& dir) {
    const Vec3& d = dir[static_cast<std::size_t>(unknownOf(entry))];
    return entry < 0 ? Vec3(-d) : d;
}

/// f(u, from_a) for each live structural spring at vertex i that has i as an end (a spring
/// may name a vertex it spans, a crease's): u its unknown (`unknown` per spring), from_a
/// whether i is its end a. In the order of the vertex's spring list.
template <class F>
void forStructuralEnds(const PaperSheet& s, const std::vector<int>& unknown, std::size_t i, F&& f) {
    for (std::uint32_t k : s.vertex_springs[i]) {
        const int u = unknown[k];
        if (u < 0) continue;
        const PaperSpring& sp = s.springs[k];
        if (sp.a != i && sp.b != i) continue;
        f(u, sp.a == i);
    }
}

/// Lists the live structural springs in w.springs as they are joined now (spring, a, b per
/// unknown) into `out`.
void recordEnds(const PaperSheet& s, const PaperSheet::TensionScratch& w, std::vector<std::array<std::uint32_t, 3>>& out) {
    out.resize(w.springs.size());
    for (std::size_t u = 0; u < w.springs.size(); ++u) {
        const PaperSpring& sp = s.springs[w.springs[u]];
        out[u] = {w.springs[u], sp.a, sp.b};
    }
}

/// Builds the direct solve's pattern for the unknowns in w.springs (w.unknown per spring):
/// per vertex its incident unknowns, the lower triangle of A^T A + lambda I over every
/// vertex (a vertex without a row this step adds zeros: the pattern does not change with
/// the contacts), its columns in a fill-reducing order (AMD, or nested dissection on a
/// rectangle's grid), analysed, and where each vertex's pairs go in the values. Runs when
/// the live structural springs or their ends changed (and then stayed so for a step).
void buildTensionPattern(const PaperSheet& s, PaperSheet::TensionScratch& w) {
    const std::size_t n = s.vertices(), count = w.springs.size();
    recordEnds(s, w, w.pattern_ends);
    w.incident_start.assign(n + 1, 0);
    w.incident.clear();
    for (std::size_t i = 0; i < n; ++i) {
        forStructuralEnds(s, w.unknown, i, [&](int u, bool from_a) { w.incident.push_back(from_a ? u : ~u); });
        w.incident_start[i + 1] = static_cast<std::uint32_t>(w.incident.size());
    }
    // The unknowns' graph in natural order, then AMD's order of it.
    std::vector<Eigen::Triplet<double>> triplets;
    auto pairs = [&](auto&& f) {
        for (std::size_t i = 0; i < n; ++i)
            for (std::uint32_t a = w.incident_start[i]; a < w.incident_start[i + 1]; ++a)
                for (std::uint32_t k = w.incident_start[i]; k < a; ++k) {
                    const int ua = unknownOf(w.incident[a]);
                    const int uk = unknownOf(w.incident[k]);
                    f(ua, uk);
                }
    };
    const auto size = static_cast<Eigen::Index>(count);
    for (std::size_t u = 0; u < count; ++u) triplets.emplace_back(static_cast<int>(u), static_cast<int>(u), 1.0);
    pairs([&](int ua, int uk) { triplets.emplace_back(std::max(ua, uk), std::min(ua, uk), 1.0); });
    Eigen::SparseMatrix<double> graph(size, size);
    graph.setFromTriplets(triplets.begin(), triplets.end());
    Eigen::AMDOrdering<int> amd;
    Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int> inverse;
    amd(Eigen::SparseMatrix<double>(graph.selfadjointView<Eigen::Lower>()), inverse);
    // The pattern in an order (order[k]: the unknown in column k), analysed; its cost.
    auto patternIn = [&](const auto& order) {
        w.column.resize(count);
        for (std::size_t k = 0; k < count; ++k) w.column[static_cast<std::size_t>(order[k])] = static_cast<int>(k);
        triplets.clear();
        for (std::size_t u = 0; u < count; ++u) triplets.emplace_back(w.column[u], w.column[u], 1.0);
        pairs([&](int ua, int uk) {
            const int ca = w.column[static_cast<std::size_t>(ua)], ck = w.column[static_cast<std::size_t>(uk)];
            triplets.emplace_back(std::max(ca, ck), std::min(ca, ck), 1.0);
        });
        w.normal.resize(size, size);
        w.normal.setFromTriplets(triplets.begin(), triplets.end());
        w.normal.makeCompressed();
        w.factor.analyze(w.normal);
        return w.factor.flops();
    };
    const double amd_flops = patternIn(inverse.indices());
    // A rectangle's sheet still on its grid: nested dissection of the edges at their doubled
    // midpoints, as the cloth's yarns (cloth/tension.cpp): an odd line of it (the edges
    // crossing between two columns or rows of vertices, diagonals included) separates the
    // edges on either side. Kept where it costs fewer operations than AMD's order.
    const int nx = s.desc.resolution[0], nz = s.desc.resolution[1];
    const auto grid = static_cast<std::uint32_t>(nx * nz);
    bool on_grid = s.desc.vertices.empty() && s.vertices() == grid;
    std::vector<std::array<int, 2>> midpoint(on_grid ? count : 0);
    for (std::size_t u = 0; u < count && on_grid; ++u) {
        const auto& end = w.pattern_ends[u];
        on_grid = end[1] < grid && end[2] < grid;
        midpoint[u] = {static_cast<int>(end[1] % nx + end[2] % nx), static_cast<int>(end[1] / nx + end[2] / nx)};
    }
    if (on_grid && patternIn(gridDissection(midpoint, 1, 2, 1)) > amd_flops) patternIn(inverse.indices());
    // Where each vertex's pairs (a, k <= a) go in the values.
    const int* outer = w.normal.outerIndexPtr();
    const int* inner = w.normal.innerIndexPtr();
    auto entry = [&](int row, int col) {
        const int* found = std::lower_bound(inner + outer[col], inner + outer[col + 1], row);
        return static_cast<int>(found - inner);
    };
    w.pair_start.assign(n + 1, 0);
    w.pair_value.clear();
    for (std::size_t i = 0; i < n; ++i) {
        for (std::uint32_t a = w.incident_start[i]; a < w.incident_start[i + 1]; ++a)
            for (std::uint32_t k = w.incident_start[i]; k <= a; ++k) {
                const int ua = unknownOf(w.incident[a]);
                const int uk = unknownOf(w.incident[k]);
                const int ca = w.column[static_cast<std::size_t>(ua)], ck = w.column[static_cast<std::size_t>(uk)];
                w.pair_value.push_back(entry(std::max(ca, ck), std::min(ca, ck)));
            }
        w.pair_start[i + 1] = static_cast<std::uint32_t>(w.pair_value.size());
    }
    w.right.resize(size);
}

/// True when `ends` lists the live structural springs in w.springs as they are joined now
/// (spring, a, b per unknown).
bool sameEnds(const PaperSheet& s, const PaperSheet::TensionScratch& w, const std::vector<std::array<std::uint32_t, 3>>& ends) {
    if (ends.size() != w.springs.size()) return false;
    for (std::size_t u = 0; u < w.springs.size(); ++u) {
        const PaperSpring& sp = s.springs[w.springs[u]];
        if (ends[u] != std::array<std::uint32_t, 3>{w.springs[u], sp.a, sp.b}) return false;
    }
    return true;
}

/// The normal equations solved directly: assembled into the pattern, factorised
/// (SupernodalLLT), one back-substitution. Leaves the tensions in w.solution (unknown
/// order) and returns true; false where the springs changed this step (see below) or the
/// factorisation fails (not finite).
bool solveDirect(const PaperSheet& s, PaperSheet::TensionScratch& w) {
    const std::size_t n = s.vertices(), count = w.springs.size();
    if (!w.factor.analysed() || !sameEnds(s, w, w.pattern_ends)) {
        // The springs changed since the pattern was built. It is built anew once they have
        // stayed the same for a step; until then the conjugate gradients answer. A sheet
        // that creases or tears every step would otherwise pay the analysis every step.
        if (!sameEnds(s, w, w.seen_ends)) {
            recordEnds(s, w, w.seen_ends);
            return false;
        }
        buildTensionPattern(s, w);
    }
    double* values = w.normal.valuePtr();
    std::fill(values, values + w.normal.nonZeros(), 0.0);
    const int* outer = w.normal.outerIndexPtr();  // a column's first entry is its diagonal
    for (std::size_t u = 0; u < count; ++u) {
        const int c = w.column[u];
        values[outer[c]] = kLambda;
        w.right[c] = kLambda * w.solution[u];
    }
    for (std::size_t i = 0; i < n; ++i) {
        if (!w.row[i]) continue;
        const std::uint32_t first = w.incident_start[i], last = w.incident_start[i + 1];
        const int* pair = w.pair_value.data() + w.pair_start[i];
        for (std::uint32_t a = first; a < last; ++a) {
            const int ua = unknownOf(w.incident[a]);
            const Vec3 ea = awayFrom(w.incident[a], w.dir);
            w.right[w.column[static_cast<std::size_t>(ua)]] += ea.dot(w.b[i]);
            for (std::uint32_t k = first; k <= a; ++k) values[*pair++] += ea.dot(awayFrom(w.incident[k], w.dir));
        }
    }
    if (!w.factor.factorize(w.normal)) return false;
    w.factor.solveInPlace(w.right);
    for (std::size_t u = 0; u < count; ++u) w.solution[u] = w.right[w.column[u]];
    return true;
}

}  // namespace

void estimateTension(PaperSheet& s, const std::vector<PointContact>& contacts, const PaperStep& ctx) {
    const std::size_t m = s.springs.size();
    assignGrowing(s.tension, m, 0.0);
    // The lengths are the solve's (solveVelocities keeps them per spring; the positions
    // have not moved since), computed anew only without them.
    const bool lengths = s.link_length.size() == m;
    for (std::size_t k = 0; k < m; ++k) {
        const PaperSpring& sp = s.springs[k];
        if (sp.broken) continue;
        const double length = lengths ? s.link_length[k] : (s.x[sp.b] - s.x[sp.a]).norm();
        if (sp.kind != PaperSpringKind::Structural) continue;
        s.tension[k] = sp.stiffness * (length - sp.rest);
    }
    if (s.desc.tension != PaperTension::Momentum) return;

    const std::size_t n = s.vertices();
    PaperSheet::TensionScratch& w = s.tension_scratch;
    // Rows: free vertices without a body's mass.
    std::vector<std::uint8_t>& row = w.row;
    assignGrowing(row, n, 0);
    for (std::size_t i = 0; i < n; ++i)
        row[i] = !s.fixed[i] && (s.added_mass.size() != n || s.added_mass[i].isZero(0.0));
    for (const PointContact& c : contacts) {
        if (c.vertex < n) row[c.vertex] = 0;
        if (c.onFace())
            for (std::uint32_t v : c.face)
                if (v < n) row[v] = 0;
    }
    // b_i = m (v'' - v) / h - m g - f_user - f_other_springs.
    std::vector<Vec3>& b = w.b;
    assignGrowing(b, n, Vec3::Zero());
    for (std::size_t i = 0; i < n; ++i)
        if (row[i]) b[i] = s.mass[i] * (s.v[i] - s.v_start[i]) * ctx.inv_h - s.mass[i] * ctx.gravity - s.force[i];
    for (const PaperSpring& sp : s.springs) {
        if (sp.broken || sp.kind == PaperSpringKind::Structural) continue;
        const Vec3 f = springForce(sp, s.x[sp.a], s.x[sp.b], s.v_start[sp.a], s.v_start[sp.b], s.desc.damping);
        b[sp.a] -= f;
        b[sp.b] += f;
    }
    // Unknowns: live structural springs.
    std::vector<int>& unknown = w.unknown;
    std::vector<std::uint32_t>& springs = w.springs;
    assignGrowing(unknown, m, -1);
    springs.clear();
    for (std::size_t k = 0; k < m; ++k)
        if (!s.springs[k].broken && s.springs[k].kind == PaperSpringKind::Structural) {
            unknown[k] = static_cast<int>(springs.size());
            springs.push_back(static_cast<std::uint32_t>(k));
        }
    const std::size_t count = springs.size();
    if (count == 0) return;
    std::vector<Vec3>& dir = w.dir;
    dir.resize(count);
    for (std::size_t u = 0; u < count; ++u) {
        const PaperSpring& sp = s.springs[springs[u]];
        const Vec3 e = s.x[sp.b] - s.x[sp.a];
        dir[u] = e.norm() > 0.0 ? Vec3(e.normalized()) : Vec3(Vec3::Zero());  // from a to b
    }
    // The edges at row vertex i (unit vectors pointing away from it): f(u, e) for each.
    // Gathered once into flat lists (w.edge_start per vertex + 1, w.edge_unknown,
    // w.edge_dir): the products below pass over them 120 times in a step that falls back
    // to the conjugate gradients.
    assignGrowing(w.edge_start, n + 1, 0);
    w.edge_unknown.clear();
    w.edge_dir.clear();
    for (std::size_t i = 0; i < n; ++i) {
        if (row[i])
            forStructuralEnds(s, unknown, i, [&](int u, bool from_a) {
                const Vec3& d = dir[static_cast<std::size_t>(u)];
                w.edge_unknown.push_back(static_cast<std::uint32_t>(u));
                w.edge_dir.push_back(from_a ? d : Vec3(-d));
            });
        w.edge_start[i + 1] = static_cast<std::uint32_t>(w.edge_unknown.size());
    }
    auto forEdgeAt = [&](std::size_t i, auto&& f) {
        for (std::uint32_t at = w.edge_start[i]; at < w.edge_start[i + 1]; ++at) f(w.edge_unknown[at], w.edge_dir[at]);
    };
    // The normal equations (A^T A + lambda I) T = A^T b + lambda T_k: the right-hand side
    // and the diagonal, and the matrix's product without forming it (A T per row vertex,
    // then A^T of that) for the residual and the fallback.
    std::vector<double>& t = w.solution;
    std::vector<double>& rhs = w.rhs;
    std::vector<double>& diagonal = w.diagonal;
    t.resize(count);
    rhs.resize(count);
    assignGrowing(diagonal, count, kLambda);
    for (std::size_t u = 0; u < count; ++u) {
        t[u] = s.tension[springs[u]];
        rhs[u] = kLambda * t[u];
    }
    for (std::size_t i = 0; i < n; ++i) {
        if (!row[i]) continue;
        forEdgeAt(i, [&](std::size_t u, const Vec3& e) {
            rhs[u] += e.dot(b[i]);
            diagonal[u] += e.dot(e);
        });
    }
    std::vector<Vec3>& image = w.image;
    image.resize(n);
    auto multiply = [&](const std::vector<double>& x, std::vector<double>& out) {
        for (std::size_t i = 0; i < n; ++i) {
            if (!row[i]) continue;
            Vec3 sum = Vec3::Zero();
            forEdgeAt(i, [&](std::size_t u, const Vec3& e) { sum += x[u] * e; });
            image[i] = sum;
        }
        for (std::size_t u = 0; u < count; ++u) out[u] = kLambda * x[u];
        for (std::size_t i = 0; i < n; ++i) {
            if (!row[i]) continue;
            forEdgeAt(i, [&](std::size_t u, const Vec3& e) { out[u] += e.dot(image[i]); });
        }
    };
    auto dot = [count](const std::vector<double>& a, const std::vector<double>& c) {
        double sum = 0.0;
        for (std::size_t u = 0; u < count; ++u) sum += a[u] * c[u];
        return sum;
    };
    std::vector<double>& r = w.residual;
    std::vector<double>& q = w.product;
    r.resize(count);
    q.resize(count);
    const double rhs_norm2 = dot(rhs, rhs);
    auto residual = [&] {  // r = rhs - N t; |r| / |rhs|
        multiply(t, q);
        for (std::size_t u = 0; u < count; ++u) r[u] = rhs[u] - q[u];
        return rhs_norm2 > 0.0 ? std::sqrt(dot(r, r) / rhs_norm2) : 0.0;
    };
    w.iterations = 0;
    if (solveDirect(s, w)) {
        w.residual_norm = residual();
    } else {
        // In a step whose springs changed (a crease, a tear), or where the factorisation
        // fails (a pivot not finite): conjugate gradients with the diagonal (Jacobi)
        // preconditioner, warm-started at T_k, stopping at |r| <= kCgTolerance |rhs| or
        // after kCgIterations. Ill-conditioned (lambda is 1e-6 of the diagonal), hence the
        // direct solve wherever the pattern holds. (t still holds T_k: the direct solve
        // writes it only when it succeeds.)
        std::vector<double>& z = w.z;
        std::vector<double>& p = w.direction;
        z.resize(count);
        p.resize(count);
        w.residual_norm = residual();
        if (!(rhs_norm2 > 0.0)) {
            std::fill(t.begin(), t.end(), 0.0);
            w.residual_norm = 0.0;
        } else if (w.residual_norm >= kCgTolerance) {
            const double threshold = std::max(kCgTolerance * kCgTolerance * rhs_norm2, std::numeric_limits<double>::min());
            for (std::size_t u = 0; u < count; ++u) p[u] = r[u] / diagonal[u];
            double rz = dot(r, p);
            for (int it = 0; it < kCgIterations; ++it) {
                multiply(p, q);
                ++w.iterations;
                const double alpha = rz / dot(p, q);
                for (std::size_t u = 0; u < count; ++u) {
                    t[u] += alpha * p[u];
                    r[u] -= alpha * q[u];
                }
                if (dot(r, r) < threshold) break;
                for (std::size_t u = 0; u < count; ++u) z[u] = r[u] / diagonal[u];
                const double rz_new = dot(r, z);
                const double beta = rz_new / rz;
                rz = rz_new;
                for (std::size_t u = 0; u < count; ++u) p[u] = z[u] + beta * p[u];
            }
            w.residual_norm = std::sqrt(dot(r, r) / rhs_norm2);
        }
    }
    for (std::size_t u = 0; u < count; ++u)
        if (!std::isfinite(t[u])) return;  // keep the spring forces
    for (std::size_t u = 0; u < count; ++u) s.tension[springs[u]] = t[u];
}

}  // namespace tearables::detail
