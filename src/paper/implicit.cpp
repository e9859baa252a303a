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
#include "base/lanes.hpp"
#include "paper/sheet.hpp"
#include "sim/rigid_table.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

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
/// flips that mode's displacement every step and the sheet rings forever. Weighted Jacobi
/// with w = 2/3, the textbook smoother, maps that eigenvalue to -1/3: the mode is damped
/// for every iteration count.
constexpr double kJacobiWeight = 2.0 / 3.0;

/// Velocity a held vertex must have to be where its holder is at the end of the step.
Vec3 heldVelocity(const PaperSheet& s, std::size_t i, const RigidTable& rigids, const PaperStep& ctx) {
    const ParticleHold& hold = s.hold[i];
    if (hold.kind == ParticleHold::Kind::Pin) return (hold.point - s.x[i]) * ctx.inv_h;
    const RigidState& b = rigids.bodies[hold.body.index];
    return (gluePoint(b, hold.point) - s.x[i]) * ctx.inv_h;
}

}  // namespace

namespace {

/// Two doubles in one SIMD register (GCC's and Clang's vector extension: SSE2 on x86-64,
/// NEON on AArch64, scalar code elsewhere); +, - and * act on both lanes.
typedef double Lanes __attribute__((vector_size(16)));
/// Four doubles: one AVX register where the sweep is compiled for AVX2 (jacobiPassAvx2).
typedef double Lanes4 __attribute__((vector_size(32)));
/// Lane indices of __builtin_shuffle on two Lanes4 (0-3 the first, 4-7 the second).
typedef long long LaneIndex4 __attribute__((vector_size(32)));

/// Lanes `lane` and `lane + 1` of a block's array.
inline Lanes load2(const double (&quad)[4], unsigned lane) {
    Lanes v;
    std::memcpy(&v, quad + lane, sizeof v);
    return v;
}

/// The rows of the Jacobi gather: per vertex, the couplings of its live springs, in spring
/// order (so every sum is deterministic), padded with a zero entry to an even length (the
/// sweep sums even and odd entries apart, two or four entries at a time). They depend only
/// on the live springs' ends and the vertex count, and are rebuilt only when those changed
/// (a crease or a tear): the check is one pass over the springs.
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
    assignGrowing(s.vertex_link_start, n + 1, 0);
    for (const auto& [a, b] : s.link_ends) {
        ++s.vertex_link_start[a + 1];
        ++s.vertex_link_start[b + 1];
    }
    for (std::size_t i = 0; i < n; ++i) s.vertex_link_start[i + 1] += s.vertex_link_start[i] + (s.vertex_link_start[i + 1] & 1u);
    const std::size_t entries = s.vertex_link_start[n];
    assignGrowing(s.row_quads, (entries + 3) / 4, JacobiQuad{});
    assignGrowing(s.row_force, entries, Vec3::Zero());
    s.link_slot.resize(s.link_ends.size());
    std::vector<std::uint32_t> fill(s.vertex_link_start.begin(), s.vertex_link_start.end() - 1);
    for (std::size_t i = 0; i < n; ++i)  // pads: a zero coupling to the vertex itself
        for (std::uint32_t j = s.vertex_link_start[i]; j < s.vertex_link_start[i + 1]; ++j)
            s.row_quads[j >> 2].other[j & 3] = static_cast<std::uint32_t>(i);
    for (std::size_t k = 0; k < s.link_ends.size(); ++k) {
        const auto [a, b] = s.link_ends[k];
        s.link_slot[k] = {fill[a]++, fill[b]++};
        s.row_quads[s.link_slot[k][0] >> 2].other[s.link_slot[k][0] & 3] = b;
        s.row_quads[s.link_slot[k][1] >> 2].other[s.link_slot[k][1] & 3] = a;
    }
    s.row_reach = 1;
    for (const auto& [a, b] : s.link_ends) s.row_reach = std::max<std::size_t>(s.row_reach, a > b ? a - b : b - a);
    s.row_vertices = n;
    ++s.rows_version;
}

/// Writes a coupling into row entry `slot`.
void setCoupling(PaperSheet& s, std::uint32_t slot, double iso, double along, const Vec3& d) {
    JacobiQuad& quad = s.row_quads[slot >> 2];
    const unsigned lane = slot & 3u;
    quad.iso[lane] = iso;
    quad.along[lane] = along;
    quad.dir_x[lane] = d.x();
    quad.dir_y[lane] = d.y();
    quad.dir_z[lane] = d.z();
}

/// Iterations per pass of jacobiSweeps over the rows (docs/benchmarks-history.md: the
/// measurements that chose 1). Any depth gives the same bits.
constexpr int kPipelineDepth = 1;

/// One vertex of one weighted Jacobi iteration (Eq. 6): b_i - sum_j W_ij dv_j
/// (W_ij = -block, so + block dv_j) gathered over its row in registers, then W_ii^-1 and
/// the weight; a held vertex keeps its prescribed dv. The row's entries are summed in two
/// chains, even and odd entries (two lanes of one register: the sum's latency, not the
/// arithmetic, bounded a single chain), each in row order: with `kWide`, the terms of
/// four entries are computed at once (AVX) and added pair by pair, the same additions in
/// the same order, so both kernels give the same bits.
template <bool kWide>
__attribute__((always_inline)) inline void jacobiVertex(const PaperSheet& s, std::size_t i, const JacobiEntry* dv, JacobiEntry* next) {
    if (s.fixed[i]) {
        next[i] = dv[i];
        return;
    }
    const JacobiQuad* const quads = s.row_quads.data();
    const Vec3& b = s.rhs[i];
    Lanes sum_x = {b.x(), 0.0}, sum_y = {b.y(), 0.0}, sum_z = {b.z(), 0.0};
    std::uint32_t j = s.vertex_link_start[i];
    const std::uint32_t end = s.vertex_link_start[i + 1];
    auto pair = [&](std::uint32_t at) {  // entries at, at + 1 (at even)
        const JacobiQuad& c = quads[at >> 2];
        const unsigned lane = at & 3u;
        const double* o0 = dv[c.other[lane]].v;
        const double* o1 = dv[c.other[lane + 1]].v;
        const Lanes ox = {o0[0], o1[0]}, oy = {o0[1], o1[1]}, oz = {o0[2], o1[2]};
        const Lanes dx = load2(c.dir_x, lane), dy = load2(c.dir_y, lane), dz = load2(c.dir_z, lane);
        const Lanes along = load2(c.along, lane) * (dx * ox + dy * oy + dz * oz);
        const Lanes iso = load2(c.iso, lane);
        sum_x += iso * ox + along * dx;
        sum_y += iso * oy + along * dy;
        sum_z += iso * oz + along * dz;
    };
    if constexpr (kWide) {
        if ((j & 3u) != 0 && j < end) {  // the row starts in the middle of a block
            pair(j);
            j += 2;
        }
        for (; j + 4 <= end; j += 4) {
            const JacobiQuad& c = quads[j >> 2];
            // The four neighbours' entries, one load each, transposed into x, y and z lanes.
            Lanes4 r0, r1, r2, r3;
            std::memcpy(&r0, dv[c.other[0]].v, sizeof r0);
            std::memcpy(&r1, dv[c.other[1]].v, sizeof r1);
            std::memcpy(&r2, dv[c.other[2]].v, sizeof r2);
            std::memcpy(&r3, dv[c.other[3]].v, sizeof r3);
            const Lanes4 t0 = __builtin_shuffle(r0, r1, LaneIndex4{0, 4, 2, 6});  // x0 x1 z0 z1
            const Lanes4 t1 = __builtin_shuffle(r0, r1, LaneIndex4{1, 5, 3, 7});  // y0 y1 0 0
            const Lanes4 t2 = __builtin_shuffle(r2, r3, LaneIndex4{0, 4, 2, 6});  // x2 x3 z2 z3
            const Lanes4 t3 = __builtin_shuffle(r2, r3, LaneIndex4{1, 5, 3, 7});  // y2 y3 0 0
            const Lanes4 ox = __builtin_shuffle(t0, t2, LaneIndex4{0, 1, 4, 5});
            const Lanes4 oy = __builtin_shuffle(t1, t3, LaneIndex4{0, 1, 4, 5});
            const Lanes4 oz = __builtin_shuffle(t0, t2, LaneIndex4{2, 3, 6, 7});
            Lanes4 dx, dy, dz, along, iso;
            std::memcpy(&dx, c.dir_x, sizeof dx);
            std::memcpy(&dy, c.dir_y, sizeof dy);
            std::memcpy(&dz, c.dir_z, sizeof dz);
            std::memcpy(&along, c.along, sizeof along);
            std::memcpy(&iso, c.iso, sizeof iso);
            along *= dx * ox + dy * oy + dz * oz;
            const Lanes4 tx = iso * ox + along * dx, ty = iso * oy + along * dy, tz = iso * oz + along * dz;
            sum_x += Lanes{tx[0], tx[1]};
            sum_y += Lanes{ty[0], ty[1]};
            sum_z += Lanes{tz[0], tz[1]};
            sum_x += Lanes{tx[2], tx[3]};
            sum_y += Lanes{ty[2], ty[3]};
            sum_z += Lanes{tz[2], tz[3]};
        }
    }
    for (; j < end; j += 2) pair(j);
    const Vec3 even(sum_x[0], sum_y[0], sum_z[0]), odd(sum_x[1], sum_y[1], sum_z[1]);
    next[i] = JacobiEntry(Vec3((1.0 - kJacobiWeight) * dv[i].vec() + kJacobiWeight * (s.diag_inv[i] * (even + odd))));
}

/// Up to kPipelineDepth iterations, first + 1 ..., in one pass over the rows (jacobiSweeps).
template <bool kWide>
__attribute__((always_inline)) inline void jacobiPassBody(PaperSheet& s, int first, int depth) {
    const std::size_t n = s.vertices();
    JacobiEntry* buffer[2] = {s.dv.data(), s.dv_next.data()};
    const std::size_t lag = std::max<std::size_t>(s.row_reach, 1);
    const std::size_t steps = n + static_cast<std::size_t>(depth - 1) * lag;
    for (std::size_t t = 0; t < steps; ++t)
        for (int k = 0; k < depth; ++k) {  // iteration first + k + 1, at vertex t - k lag
            const std::size_t behind = static_cast<std::size_t>(k) * lag;
            if (t < behind) break;
            const std::size_t i = t - behind;
            if (i >= n) continue;
            const int it = first + k;  // reads iterate it, writes it + 1
            jacobiVertex<kWide>(s, i, buffer[it & 1], buffer[(it + 1) & 1]);
        }
}

void jacobiPass(PaperSheet& s, int first, int depth) { jacobiPassBody<false>(s, first, depth); }

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
/// The same pass compiled for AVX2 (the build targets plain x86-64: chosen at run time).
__attribute__((target("avx2"))) void jacobiPassAvx2(PaperSheet& s, int first, int depth) { jacobiPassBody<true>(s, first, depth); }
bool haveAvx2() {
    static const bool have = __builtin_cpu_supports("avx2");
    return have;
}
#else
void jacobiPassAvx2(PaperSheet& s, int first, int depth) { jacobiPassBody<true>(s, first, depth); }
bool haveAvx2() { return false; }
#endif

/// Eq. 6, weighted, jacobi_iterations times: iteration k reads iterate k - 1 (s.dv /
/// s.dv_next, alternately) and writes iterate k.
///
/// Pipelined (temporal blocking): a vertex's row reaches at most `reach` = s.row_reach
/// indices away, so iteration k can run at vertex i as soon as iteration k - 1 has passed
/// i + reach. Up to kPipelineDepth iterations run in one pass over the rows, each `reach`
/// vertices behind the one before, in the order of increasing k at every position: the
/// rows a vertex needs are read again while they are still in the cache (the rows in
/// flight are a small part of a large sheet's). Two buffers suffice:
/// when iteration k overwrites iterate k - 2 at vertex i, iteration k - 1 has passed
/// i + reach and needs no vertex <= i any more. The arithmetic is that of plain sweeps,
/// in the same order: the same bits.
void jacobiSweeps(PaperSheet& s) {
    for (int done = 0; done < s.desc.jacobi_iterations; done += kPipelineDepth) {
        const int depth = std::min(kPipelineDepth, s.desc.jacobi_iterations - done);
        if (haveAvx2())
            jacobiPassAvx2(s, done, depth);
        else
            jacobiPass(s, done, depth);
    }
    if (s.desc.jacobi_iterations & 1) s.dv.swap(s.dv_next);  // the last iterate into s.dv
}

}  // namespace

/// y = W x on the free rows (y_i = 0 on a held row), with W_ij = -(iso I + along d d^T)
/// from the row entries (a pad couples with zero) and W_ii from s.diag.
void applySystem(const PaperSheet& s, const std::vector<Vec3>& x, std::vector<Vec3>& y) {
    const std::size_t n = s.vertices();
    const std::uint32_t* const start = s.vertex_link_start.data();
    const JacobiQuad* const quads = s.row_quads.data();
    for (std::size_t i = 0; i < n; ++i) {
        if (s.fixed[i]) {
            y[i].setZero();
            continue;
        }
        Vec3 sum = s.diag[i] * x[i];
        for (std::uint32_t j = start[i]; j < start[i + 1]; ++j) {
            const JacobiQuad& c = quads[j >> 2];
            const unsigned lane = j & 3u;
            const Vec3 d(c.dir_x[lane], c.dir_y[lane], c.dir_z[lane]);
            const Vec3& o = x[c.other[lane]];
            sum -= c.iso[lane] * o + (c.along[lane] * d.dot(o)) * d;
        }
        y[i] = sum;
    }
}

namespace {

/// A sheet none of whose vertices is held: a spring adds B at (a, a) and (b, b) and -B at
/// (a, b) and (b, a), so its blocks cancel column by column and the rows of W dv sum to
/// sum_i (m_i I + A_i) dv_i (A_i the bodies' lent mass). The residual's sum,
/// sum_i (rhs_i - (W dv)_i) = h F_external - sum_i (m_i I + A_i) dv_i, is the momentum the
/// sweeps left out (they stop where they stop, and a force on one vertex reaches only the
/// vertices the sweeps reach). The uniform c = (sum_i m_i I + A_i)^-1 (that sum), added to
/// every dv, removes it: springs do not resist a translation, W (dv + c) = W dv + (M + A) c.
/// It is the Galerkin correction on the three translations (the coarsest level of a
/// multigrid), so it also lowers the error's W-norm. A held vertex takes an impulse from
/// its holder that the sheet does not see: then there is no momentum to keep, and no
/// correction.
void keepMomentum(PaperSheet& s) {
    const std::size_t n = s.vertices();
    for (std::size_t i = 0; i < n; ++i)
        if (s.fixed[i]) return;
    Mat3 mass = Mat3::Zero();
    Vec3 left = Vec3::Zero();
    for (std::size_t i = 0; i < n; ++i) {
        const Mat3 m = s.mass[i] * Mat3::Identity() + s.added_mass[i];
        mass += m;
        left += s.rhs[i] - m * s.dv[i].vec();
    }
    const Vec3 c = mass.inverse() * left;
    if (!c.allFinite()) return;  // a non-finite solve: the finite check after the step freezes the sheet
    for (std::size_t i = 0; i < n; ++i) s.dv[i] = JacobiEntry(Vec3(s.dv[i].vec() + c));
}

/// A solve that met a non-finite number: the free rows' dv are NaN (the caller's finite
/// check freezes the sheet), the warm start is dropped.
void poisonSolve(PaperSheet& s) {
    const double nan = std::numeric_limits<double>::quiet_NaN();
    for (std::size_t i = 0; i < s.vertices(); ++i) {
        if (!s.fixed[i]) s.dv[i] = JacobiEntry(Vec3(nan, nan, nan));
        s.cg_warm[i].setZero();
    }
    s.cg_iterations = 0;
    s.cg_residual = nan;
}

/// z = M^-1 r (s.cg_z from s.cg_r; zero on the held rows): the block-Jacobi preconditioner
/// W_ii^-1 (s.diag_inv), or for PaperSolver::Multigrid one V-cycle (multigrid.cpp). Both
/// are symmetric positive definite, as conjugate gradients need.
void precondition(PaperSheet& s) {
    if (s.desc.solver == PaperSolver::Multigrid) return multigridPrecondition(s, s.cg_r, s.cg_z);
    for (std::size_t i = 0; i < s.vertices(); ++i) s.cg_z[i] = s.fixed[i] ? Vec3::Zero() : Vec3(s.diag_inv[i] * s.cg_r[i]);
}

/// W dv = rhs by preconditioned conjugate gradients (precondition), the held rows' dv
/// prescribed (already in s.dv).
///
/// W is symmetric positive definite as built: every live spring adds
/// [B -B; -B B] (x) with B = h c d d^T + h^2 k (t (I - d d^T) + (1 - t) d d^T) = iso I + along d d^T,
/// t = max(0, 1 - l0/l) in [0, 1), so iso >= 0 and along >= 0: B is symmetric positive
/// semi-definite and so is the spring's 6x6 block (B (x) [1 -1; -1 1], a Kronecker product
/// of two PSD matrices). The mass M (and the movable bodies' lent mass, a symmetric PSD
/// n n^T m or glue mass) makes the sum positive definite. The geometric term dropped for
/// compressed springs (the comment at the top) is what keeps B from going indefinite.
///
/// Held rows are Dirichlet conditions: with the free unknowns u and the held values g, the
/// free rows read W_uu u = rhs_u - W_ug g, and W_uu is a principal submatrix of an SPD
/// matrix, SPD too. The iteration keeps the held entries of its search directions zero, so
/// W p on the free rows is W_uu p_u (applySystem), and starts from the last step's dv (a
/// sheet in steady motion changes its velocity by about the same each step).
/// Stops when |r| <= tolerance |rhs_u - W_ug g| (Euclidean norms of momenta, kg m/s),
/// or after 3 n iterations (exact arithmetic ends within the 3 n unknowns).
void conjugateGradient(PaperSheet& s) {
    const std::size_t n = s.vertices();
    s.cg_r.resize(n);
    s.cg_z.resize(n);
    s.cg_p.resize(n);
    s.cg_q.resize(n);
    s.cg_warm.resize(n, Vec3::Zero());
    // |b|: the free rows' right-hand side with the held values moved over (x = held, 0).
    for (std::size_t i = 0; i < n; ++i) s.cg_p[i] = s.fixed[i] ? s.dv[i].vec() : Vec3::Zero();
    applySystem(s, s.cg_p, s.cg_q);
    double b_norm2 = 0.0;
    for (std::size_t i = 0; i < n; ++i)
        if (!s.fixed[i]) b_norm2 += (s.rhs[i] - s.cg_q[i]).squaredNorm();
    // x0: the held values and the warm start.
    for (std::size_t i = 0; i < n; ++i) s.cg_p[i] = s.fixed[i] ? s.dv[i].vec() : s.cg_warm[i];
    applySystem(s, s.cg_p, s.cg_q);
    for (std::size_t i = 0; i < n; ++i) {
        s.dv[i] = JacobiEntry(s.cg_p[i]);
        s.cg_r[i] = s.fixed[i] ? Vec3::Zero() : Vec3(s.rhs[i] - s.cg_q[i]);
    }
    const double stop2 = s.desc.tolerance * s.desc.tolerance * b_norm2;
    double r2 = 0.0;
    for (std::size_t i = 0; i < n; ++i) r2 += s.cg_r[i].squaredNorm();
    // A right-hand side or residual that is not finite (a force past 1e154 squares to inf)
    // has no answer to a tolerance, and the stop test would be false on it and keep the
    // start: the free rows' dv go non-finite instead, so that the sheet is frozen by the
    // finite check after the step, as the Jacobi sweeps' overflow freezes it.
    if (!std::isfinite(b_norm2) || !std::isfinite(r2)) return poisonSolve(s);
    precondition(s);
    double rz = 0.0;
    for (std::size_t i = 0; i < n; ++i) {
        s.cg_p[i] = s.cg_z[i];
        rz += s.cg_r[i].dot(s.cg_z[i]);
    }
    int it = 0;
    const int cap = static_cast<int>(std::min<std::size_t>(3 * n, 1u << 30));
    while (r2 > stop2 && it < cap) {
        applySystem(s, s.cg_p, s.cg_q);
        double pq = 0.0;
        for (std::size_t i = 0; i < n; ++i) pq += s.cg_p[i].dot(s.cg_q[i]);
        if (!std::isfinite(pq)) return poisonSolve(s);
        if (!(pq > 0.0)) break;  // p = 0 (converged to rounding) or lost positivity to rounding
        const double alpha = rz / pq;
        r2 = 0.0;
        for (std::size_t i = 0; i < n; ++i) {
            s.dv[i] = JacobiEntry(Vec3(s.dv[i].vec() + alpha * s.cg_p[i]));
            s.cg_r[i] -= alpha * s.cg_q[i];
            r2 += s.cg_r[i].squaredNorm();
        }
        ++it;
        if (!std::isfinite(r2)) return poisonSolve(s);
        if (r2 <= stop2) break;
        precondition(s);
        double rz_next = 0.0;
        for (std::size_t i = 0; i < n; ++i) rz_next += s.cg_r[i].dot(s.cg_z[i]);
        const double beta = rz_next / rz;
        rz = rz_next;
        for (std::size_t i = 0; i < n; ++i) s.cg_p[i] = s.cg_z[i] + beta * s.cg_p[i];
    }
    s.cg_iterations = it;
    s.cg_residual = b_norm2 > 0.0 ? std::sqrt(r2 / b_norm2) : 0.0;
    for (std::size_t i = 0; i < n; ++i) s.cg_warm[i] = s.fixed[i] ? Vec3::Zero() : s.dv[i].vec();
}

}  // namespace

void solveVelocities(PaperSheet& s, const RigidTable& rigids, const PaperStep& ctx) {
    const std::size_t n = s.vertices();
    const double h = ctx.h, h2 = h * h;
    const double damping = s.desc.damping;
    const bool implicit = s.desc.integrator == PaperIntegrator::Implicit;
    const bool cg = implicit && (s.desc.solver == PaperSolver::ConjugateGradient || s.desc.solver == PaperSolver::Multigrid);
    if (cg) s.diag.resize(n);
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
    //
    // In chunks of kLengthChunk live springs: first their lengths and inverse lengths, in
    // short loops (a root and a division, ~35 cycles of latency, overlap across springs
    // only in a loop this short), then the rest. The roots and the divisions two springs at
    // a time, in lanes (one sqrtpd, one divpd; the same bits as norm() and 1.0 / l).
    s.link_length.resize(s.springs.size());
    constexpr std::size_t kLengthChunk = 32;
    std::uint32_t chunk_spring[kLengthChunk];
    double chunk_length[kLengthChunk], chunk_inverse[kLengthChunk];
    std::size_t k = 0;
    for (std::size_t next = 0; next < s.springs.size();) {
        std::size_t count = 0;
        for (; next < s.springs.size() && count < kLengthChunk; ++next) {
            const PaperSpring& sp = s.springs[next];
            if (sp.broken) continue;
            chunk_spring[count] = static_cast<std::uint32_t>(next);
            chunk_length[count++] = (s.x[sp.b] - s.x[sp.a]).squaredNorm();
        }
        std::size_t pair = 0;
        for (; pair + 1 < count; pair += 2) {
            const Lanes2 l = sqrtLanes(loadLanes(chunk_length + pair));
            storeLanes(chunk_length + pair, l);
            storeLanes(chunk_inverse + pair, 1.0 / l);  // one division per spring, not four (unused where l is 0)
        }
        if (pair < count) {
            chunk_length[pair] = std::sqrt(chunk_length[pair]);
            chunk_inverse[pair] = 1.0 / chunk_length[pair];
        }
        for (std::size_t c = 0; c < count; ++c) {
            const std::uint32_t spring = chunk_spring[c];
            const PaperSpring& sp = s.springs[spring];
            const auto [slot_a, slot_b] = s.link_slot[k++];
            const Vec3 e = s.x[sp.b] - s.x[sp.a];
            const double l = chunk_length[c];
            s.link_length[spring] = l;
            if (!(l > 1e-12)) {  // no direction: no force, no coupling
                setCoupling(s, slot_a, 0.0, 0.0, Vec3::Zero());
                setCoupling(s, slot_b, 0.0, 0.0, Vec3::Zero());
                s.row_force[slot_a].setZero();
                s.row_force[slot_b].setZero();
                continue;
            }
            const double inv_l = chunk_inverse[c];
            const Vec3 d = e * inv_l;
            const Vec3 relative = s.v[sp.b] - s.v[sp.a];
            // springForce: elastic and damping force on a.
            Vec3 f = h * (sp.stiffness * (l - sp.rest) + damping * sp.stiffness * d.dot(relative)) * d;
            // K = k (d d^T + t (I - d d^T)), t = max(0, 1 - l0 / l): the block
            // h c d d^T + h^2 K = iso I + along d d^T needs two numbers and d, not nine.
            // max(0, 1 - l0 / l) without a branch (springs swing between stretched and
            // compressed at random): x + |x| is 2x or 0 exactly.
            const double stretch = 1.0 - sp.rest * inv_l;
            const double t = 0.5 * (stretch + std::abs(stretch));
            const double iso = h2 * sp.stiffness * t;
            const double axial = h2 * sp.stiffness * (1.0 - t);
            const double along = h * damping * sp.stiffness + axial;
            // h^2 J v: row a gets -h^2 K (v_a - v_b) = h^2 K (v_b - v_a); row b the opposite.
            if (implicit) f += iso * relative + (axial * d.dot(relative)) * d;
            setCoupling(s, slot_a, iso, along, d);
            setCoupling(s, slot_b, iso, along, d);
            s.row_force[slot_a] = f;
            s.row_force[slot_b] = -f;
        }
    }

    // Pass 2, per vertex: rhs = h f + h^2 J v (gravity, the user's force, the bodies'
    // lent weight, the springs) and W_ii = M + sum of the blocks.
    const std::uint32_t* const start = s.vertex_link_start.data();
    const JacobiQuad* const quads = s.row_quads.data();
    for (std::size_t i = 0; i < n; ++i) {
        // Pins and glue to immovable bodies prescribe the velocity; a glue to a movable
        // body was turned into added mass (coupleBodies).
        s.fixed[i] = s.hold[i].kind == ParticleHold::Kind::Pin ||
                     (s.hold[i].kind == ParticleHold::Kind::Glue && !rigids.movable(s.hold[i].body));
        Vec3 rhs = h * (s.mass[i] * ctx.gravity + s.force[i] + s.added_force[i]);
        // The symmetric sum of the blocks in scalars (kept in registers; an Eigen 3x3
        // accumulator is spilled to the stack and reloaded in every pass of the loop).
        double iso = 0.0, xx = 0.0, yy = 0.0, zz = 0.0, xy = 0.0, xz = 0.0, yz = 0.0;
        for (std::uint32_t j = start[i]; j < start[i + 1]; ++j) {  // a pad adds zeros
            rhs += s.row_force[j];
            const JacobiQuad& c = quads[j >> 2];
            const unsigned lane = j & 3u;
            const Vec3 dir(c.dir_x[lane], c.dir_y[lane], c.dir_z[lane]);
            const Vec3 u = c.along[lane] * dir;
            iso += c.iso[lane];
            xx += u.x() * dir.x();
            yy += u.y() * dir.y();
            zz += u.z() * dir.z();
            xy += u.x() * dir.y();
            xz += u.x() * dir.z();
            yz += u.y() * dir.z();
        }
        s.rhs[i] = rhs;
        Mat3 diag;  // W_ii, inverted below
        diag << xx + iso, xy, xz, xy, yy + iso, yz, xz, yz, zz + iso;
        if (!implicit) diag.setZero();
        s.diag_inv[i] = diag + s.mass[i] * Mat3::Identity() + s.added_mass[i];
        if (cg) s.diag[i] = s.diag_inv[i];
    }
    if (!implicit) {
        // Semi-implicit (symplectic) Euler: v += h f / m. Stable only for h < 2 / omega.
        for (std::size_t i = 0; i < n; ++i)
            s.v[i] = s.fixed[i] ? heldVelocity(s, i, rigids, ctx) : Vec3(s.v[i] + s.diag_inv[i].inverse() * s.rhs[i]);
    } else {
        for (std::size_t i = 0; i < n; ++i) {
            if (s.fixed[i]) {
                s.dv[i] = JacobiEntry(heldVelocity(s, i, rigids, ctx) - s.v[i]);
                continue;
            }
            s.diag_inv[i] = s.diag_inv[i].inverse().eval();
            s.dv[i] = JacobiEntry(s.diag_inv[i] * s.rhs[i]);  // Eq. 6, k = 0
        }
        if (cg) {
            if (s.desc.solver == PaperSolver::Multigrid) multigridSetup(s);
            conjugateGradient(s);
        }
        else {
            jacobiSweeps(s);  // Eq. 6, weighted, jacobi_iterations times
            keepMomentum(s);
        }
        for (std::size_t i = 0; i < n; ++i) s.v[i] += s.dv[i].vec();
    }
    for (std::size_t i = 0; i < n; ++i) {
        // A norm past 1e154 overflows: the scaled norm then, or the clamp would zero it.
        const double speed = s.v[i].norm();
        if (speed > ctx.max_speed) s.v[i] *= ctx.max_speed / (std::isfinite(speed) ? speed : s.v[i].stableNorm());
        s.x_pred[i] = s.x[i] + h * s.v[i];
    }
}

}  // namespace tearables::detail
