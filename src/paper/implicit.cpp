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

namespace {

/// The rows of the Jacobi gather: per vertex, the couplings of its live springs, in spring
/// order (so every sum is deterministic). They depend only on the live springs' ends and
/// the vertex count, and are rebuilt only when those changed (a crease or a tear): the
/// check is one pass over the springs.
void buildRows(PaperSheet& s) {
    const std::size_t n = s.vertices();
    std::size_t live = 0;
    bool same = s.row_vertices == n;
    for (const PaperSpring& sp : s.springs) {
        if (sp.broken) continue;
        same = same && live < s.link_ends.size() && s.link_ends[live][0] == sp.a && s.link_ends[live][1] == sp.b;
        ++live;
    }
    if (same && live == s.link_ends.size()) return;
    s.link_ends.clear();
    for (const PaperSpring& sp : s.springs)
        if (!sp.broken) s.link_ends.push_back({sp.a, sp.b});
    s.vertex_link_start.assign(n + 1, 0);
    for (const auto& [a, b] : s.link_ends) {
        ++s.vertex_link_start[a + 1];
        ++s.vertex_link_start[b + 1];
    }
    for (std::size_t i = 0; i < n; ++i) s.vertex_link_start[i + 1] += s.vertex_link_start[i];
    const std::size_t entries = s.vertex_link_start[n];
    s.row_coupling.assign(entries, JacobiCoupling{});
    s.row_force.assign(entries, Vec3::Zero());
    s.link_slot.resize(s.link_ends.size());
    std::vector<std::uint32_t> fill(s.vertex_link_start.begin(), s.vertex_link_start.end() - 1);
    for (std::size_t k = 0; k < s.link_ends.size(); ++k) {
        const auto [a, b] = s.link_ends[k];
        s.link_slot[k] = {fill[a]++, fill[b]++};
        s.row_coupling[s.link_slot[k][0]].other = b;
        s.row_coupling[s.link_slot[k][1]].other = a;
    }
    s.row_vertices = n;
}

}  // namespace

void solveVelocities(PaperSheet& s, const RigidTable& rigids, const PaperStep& ctx) {
    const std::size_t n = s.vertices();
    const double h = ctx.h, h2 = h * h;
    const double damping = s.desc.damping;
    const bool implicit = s.desc.integrator == PaperIntegrator::Implicit;
    s.rhs.resize(n);
    s.dv.resize(n);
    s.dv_next.resize(n);
    s.diag_inv.resize(n);
    s.fixed.resize(n);
    s.added_mass.resize(n, Mat3::Zero());
    s.added_force.resize(n, Vec3::Zero());
    buildRows(s);

    // Pass 1, per live spring: direction, force and coupling, written into the row entries
    // of its two vertices. No spring adds to a vertex: consecutive springs that share a
    // vertex do not wait on each other's stores, and pass 2 and the sweeps read the rows
    // in order.
    std::size_t k = 0;
    for (const PaperSpring& sp : s.springs) {
        if (sp.broken) continue;
        const auto [slot_a, slot_b] = s.link_slot[k++];
        JacobiCoupling& row_a = s.row_coupling[slot_a];
        JacobiCoupling& row_b = s.row_coupling[slot_b];
        const Vec3 e = s.x[sp.b] - s.x[sp.a];
        const double l = e.norm();
        if (!(l > 1e-12)) {  // no direction: no force, no coupling
            row_a.iso = row_a.along = row_b.iso = row_b.along = 0.0;
            row_a.dir.setZero();
            row_b.dir.setZero();
            s.row_force[slot_a].setZero();
            s.row_force[slot_b].setZero();
            continue;
        }
        const double inv_l = 1.0 / l;  // one division per spring, not four
        const Vec3 d = e * inv_l;
        const Vec3 relative = s.v[sp.b] - s.v[sp.a];
        // springForce: elastic and damping force on a.
        Vec3 f = h * (sp.stiffness * (l - sp.rest) + damping * sp.stiffness * d.dot(relative)) * d;
        // K = k (d d^T + t (I - d d^T)), t = max(0, 1 - l0 / l): the block
        // h c d d^T + h^2 K = iso I + along d d^T needs two numbers and d, not nine.
        const double t = std::max(0.0, 1.0 - sp.rest * inv_l);
        const double iso = h2 * sp.stiffness * t;
        const double axial = h2 * sp.stiffness * (1.0 - t);
        const double along = h * damping * sp.stiffness + axial;
        // h^2 J v: row a gets -h^2 K (v_a - v_b) = h^2 K (v_b - v_a); row b the opposite.
        if (implicit) f += iso * relative + (axial * d.dot(relative)) * d;
        row_a.iso = row_b.iso = iso;
        row_a.along = row_b.along = along;
        row_a.dir = row_b.dir = d;
        s.row_force[slot_a] = f;
        s.row_force[slot_b] = -f;
    }

    // Pass 2, per vertex: rhs = h f + h^2 J v (gravity, the user's force, the bodies'
    // lent weight, the springs) and W_ii = M + sum of the blocks.
    const std::uint32_t* const start = s.vertex_link_start.data();
    const JacobiCoupling* const row = s.row_coupling.data();
    for (std::size_t i = 0; i < n; ++i) {
        // Pins and glue to immovable bodies prescribe the velocity; a glue to a movable
        // body was turned into added mass (coupleBodies).
        s.fixed[i] = s.hold[i].kind == VertexHold::Kind::Pin ||
                     (s.hold[i].kind == VertexHold::Kind::Glue && !rigids.movable(s.hold[i].body));
        Vec3 rhs = h * (s.mass[i] * ctx.gravity + s.force[i] + s.added_force[i]);
        // The symmetric sum of the blocks in scalars (kept in registers; an Eigen 3x3
        // accumulator is spilled to the stack and reloaded in every pass of the loop).
        double iso = 0.0, xx = 0.0, yy = 0.0, zz = 0.0, xy = 0.0, xz = 0.0, yz = 0.0;
        for (std::uint32_t j = start[i]; j < start[i + 1]; ++j) {
            rhs += s.row_force[j];
            const JacobiCoupling& c = row[j];
            const Vec3 u = c.along * c.dir;
            iso += c.iso;
            xx += u.x() * c.dir.x();
            yy += u.y() * c.dir.y();
            zz += u.z() * c.dir.z();
            xy += u.x() * c.dir.y();
            xz += u.x() * c.dir.z();
            yz += u.y() * c.dir.z();
        }
        s.rhs[i] = rhs;
        Mat3 diag;  // W_ii, inverted below
        diag << xx + iso, xy, xz, xy, yy + iso, yz, xz, yz, zz + iso;
        if (!implicit) diag.setZero();
        s.diag_inv[i] = diag + s.mass[i] * Mat3::Identity() + s.added_mass[i];
    }
    if (!implicit) {
        // Semi-implicit (symplectic) Euler: v += h f / m. Stable only for h < 2 / omega.
        for (std::size_t i = 0; i < n; ++i)
            s.v[i] = s.fixed[i] ? heldVelocity(s, i, rigids, ctx) : Vec3(s.v[i] + s.diag_inv[i].inverse() * s.rhs[i]);
    } else {
        for (std::size_t i = 0; i < n; ++i) {
            if (s.fixed[i]) {
                s.dv[i] = heldVelocity(s, i, rigids, ctx) - s.v[i];
                continue;
            }
            s.diag_inv[i] = s.diag_inv[i].inverse().eval();
            s.dv[i] = s.diag_inv[i] * s.rhs[i];  // Eq. 6, k = 0
        }
        // Eq. 6, weighted: per vertex, b_i - sum_j W_ij dv_j (W_ij = -block, so + block dv_j)
        // gathered over its row in registers, then W_ii^-1 and the weight. A held vertex
        // keeps its prescribed dv.
        for (int it = 0; it < s.desc.jacobi_iterations; ++it) {
            const Vec3* const dv = s.dv.data();
            Vec3* const next = s.dv_next.data();
            for (std::size_t i = 0; i < n; ++i) {
                if (s.fixed[i]) {
                    next[i] = dv[i];
                    continue;
                }
                // Two partial sums, even and odd entries: two chains of additions instead
                // of one (the sum's latency, not the arithmetic, bounds the loop).
                Vec3 even = s.rhs[i], odd = Vec3::Zero();
                std::uint32_t j = start[i];
                const std::uint32_t end = start[i + 1];
                for (; j + 1 < end; j += 2) {
                    const JacobiCoupling& c0 = row[j];
                    const JacobiCoupling& c1 = row[j + 1];
                    const Vec3& o0 = dv[c0.other];
                    const Vec3& o1 = dv[c1.other];
                    even += c0.iso * o0 + (c0.along * c0.dir.dot(o0)) * c0.dir;
                    odd += c1.iso * o1 + (c1.along * c1.dir.dot(o1)) * c1.dir;
                }
                if (j < end) {
                    const JacobiCoupling& c = row[j];
                    const Vec3& o = dv[c.other];
                    even += c.iso * o + (c.along * c.dir.dot(o)) * c.dir;
                }
                next[i] = (1.0 - kJacobiWeight) * dv[i] + kJacobiWeight * (s.diag_inv[i] * (even + odd));
            }
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
