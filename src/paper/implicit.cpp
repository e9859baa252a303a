// Paper sheets: forces and the velocity solve.
//
// Paper Sec. III.A: backward Euler linearised once (Baraff and Witkin),
//   (M - h C_v - h^2 J) dv = h (f + h J v),
// with J = df/dx the springs' stiffness and C_v = df/dv their damping, solved by Jacobi
// iterations (Eq. 5-6): dv_i^(0) = W_ii^-1 b_i, dv_i^(k+1) = W_ii^-1 (b_i - sum_j W_ij dv_j^(k)).
// The paper writes 3-vectors per vertex and a scalar W_ii; we keep the 3x3 blocks (a
// spring is stiff only along itself), which is what makes W_ii^-1 damp the stiff direction
// without damping the soft ones.
//
// Choices where the paper is vague:
// - The spring Jacobian K = k (d d^T + max(0, 1 - l0/l) (I - d d^T)): the transverse
//   (geometric) term is dropped for a compressed spring, so that W stays positive
//   definite (Choi and Ko's argument): a compressed spring then neither buckles the
//   solve nor diverges; it is what lets compressed springs build up until they break.
// - Damping is stiffness-proportional along each spring, c = damping * k (Rayleigh):
//   rigid motion is not damped, and the in-plane vibrations that the stiff springs would
//   ring with are.
#include "paper/sheet.hpp"
#include "string/string_state.hpp"

#include <algorithm>
#include <cmath>

namespace tearables::detail {

Vec3 springForce(const PaperSpring& sp, const Vec3& xa, const Vec3& xb, const Vec3& va, const Vec3& vb, double damping) {
    const Vec3 e = xb - xa;
    const double l = e.norm();
    if (!(l > 1e-12)) return Vec3::Zero();
    const Vec3 d = e / l;
    return (sp.stiffness * (l - sp.rest) + damping * sp.stiffness * d.dot(vb - va)) * d;
}

namespace {

/// Weight of the Jacobi update, dv <- (1 - w) dv + w W_ii^-1 (b - sum_j W_ij dv_j).
/// Paper Eq. 6 is plain Jacobi (w = 1). For paper-stiff springs W_ii is almost all
/// h^2 sum k, and the iteration matrix of plain Jacobi then has an eigenvalue near -1 (the
/// checkerboard mode of the mesh): with an even number of iterations the truncated series
/// flips that mode's displacement every step and the sheet rings forever (measured: 24%
/// strain and 0.4 m/s after 20 s with 8 iterations, 0.002% with 7 or 9). Weighted Jacobi
/// with w = 2/3, the textbook smoother, maps that eigenvalue to -1/3: the mode is damped
/// for every iteration count.
constexpr double kJacobiWeight = 2.0 / 3.0;

/// Velocity a held vertex must have to be where its holder is at the end of the step.
Vec3 heldVelocity(const PaperSheet& s, std::size_t i, const RigidTable& rigids, const PaperStep& ctx) {
    const VertexHold& hold = s.hold[i];
    if (hold.kind == VertexHold::Kind::Pin) return (hold.point - s.x[i]) * ctx.inv_h;
    const RigidState& b = rigids.bodies[hold.body.index];
    return (gluePoint(b, hold.point) - s.x[i]) * ctx.inv_h;
}

}  // namespace

void solveVelocities(PaperSheet& s, const RigidTable& rigids, const PaperStep& ctx) {
    const std::size_t n = s.vertices();
    const double h = ctx.h, h2 = h * h;
    const double damping = s.desc.damping;
    s.rhs.resize(n);
    s.dv.resize(n);
    s.dv_next.resize(n);
    s.diag_inv.resize(n);
    s.fixed.resize(n);
    s.block.resize(s.springs.size());
    // Forces: gravity, the user's, springs with damping. rhs collects h f + h^2 J v.
    s.added_mass.resize(n, Mat3::Zero());
    s.added_force.resize(n, Vec3::Zero());
    for (std::size_t i = 0; i < n; ++i) {
        // Pins and glue to immovable bodies prescribe the velocity; a glue to a movable
        // body was turned into added mass (coupleBodies).
        s.fixed[i] = s.hold[i].kind == VertexHold::Kind::Pin ||
                     (s.hold[i].kind == VertexHold::Kind::Glue && !rigids.movable(s.hold[i].body));
        s.rhs[i] = h * (s.mass[i] * ctx.gravity + s.force[i] + s.added_force[i]);
        s.diag_inv[i] = s.mass[i] * Mat3::Identity() + s.added_mass[i];  // W_ii accumulated here, inverted below
    }
    const bool implicit = s.desc.integrator == PaperIntegrator::Implicit;
    for (std::size_t k = 0; k < s.springs.size(); ++k) {
        const PaperSpring& sp = s.springs[k];
        if (sp.broken) continue;
        const Vec3 e = s.x[sp.b] - s.x[sp.a];
        const double l = e.norm();
        if (!(l > 1e-12)) {
            s.block[k].setZero();
            continue;
        }
        const Vec3 d = e / l;
        const Vec3 f = springForce(sp, s.x[sp.a], s.x[sp.b], s.v[sp.a], s.v[sp.b], damping);
        s.rhs[sp.a] += h * f;
        s.rhs[sp.b] -= h * f;
        if (!implicit) continue;
        const Mat3 ddt = d * d.transpose();
        const Mat3 K = sp.stiffness * (ddt + std::max(0.0, 1.0 - sp.rest / l) * (Mat3::Identity() - ddt));
        const Vec3 kv = h2 * (K * (s.v[sp.a] - s.v[sp.b]));  // h^2 J v: row a gets -K (v_a - v_b)
        s.rhs[sp.a] -= kv;
        s.rhs[sp.b] += kv;
        s.block[k] = h * damping * sp.stiffness * ddt + h2 * K;
        s.diag_inv[sp.a] += s.block[k];
        s.diag_inv[sp.b] += s.block[k];
    }
    if (!implicit) {
        // Semi-implicit (symplectic) Euler: v += h f / m. Stable only for h < 2 / omega.
        for (std::size_t i = 0; i < n; ++i)
            s.v[i] = s.fixed[i] ? heldVelocity(s, i, rigids, ctx)
                                : Vec3(s.v[i] + (s.mass[i] * Mat3::Identity() + s.added_mass[i]).inverse() * s.rhs[i]);
    } else {
        for (std::size_t i = 0; i < n; ++i) {
            if (s.fixed[i]) {
                s.dv[i] = heldVelocity(s, i, rigids, ctx) - s.v[i];
                continue;
            }
            s.diag_inv[i] = s.diag_inv[i].inverse().eval();
            s.dv[i] = s.diag_inv[i] * s.rhs[i];  // Eq. 6, k = 0
        }
        for (int it = 0; it < s.desc.jacobi_iterations; ++it) {
            for (std::size_t i = 0; i < n; ++i) s.dv_next[i] = s.fixed[i] ? s.dv[i] : s.rhs[i];
            for (std::size_t k = 0; k < s.springs.size(); ++k) {
                const PaperSpring& sp = s.springs[k];
                if (sp.broken) continue;
                // W_ab = -block: b_a - W_ab dv_b = b_a + block dv_b.
                if (!s.fixed[sp.a]) s.dv_next[sp.a] += s.block[k] * s.dv[sp.b];
                if (!s.fixed[sp.b]) s.dv_next[sp.b] += s.block[k] * s.dv[sp.a];
            }
            for (std::size_t i = 0; i < n; ++i)
                if (!s.fixed[i]) s.dv_next[i] = (1.0 - kJacobiWeight) * s.dv[i] + kJacobiWeight * (s.diag_inv[i] * s.dv_next[i]);
            s.dv.swap(s.dv_next);
        }
        for (std::size_t i = 0; i < n; ++i) s.v[i] += s.dv[i];
    }
    for (std::size_t i = 0; i < n; ++i) {
        const double speed = s.v[i].norm();
        if (speed > ctx.max_speed) s.v[i] *= ctx.max_speed / speed;
        s.x_pred[i] = s.x[i] + h * s.v[i];
    }
}

}  // namespace tearables::detail
