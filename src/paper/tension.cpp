// Paper sheets: edge tensions, the stress that tears a sheet.
//
// Stretch: T_e = k (l - l0), the spring's own force (exact for this mass-spring model).
//
// Momentum (Yarn Sec. 3.2, the cloth case; see papers/README.md for the lost equations):
// a free vertex i of mass m_i joined by edges e must satisfy
//   m_i (v''_i - v_i) / h = F_ext_i + F_in_i + sum_e T_e e_ie,
// with v'' the velocity after the step's solve, F_ext gravity and the user's forces, F_in
// the non-structural springs (bending, auxiliary, hinge) and e_ie the unit vector from i
// along edge e. Three equations per vertex; vertices that are held, touch a body or carry
// a body's mass are left out (unknown forces act there). The tensions are the regularised
// least squares min |A T - b|^2 + lambda |T - T_k|^2, lambda = 1e-6 (Yarn's value), where
// we regularise toward the spring forces T_k = k (l - l0) instead of toward zero, so that
// an edge the balance cannot see (both ends held) keeps its elastic tension instead of
// reading zero. The normal equations (A^T A + lambda I) T = A^T b + lambda T_k are sparse
// (edges that share a vertex) and solved by conjugate gradients warm-started at T_k.
// Directions and forces are those of the step's start (what the solve linearised about).
#include "paper/sheet.hpp"

#include <Eigen/IterativeLinearSolvers>
#include <Eigen/SparseCore>

#include <cmath>

namespace tearables::detail {

namespace {

constexpr double kLambda = 1e-6;
constexpr int kCgIterations = 60;
constexpr double kCgTolerance = 1e-8;

}  // namespace

void estimateTension(PaperSheet& s, const std::vector<PointContact>& contacts, const PaperStep& ctx) {
    const std::size_t m = s.springs.size();
    s.tension.assign(m, 0.0);
    // The lengths are the solve's (solveVelocities keeps them per live spring; the
    // positions have not moved since), computed anew only without one.
    std::size_t live = 0;
    for (const PaperSpring& sp : s.springs) live += sp.broken ? 0 : 1;
    const bool lengths = s.link_length.size() == live;
    live = 0;
    for (std::size_t k = 0; k < m; ++k) {
        const PaperSpring& sp = s.springs[k];
        if (sp.broken) continue;
        const double length = lengths ? s.link_length[live] : (s.x[sp.b] - s.x[sp.a]).norm();
        ++live;
        if (sp.kind != PaperSpringKind::Structural) continue;
        s.tension[k] = sp.stiffness * (length - sp.rest);
    }
    if (s.desc.tension != PaperTension::Momentum) return;

    const std::size_t n = s.vertices();
    // Rows: free vertices without a body's mass.
    std::vector<std::uint8_t> row(n, 0);
    for (std::size_t i = 0; i < n; ++i)
        row[i] = !s.fixed[i] && (s.added_mass.size() != n || s.added_mass[i].isZero(0.0));
    for (const PointContact& c : contacts) {
        if (c.vertex < n) row[c.vertex] = 0;
        if (c.onFace())
            for (std::uint32_t v : c.face)
                if (v < n) row[v] = 0;
    }
    // b_i = m (v'' - v) / h - m g - f_user - f_other_springs.
    std::vector<Vec3> b(n, Vec3::Zero());
    for (std::size_t i = 0; i < n; ++i)
        if (row[i]) b[i] = s.mass[i] * (s.v[i] - s.v_start[i]) * ctx.inv_h - s.mass[i] * ctx.gravity - s.force[i];
    for (const PaperSpring& sp : s.springs) {
        if (sp.broken || sp.kind == PaperSpringKind::Structural) continue;
        const Vec3 f = springForce(sp, s.x[sp.a], s.x[sp.b], s.v_start[sp.a], s.v_start[sp.b], s.desc.damping);
        b[sp.a] -= f;
        b[sp.b] += f;
    }
    // Unknowns: live structural springs.
    std::vector<int> unknown(m, -1);
    std::vector<std::uint32_t> springs;
    for (std::size_t k = 0; k < m; ++k)
        if (!s.springs[k].broken && s.springs[k].kind == PaperSpringKind::Structural) {
            unknown[k] = static_cast<int>(springs.size());
            springs.push_back(static_cast<std::uint32_t>(k));
        }
    const auto count = static_cast<Eigen::Index>(springs.size());
    if (count == 0) return;
    std::vector<Vec3> dir(springs.size());
    for (std::size_t u = 0; u < springs.size(); ++u) {
        const PaperSpring& sp = s.springs[springs[u]];
        const Vec3 e = s.x[sp.b] - s.x[sp.a];
        dir[u] = e.norm() > 0.0 ? Vec3(e.normalized()) : Vec3(Vec3::Zero());  // from a to b
    }
    std::vector<Eigen::Triplet<double>> triplets;
    Eigen::VectorXd rhs = Eigen::VectorXd::Zero(count), guess(count);
    for (Eigen::Index u = 0; u < count; ++u) {
        guess[u] = s.tension[springs[static_cast<std::size_t>(u)]];
        triplets.emplace_back(u, u, kLambda);
        rhs[u] = kLambda * guess[u];
    }
    // Per row vertex: the edges at it (unit vectors pointing away from it).
    std::vector<std::pair<int, Vec3>> at;
    for (std::size_t i = 0; i < n; ++i) {
        if (!row[i]) continue;
        at.clear();
        for (std::uint32_t k : s.vertex_springs[i]) {
            const int u = unknown[k];
            if (u < 0) continue;
            const PaperSpring& sp = s.springs[k];
            if (sp.a != i && sp.b != i) continue;  // names i only as what it spans
            at.emplace_back(u, sp.a == i ? dir[static_cast<std::size_t>(u)] : Vec3(-dir[static_cast<std::size_t>(u)]));
        }
        for (const auto& [u, e] : at) {
            rhs[u] += e.dot(b[i]);
            for (const auto& [w, f] : at) triplets.emplace_back(u, w, e.dot(f));
        }
    }
    Eigen::SparseMatrix<double> normal(count, count);
    normal.setFromTriplets(triplets.begin(), triplets.end());
    Eigen::ConjugateGradient<Eigen::SparseMatrix<double>, Eigen::Lower | Eigen::Upper> cg;
    cg.setMaxIterations(kCgIterations);
    cg.setTolerance(kCgTolerance);
    cg.compute(normal);
    const Eigen::VectorXd t = cg.solveWithGuess(rhs, guess);
    if (!t.allFinite()) return;  // keep the spring forces
    for (Eigen::Index u = 0; u < count; ++u) s.tension[springs[static_cast<std::size_t>(u)]] = t[u];
}

}  // namespace tearables::detail
