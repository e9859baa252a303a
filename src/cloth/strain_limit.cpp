// Stage: strain limiting of the weave, the strings' solve (string/strain_limit.cpp) from a
// chain to a mesh: backward Euler with the yarns at the material's own stiffness,
//   x, u = argmin  sum_i m_i/(2h^2) |x_i - x'_i|^2 + sum_b u_b^T M_b u_b / (2h^2)
//                + sum_yarn k_e/2 max(0, |x_b - x_a| - L_e)^2          (stiff: k_e = E A / L_e)
//                + sum_soft k_s/2 (|x_b - x_a| - L_s)^2                 (shear, bending)
//                + sum_penalty k_c/2 g^2  (contacts: only where g < 0; glue: always),
// the compliance form of Yarn Sec. 3.3's L_max = L (1 + sigma / E), met implicitly; a slack
// yarn pushes nothing, so yarns buckle freely. Newton's method with the geometric stiffness
// (projected positive semi-definite for compressed soft springs), solved by conjugate
// gradients preconditioned with a sparse Cholesky of the Hessian with its bending blocks
// lumped (linalg/supernodal.hpp, nested-dissection order, the analysis reused while the
// pattern stays; the Hessian's SimplicialLDLT where a pivot is not positive), and a
// backtracking line search on the energy: exact at any stiffness ratio, where Jacobi or
// PBD sweeps would need many.
#include "cloth/cloth_state.hpp"

#include <algorithm>
#include <cmath>

namespace tearables::detail {

namespace {

using Vec6 = Eigen::Matrix<double, 6, 1>;
using Mat6 = Eigen::Matrix<double, 6, 6>;

// Rigid bodies: a movable body a cloth touches or holds is 6 unknowns (translation u,
// rotation w) with its mass and inertia M_b, relative to the pose the host already
// integrated; contacts and glues are linear penalty rows g = n.x_v - n.(u + w x r) - c, so
// the cloth holds the body with its real mass and the body pushes the cloth (two-way, as
// the strings do). The penalty is 100x the stiffest yarn or inertia it competes with.
constexpr double kPenaltyFactor = 100.0;
constexpr int kLineSearchSteps = 12;
/// The Newton system's conjugate gradients (Solver::solveStep) stop when the preconditioned
/// residual has fallen by the forcing factor eta = min(kNewtonSolveTolerance, |g| / |g_0|)
/// (g_0 the gradient of the solve's first iteration; floored at kNewtonSolveFloor), or after
/// kNewtonSolveIterations. Newton with such a solve converges superlinearly where the exact
/// one converges quadratically (Dembo, Eisenstat and Steihaug 1982: eta -> 0 gives
/// superlinear convergence; Eisenstat and Walker 1996), so a taut cloth still ends a step
/// near round-off, while iterations far from the minimum, or stalled at a slack or contact
/// switch, stop after 5-6 iterations instead of solving to round-off. A crack follows
/// stresses that differ by little: a 9 x 7 cloth of uniform yarns pulled apart (the
/// preconditioner made to lump) tears where the direct solve tears it in each of nine
/// pulls (0.04-0.06 m/s, damping 0.5-2 /s) at 1e-5, and elsewhere in four of them at 1e-4.
constexpr double kNewtonSolveTolerance = 1e-5;
constexpr double kNewtonSolveFloor = 1e-12;
constexpr int kNewtonSolveIterations = 50;

bool movableGlue(const ClothState& c, const RigidTable& rigids, std::size_t p) {
    return c.hold[p].kind == ParticleHold::Kind::Glue && rigids.movable(c.hold[p].body);
}

Mat6 bodyMass(const RigidState& b) {
    Mat6 m = Mat6::Zero();
    m.topLeftCorner<3, 3>() = Mat3::Identity() / b.inverse_mass;
    const Mat3 inv_inertia = b.inverseInertiaWorld();
    // A body with a zero inverse inertia (a point mass) does not turn: a huge inertia.
    m.bottomRightCorner<3, 3>() = inv_inertia.determinant() > 0.0 ? Mat3(inv_inertia.inverse()) : Mat3(Mat3::Identity() * 1e12);
    return m;
}

int nodeFor(ClothState& c, const RigidTable& rigids, RigidId body) {
    for (std::size_t k = 0; k < c.nodes.size(); ++k)
        if (c.nodes[k].body == body) return static_cast<int>(k);
    ClothBodyNode node;
    node.body = body;
    node.mass = bodyMass(rigids.bodies[body.index]);
    c.nodes.push_back(node);
    return static_cast<int>(c.nodes.size() - 1);
}

/// Gap of a penalty row at trial positions and body displacements.
double rowGap(const PenaltyRow& r, const std::vector<Vec3>& x, const std::vector<Vec6>& u) {
    double g = r.normal.dot(x[r.vertex]) - r.offset;
    if (r.node >= 0) {
        const Vec6& d = u[static_cast<std::size_t>(r.node)];
        g -= r.normal.dot(d.head<3>()) + r.arm.cross(r.normal).dot(d.tail<3>());
    }
    return g;
}

struct Solver {
    ClothState& c;
    const StepContext& ctx;
    double inv_h2;
    std::vector<Vec6> u, u_trial;
    bool use_estimate = true;  ///< the yarns take yarn_estimate in their geometric terms (not after a cut step)

    double energy(const std::vector<Vec3>& x, const std::vector<Vec6>& us) const {
        double e = 0.0;
        for (std::size_t p = 0; p < c.vertices(); ++p)
            if (c.dof[p] >= 0) e += 0.5 * c.mass[p] * inv_h2 * (x[p] - c.x_pred[p]).squaredNorm();
        for (std::size_t k = 0; k < c.nodes.size(); ++k) e += 0.5 * inv_h2 * us[k].dot(c.nodes[k].mass * us[k]);
        for (std::size_t e_i = 0; e_i < c.edgeCount(); ++e_i) {
            if (c.broken[e_i]) continue;
            const double stretch = (x[c.edges[e_i][1]] - x[c.edges[e_i][0]]).norm() - c.rest_length[e_i];
            if (stretch > 0.0) e += 0.5 * c.stiffness[e_i] * stretch * stretch;
        }
        for (const SoftSpring& s : c.springs) {
            if (!s.alive) continue;
            const double stretch = (x[s.b] - x[s.a]).norm() - s.rest;
            e += 0.5 * s.stiffness * stretch * stretch;
        }
        for (const PenaltyRow& r : c.penalty) {
            const double g = rowGap(r, x, us);
            if (!r.one_sided || g < 0.0) e += 0.5 * c.penalty_stiffness * g * g;
        }
        return e;
    }

    /// Records a 3x3 block of the Hessian at (a, b) (both multiples of 3, or -1 for a fixed
    /// vertex); assemble() puts them into the matrix.
    void block(int a, int b, const Mat3& m) {
        if (a < 0 || b < 0) return;
        c.hessian_block_at.push_back({a, b});
        c.hessian_block.push_back(m);
    }

    /// Puts the recorded blocks into c.hessian. While the blocks come in the same order at
    /// the same places as when the pattern was built (same topology, contacts and bodies:
    /// every step in between), each block is written straight into the compressed values,
    /// in the order the triplets were summed (bit for bit what setFromTriplets gives);
    /// otherwise the pattern is built anew from triplets and the places remembered.
    void storeBlocks() {
        const std::size_t count = c.hessian_block_at.size();
        const bool same = c.hessian_pattern_at.size() == count && c.hessian.rows() == c.unknowns &&
                          std::equal(c.hessian_block_at.begin(), c.hessian_block_at.end(), c.hessian_pattern_at.begin());
        if (!same) {
            c.triplets.clear();
            c.triplets.reserve(9 * count);
            for (std::size_t i = 0; i < count; ++i) {
                const auto [a, b] = c.hessian_block_at[i];
                for (int r = 0; r < 3; ++r)
                    for (int k = 0; k < 3; ++k) c.triplets.emplace_back(a + r, b + k, c.hessian_block[i](r, k));
            }
            c.hessian.resize(c.unknowns, c.unknowns);
            c.hessian.setFromTriplets(c.triplets.begin(), c.triplets.end());
            c.hessian.makeCompressed();
            // Where each block's three columns start in the values, and whether it is the
            // first block summed there (the 3x3 tiles are aligned: a tile's entries share that).
            const int* outer = c.hessian.outerIndexPtr();
            const int* inner = c.hessian.innerIndexPtr();
            std::vector<std::uint8_t> touched(static_cast<std::size_t>(c.hessian.nonZeros()), 0);
            c.hessian_slot.resize(count);
            c.hessian_first.resize(count);
            for (std::size_t i = 0; i < count; ++i) {
                const auto [a, b] = c.hessian_block_at[i];
                for (int k = 0; k < 3; ++k) {
                    const int* at = std::lower_bound(inner + outer[b + k], inner + outer[b + k + 1], a);
                    c.hessian_slot[i][k] = static_cast<int>(at - inner);
                }
                c.hessian_first[i] = !touched[static_cast<std::size_t>(c.hessian_slot[i][0])];
                touched[static_cast<std::size_t>(c.hessian_slot[i][0])] = 1;
            }
            c.hessian_pattern_at = c.hessian_block_at;
            buildPreconditionerPattern();
            return;
        }
        double* values = c.hessian.valuePtr();
        for (std::size_t i = 0; i < count; ++i) {
            const Mat3& m = c.hessian_block[i];
            const auto& slot = c.hessian_slot[i];
            if (c.hessian_first[i]) {
                for (int k = 0; k < 3; ++k)
                    for (int r = 0; r < 3; ++r) values[slot[k] + r] = m(r, k);
            } else {
                for (int k = 0; k < 3; ++k)
                    for (int r = 0; r < 3; ++r) values[slot[k] + r] += m(r, k);
            }
        }
    }

    /// The pattern of c.preconditioner and where its values come from (see ClothState): the
    /// lower triangle of the Hessian, where c.lump_bending without the blocks that link
    /// vertices of different cells (else P = H, and one conjugate-gradient iteration is the
    /// direct solve); such a block -K of a spring (K positive semi-definite) is dropped and K added
    /// to both vertices' diagonal blocks. P - H is then [K K; K K] on those two vertices,
    /// positive semi-definite: P >= H, and P - H <= 2 K on the diagonal, so the conjugate
    /// gradients' rate is set by the bending springs' stiffness over the inertia and the
    /// yarns' (a bending spring is soft: 0.05 N/m for the defaults' 1 cm cells, against
    /// m/h^2 = 0.1 N/m at h = 0.01 s; 4-5 iterations a Newton step), and the weave's
    /// separators are one column of vertices wide instead of two (a quarter of the
    /// factorisation's work at 64 x 64: BENCHMARKS.md).
    void buildPreconditionerPattern() {
        std::vector<int> vertex_of(static_cast<std::size_t>(c.unknowns), -1);  // body unknowns: -1
        for (std::size_t p = 0; p < c.vertices(); ++p)
            if (c.dof[p] >= 0)
                for (int k = 0; k < 3; ++k) vertex_of[static_cast<std::size_t>(c.dof[p] + k)] = static_cast<int>(p);
        const int* outer = c.hessian.outerIndexPtr();
        const int* inner = c.hessian.innerIndexPtr();
        auto lumped = [&](int row, int col) {
            const int a = vertex_of[static_cast<std::size_t>(row)], b = vertex_of[static_cast<std::size_t>(col)];
            return c.lump_bending && a >= 0 && b >= 0 && a != b &&
                   clothLumped(c, static_cast<std::uint32_t>(a), static_cast<std::uint32_t>(b));
        };
        c.triplets.clear();
        for (int col = 0; col < c.unknowns; ++col)
            for (int p = outer[col]; p < outer[col + 1]; ++p)
                if (inner[p] >= col && !lumped(inner[p], col)) c.triplets.emplace_back(inner[p], col, 0.0);
        c.preconditioner.resize(c.unknowns, c.unknowns);
        c.preconditioner.setFromTriplets(c.triplets.begin(), c.triplets.end());
        c.preconditioner.makeCompressed();
        const int* p_outer = c.preconditioner.outerIndexPtr();
        const int* p_inner = c.preconditioner.innerIndexPtr();
        auto at = [&](int row, int col) {
            return static_cast<int>(std::lower_bound(p_inner + p_outer[col], p_inner + p_outer[col + 1], row) - p_inner);
        };
        c.precondition_copy_to.clear();
        c.precondition_copy_from.clear();
        c.precondition_lump_to.clear();
        c.precondition_lump_from.clear();
        for (int col = 0; col < c.unknowns; ++col)
            for (int p = outer[col]; p < outer[col + 1]; ++p) {
                const int row = inner[p];
                if (row < col) continue;
                if (!lumped(row, col)) {
                    c.precondition_copy_to.push_back(at(row, col));
                    c.precondition_copy_from.push_back(p);
                    continue;
                }
                // Entry (r, k) of the block -K: K_rk joins both diagonal blocks' lower
                // triangles (r >= k; the entry (k, r) of the same block is K_kr = K_rk).
                const int da = c.dof[static_cast<std::size_t>(vertex_of[static_cast<std::size_t>(row)])];
                const int db = c.dof[static_cast<std::size_t>(vertex_of[static_cast<std::size_t>(col)])];
                const int r = row - da, k = col - db;
                if (r < k) continue;
                for (const int d : {da, db}) {
                    c.precondition_lump_to.push_back(at(d + r, d + k));
                    c.precondition_lump_from.push_back(p);
                }
            }
    }

    /// Gradient and Hessian of a spring between a and b (one_sided: a yarn, no push).
    /// `estimate` (yarns only, else null): the stretch the Hessian's geometric term takes
    /// where it is positive and below the stretch now (see run()); replaced by the stretch
    /// now, or 0 where the yarn is slack, for linearisedStretch.
    void spring(std::uint32_t a, std::uint32_t b, double k, double rest, bool one_sided, double* estimate) {
        const Vec3 d = c.x[b] - c.x[a];
        const double len = d.norm();
        Mat3 hess = Mat3::Zero();
        if (len > 1e-15 && (!one_sided || len > rest)) {
            const Vec3 n = d / len;
            const double stretch = len - rest;
            const Vec3 f = k * stretch * n;  // dE/dx_b
            if (c.dof[b] >= 0) c.gradient.segment<3>(c.dof[b]) += f;
            if (c.dof[a] >= 0) c.gradient.segment<3>(c.dof[a]) -= f;
            const Mat3 nn = n * n.transpose();
            double q = std::max(0.0, 1.0 - rest / len);
            if (estimate) {
                if (use_estimate && *estimate > 0.0 && *estimate < stretch) q = *estimate / len;
                *estimate = stretch;
            }
            hess = k * (nn + q * (Mat3::Identity() - nn));
        } else if (estimate) {
            *estimate = 0.0;
        }
        // Every block is inserted, zero or not, so the pattern stays the same in a step.
        block(c.dof[a], c.dof[a], hess);
        block(c.dof[b], c.dof[b], hess);
        block(c.dof[a], c.dof[b], -hess);
        block(c.dof[b], c.dof[a], -hess);
    }

    void assemble() {
        c.gradient.setZero(c.unknowns);
        c.hessian_block_at.clear();
        c.hessian_block.clear();
        for (std::size_t p = 0; p < c.vertices(); ++p) {
            if (c.dof[p] < 0) continue;
            c.gradient.segment<3>(c.dof[p]) += c.mass[p] * inv_h2 * (c.x[p] - c.x_pred[p]);
            block(c.dof[p], c.dof[p], c.mass[p] * inv_h2 * Mat3::Identity());
        }
        for (std::size_t k = 0; k < c.nodes.size(); ++k) {
            const int d = c.nodes[k].dof;
            c.gradient.segment<6>(d) += inv_h2 * (c.nodes[k].mass * u[k]);
            const Mat6 m = inv_h2 * c.nodes[k].mass;
            block(d, d, m.topLeftCorner<3, 3>());
            block(d, d + 3, m.topRightCorner<3, 3>());
            block(d + 3, d, m.bottomLeftCorner<3, 3>());
            block(d + 3, d + 3, m.bottomRightCorner<3, 3>());
        }
        for (std::size_t e = 0; e < c.edgeCount(); ++e)
            if (!c.broken[e]) spring(c.edges[e][0], c.edges[e][1], c.stiffness[e], c.rest_length[e], true, &c.yarn_estimate[e]);
        for (const SoftSpring& s : c.springs)
            if (s.alive) spring(s.a, s.b, s.stiffness, s.rest, false, nullptr);
        for (const PenaltyRow& r : c.penalty) {
            const double g = rowGap(r, c.x, u);
            const double k = (!r.one_sided || g < 0.0) ? c.penalty_stiffness : 0.0;
            // J: n at the vertex, -n at the translation, -(arm x n) at the rotation.
            Eigen::Matrix<double, 9, 1> j;
            j.head<3>() = r.normal;
            j.segment<3>(3) = -r.normal;
            j.tail<3>() = -r.arm.cross(r.normal);
            const int dv = c.dof[r.vertex];
            const int dn = r.node >= 0 ? c.nodes[static_cast<std::size_t>(r.node)].dof : -1;
            const int idx[3] = {dv, dn, dn < 0 ? -1 : dn + 3};
            for (int a = 0; a < 3; ++a) {
                if (idx[a] < 0) continue;
                c.gradient.segment<3>(idx[a]) += k * g * j.segment<3>(3 * a);
                for (int b = 0; b < 3; ++b)
                    if (idx[b] >= 0) block(idx[a], idx[b], k * j.segment<3>(3 * a) * j.segment<3>(3 * b).transpose());
            }
        }
        storeBlocks();
    }

    /// Factorises the preconditioner, reusing the symbolic analysis while the pattern is
    /// the same.
    bool factor() {
        double* to = c.preconditioner.valuePtr();
        const double* from = c.hessian.valuePtr();
        for (std::size_t k = 0; k < c.precondition_copy_to.size(); ++k) to[c.precondition_copy_to[k]] = from[c.precondition_copy_from[k]];
        for (std::size_t k = 0; k < c.precondition_lump_to.size(); ++k) to[c.precondition_lump_to[k]] -= from[c.precondition_lump_from[k]];
        if (!c.newton_analysed || !c.newton_llt.samePattern(c.preconditioner)) {
            c.newton_llt.analyze(c.preconditioner);
            c.newton_analysed = true;
        }
        ++c.strain_factorizations;
        c.newton_factored_llt = c.newton_llt.factorize(c.preconditioner);
        if (c.newton_factored_llt) return true;
        // Not positive definite in round-off: the Hessian's LDL^T.
        if (!c.newton_solver) c.newton_solver = std::make_unique<ClothLDLT>();
        c.newton_solver->compute(c.hessian);
        return c.newton_solver->info() == Eigen::Success;
    }

    /// c.step = the Newton step H^-1 (-g), by conjugate gradients preconditioned with the
    /// factors of P (buildPreconditionerPattern) from zero, until the preconditioned
    /// residual's P^-1 norm has fallen by `forcing`. Every iterate is a descent
    /// direction (it minimises the quadratic model over a subspace holding -P^-1 g), so the
    /// line search takes any of them; the solve's accuracy sets how fast Newton converges,
    /// not what it converges to (the gradient is exact).
    void solveStep(double forcing) {
        if (!c.lump_bending) {  // P = H: the direct solve
            c.step = -c.gradient;
            c.newton_llt.solveInPlace(c.step);
            return;
        }
        c.step.setZero(c.unknowns);
        c.cg_r = -c.gradient;
        c.cg_z = c.cg_r;
        c.newton_llt.solveInPlace(c.cg_z);
        double rz = c.cg_r.dot(c.cg_z);
        const double stop = forcing * forcing * rz;
        c.cg_p = c.cg_z;
        for (int it = 0; it < kNewtonSolveIterations && rz > 0.0; ++it) {
            c.cg_q.noalias() = c.hessian * c.cg_p;
            const double pq = c.cg_p.dot(c.cg_q);
            if (!(pq > 0.0)) break;
            const double alpha = rz / pq;
            c.step += alpha * c.cg_p;
            c.cg_r -= alpha * c.cg_q;
            ++c.strain_cg_iterations;
            c.cg_z = c.cg_r;
            c.newton_llt.solveInPlace(c.cg_z);
            const double next = c.cg_r.dot(c.cg_z);
            if (!(next > stop)) break;
            c.cg_p = c.cg_z + (next / rz) * c.cg_p;
            rz = next;
        }
    }

    /// Each yarn's stretch after the step alpha * c.step from c.x, to first order:
    /// max(0, C + e . (dx_b - dx_a)), into yarn_estimate (0 for yarns slack at c.x). C, the
    /// stretch at c.x, is what assemble() left there. As in the strings' solve, the exact
    /// k C at an iterate overstates the tension (a transverse move d stretches a stiff yarn
    /// by ~d^2 / 2L) and stalls the line search; the geometric term takes this estimate
    /// where it is smaller (the gradient stays exact: the same minimum), and the exact k C
    /// in the iteration after a cut step.
    void linearisedStretch(double alpha) {
        auto move = [&](std::uint32_t p) {
            return c.dof[p] >= 0 ? Vec3(alpha * c.step.segment<3>(c.dof[p])) : Vec3::Zero();
        };
        for (std::size_t e = 0; e < c.edgeCount(); ++e) {
            double& estimate = c.yarn_estimate[e];
            if (c.broken[e] || !(estimate > 0.0)) {
                estimate = 0.0;
                continue;
            }
            const auto [a, b] = c.edges[e];
            const Vec3 d = c.x[b] - c.x[a];
            estimate = std::max(0.0, estimate + d.dot(move(b) - move(a)) / d.norm());
        }
    }

    void run() {
        const int max_iterations = ctx.settings ? ctx.settings->strain_iterations : 8;
        const double tolerance = (ctx.settings ? ctx.settings->strain_tolerance : 1e-6) * c.shortest_rest;
        u.assign(c.nodes.size(), Vec6::Zero());
        u_trial = u;
        // The first iteration's geometric terms take the stretches the yarns ended the
        // last step with (its final positions, x_prev).
        c.yarn_estimate.resize(c.edgeCount());
        for (std::size_t e = 0; e < c.edgeCount(); ++e)
            c.yarn_estimate[e] = std::max(0.0, (c.x_prev[c.edges[e][1]] - c.x_prev[c.edges[e][0]]).norm() - c.rest_length[e]);
        double current = energy(c.x, u);
        c.strain_newton_iterations = 0;
        c.strain_factorizations = 0;
        c.strain_cg_iterations = 0;
        c.strain_last_move = 0.0;
        double first_gradient = 0.0;
        for (int it = 0; it < max_iterations; ++it) {
            assemble();
            if (!factor()) break;
            const double gradient_norm = c.gradient.norm();
            if (it == 0) first_gradient = gradient_norm;
            if (c.newton_factored_llt) {
                const double ratio = first_gradient > 0.0 ? gradient_norm / first_gradient : 0.0;
                solveStep(std::max(kNewtonSolveFloor, std::min(kNewtonSolveTolerance, ratio)));
            } else {
                c.step = c.newton_solver->solve(-c.gradient);
            }
            if (!c.step.allFinite()) break;
            const double slope = c.gradient.dot(c.step);
            if (!(slope < 0.0)) break;  // no descent left: converged to round-off
            double alpha = 1.0, trial = current;
            bool accepted = false;
            for (int ls = 0; ls < kLineSearchSteps; ++ls, alpha *= 0.5) {
                for (std::size_t p = 0; p < c.vertices(); ++p)
                    c.x_trial[p] = c.dof[p] >= 0 ? Vec3(c.x[p] + alpha * c.step.segment<3>(c.dof[p])) : c.x[p];
                for (std::size_t k = 0; k < c.nodes.size(); ++k) u_trial[k] = u[k] + alpha * c.step.segment<6>(c.nodes[k].dof);
                trial = energy(c.x_trial, u_trial);
                if (trial <= current + 1e-4 * alpha * slope) {
                    accepted = true;
                    break;
                }
            }
            if (!accepted) break;
            linearisedStretch(alpha);
            // A step the line search cut: the next Hessian takes the exact k C (see top).
            use_estimate = alpha == 1.0;
            c.x.swap(c.x_trial);
            u.swap(u_trial);
            current = trial;
            c.strain_newton_iterations = it + 1;
            c.strain_last_move = alpha * c.step.lpNorm<Eigen::Infinity>();
            if (c.strain_last_move < tolerance) break;
        }
        for (std::size_t k = 0; k < c.nodes.size(); ++k) c.nodes[k].u = u[k];
        for (VertexContact& vc : c.contacts) vc.force = 0.0;
        for (const PenaltyRow& r : c.penalty)
            if (r.one_sided && r.contact >= 0)
                c.contacts[static_cast<std::size_t>(r.contact)].force = c.penalty_stiffness * std::max(0.0, -rowGap(r, c.x, u));
    }
};

/// Moves a body by a generalised displacement (translation, rotation vector).
void displaceBody(RigidState& b, const Vec6& u) {
    b.position += u.head<3>();
    const Vec3 rotation = u.tail<3>();
    const double angle = rotation.norm();
    if (angle > 0.0) b.orientation = (Quat(Eigen::AngleAxisd(angle, rotation / angle)) * b.orientation).normalized();
}

}  // namespace

void limitClothStrain(ClothState& c, RigidTable& rigids, const StepContext& ctx) {
    // Unknowns: free vertices and vertices glued to movable bodies, then the body nodes.
    c.nodes.clear();
    c.penalty.clear();
    // Numbered in nested-dissection order (gridDissection): the factorisation keeps it.
    int next = 0;
    for (const std::uint32_t p : clothVertexOrder(c)) {
        const bool moves = c.hold[p].kind == ParticleHold::Kind::Free || movableGlue(c, rigids, p);
        c.dof[p] = moves ? next : -1;
        if (moves) next += 3;
    }
    double stiffest = 0.0;
    for (std::size_t e = 0; e < c.edgeCount(); ++e)
        if (!c.broken[e]) stiffest = std::max(stiffest, c.stiffness[e]);
    for (std::size_t p = 0; p < c.vertices(); ++p) stiffest = std::max(stiffest, c.mass[p] * ctx.inv_h * ctx.inv_h);
    const double radius = c.desc.yarn_radius;
    for (std::size_t k = 0; k < c.contacts.size(); ++k) {
        const VertexContact& vc = c.contacts[k];
        if (c.dof[vc.vertex] < 0) continue;
        PenaltyRow r;
        r.vertex = vc.vertex;
        r.normal = vc.normal;
        r.offset = vc.normal.dot(vc.point) + radius;
        r.one_sided = true;
        r.contact = static_cast<int>(k);
        if (rigids.movable(vc.body)) {
            r.node = nodeFor(c, rigids, vc.body);
            r.arm = vc.point - rigids.bodies[vc.body.index].position;
        }
        c.penalty.push_back(r);
    }
    for (std::size_t p = 0; p < c.vertices(); ++p) {
        if (!movableGlue(c, rigids, p)) continue;
        const RigidState& b = rigids.bodies[c.hold[p].body.index];
        const Vec3 point = gluePoint(b, c.hold[p].point);
        const int node = nodeFor(c, rigids, c.hold[p].body);
        for (int axis = 0; axis < 3; ++axis) {
            PenaltyRow r;
            r.vertex = static_cast<std::uint32_t>(p);
            r.normal = Vec3::Unit(axis);
            r.offset = r.normal.dot(point);
            r.node = node;
            r.arm = point - b.position;
            r.one_sided = false;
            c.penalty.push_back(r);
        }
    }
    for (ClothBodyNode& node : c.nodes) {
        node.dof = next;
        next += 6;
        const Mat6& m = node.mass;
        stiffest = std::max(stiffest, m.diagonal().head<3>().maxCoeff() * ctx.inv_h * ctx.inv_h);
    }
    c.unknowns = next;
    c.penalty_stiffness = kPenaltyFactor * stiffest;
    if (c.unknowns == 0) return;
    Solver solver{c, ctx, ctx.inv_h * ctx.inv_h, {}, {}};
    solver.run();
    // The bodies move by what the cloth did to them; World::step turns that into velocity.
    for (const ClothBodyNode& node : c.nodes) {
        RigidState& b = rigids.bodies[node.body.index];
        displaceBody(b, node.u);
        b.impulse += (node.mass.topLeftCorner<3, 3>() * node.u.head<3>()) * ctx.inv_h;
    }
}

}  // namespace tearables::detail
