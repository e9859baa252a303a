// Chain shape matching, CSM (Strings Sec. 3; Rungjiratananon, Kanamori, Nishita 2010).
//
// On a piece [first, last], region k holds the particles max(first, k-w) .. min(last, k+w);
// particle i lies in N_i of them. As in lattice shape matching (Rivers & James, FastLSM
// 2007), which CSM simplifies, i has the per-region mass m~_i = m_i / N_i in each of its
// regions, in the fit and in the blend, so the goals conserve the piece's momentum exactly,
// sum_i m_i g_i = sum_i m_i x_i (the full m_i would not, at the piece's ends). A heavier
// particle (a colliding one, 3x, Sec. 6) pulls its regions towards itself and moves less.
// Fit of region k: c = sum m~ x / M, c0 = sum m~ x0 / M,
//     A = sum m~ (x - c)(x0 - c0)^T = sum m~ x x0^T - M c c0^T,
// R = rotational part of A (csmRotation), goals g_ik = R (x0_i - c0) + c, blended as
//     g_i = (1/N_i) sum_{k containing i} g_ik.
// The sums cost O(1) a region without cancellation (sliding windows: PieceLayout); a
// straight rest shape has a cheaper kernel (straightChainShapeMatchingGoals).
#include "string/shape_matching.hpp"

#include "base/lanes.hpp"
#include "base/thread_pool.hpp"

#include <Eigen/SVD>

#include <algorithm>
#include <cmath>
#include <limits>

namespace tearables::detail {

namespace {

/// sigma_2 / sigma_1 at or below which a region's A counts as rank 1 (collinear region).
/// Round-off in A (assembled about the region's centre) is ~1e-15 sigma_1, so below this
/// the rotation about the line would be picked by round-off.
constexpr double kRankOneTolerance = 1e-12;

/// The 16 sums of CsmMoments as one flat array: m, mx, mx0, mxx0 (column-major), added
/// element by element (Eigen's 3- and 9-element objects here missed store forwarding).
struct FlatMoments {
    alignas(16) double v[16] = {};
};
constexpr int kMx = 1, kMx0 = 4, kMxx0 = 7;  // offsets in FlatMoments::v

/// Adds moments b about the same reference to a.
inline void add(FlatMoments& a, const FlatMoments& b) {
    for (int j = 0; j < 16; ++j) a.v[j] += b.v[j];
}

/// Adds a particle of per-region mass m at (dx, dx0) relative to the moments' reference.
inline void addParticle(FlatMoments& s, double m, const Vec3& dx, const Vec3& dx0) {
    FlatMoments f;
    double* t = f.v;
    t[0] = m;
    for (int r = 0; r < 3; ++r) {
        t[kMx + r] = m * dx[r];
        t[kMx0 + r] = m * dx0[r];
    }
    for (int c = 0; c < 3; ++c)
        for (int r = 0; r < 3; ++r) t[kMxx0 + 3 * c + r] = t[kMx + r] * dx0[c];
    add(s, f);
}

inline void store(const FlatMoments& f, CsmMoments& s) {
    s.m = f.v[0];
    for (int r = 0; r < 3; ++r) {
        s.mx[r] = f.v[kMx + r];
        s.mx0[r] = f.v[kMx0 + r];
    }
    for (int j = 0; j < 9; ++j) s.mxx0.data()[j] = f.v[kMxx0 + j];
}

inline FlatMoments flat(const CsmMoments& s) {
    FlatMoments f;
    f.v[0] = s.m;
    for (int r = 0; r < 3; ++r) {
        f.v[kMx + r] = s.mx[r];
        f.v[kMx0 + r] = s.mx0[r];
    }
    for (int j = 0; j < 9; ++j) f.v[kMxx0 + j] = s.mxx0.data()[j];
    return f;
}

// The rotation of a region (csmRotation): R maximising tr(R^T A). With A = U S V^T,
// R = U diag(1, 1, det(U V^T)) V^T. When A has rank <= 1 (sigma_2 <= 1e-12 sigma_1: the
// region collinear now or at rest) the rotation about the line is undetermined; we take the
// smallest rotation taking v_1 to u_1, so a curved rest shape pulled straight keeps its
// plane. A = 0 or non-finite A gives identity.
//
// Three stateless paths, equal to the SVD's R to rounding times the condition number
// sigma_1 / (sigma_2 + signed sigma_3) (tested against JacobiSVD). With cof A = det(A) A^-T
// and q = |cof A|_F / |A|_F^2, q / sqrt(3) <= sigma_2 / sigma_1 <= 3 q (A is first scaled
// by a power of two so that |A|_F^2 is in [1e-100, 1e100]):
//   - q <= 1e-12 / 6, surely rank 1: v_1 and u_1 by power steps (RankOneBatch).
//   - q >= 1e-7: Higham's scaled Newton iteration for the polar factor,
//     X <- (z X + X^-T / z) / 2, z = (|X^-1|_F / |X|_F)^(1/2), from B = A + cof(A) / s,
//     s ~ sigma_1. As cof A = U diag(s2 s3, s1 s3, s1 s2) V^T (s3 signed), B has A's
//     singular vectors and all signed values positive (planar A too; reflected A once s is
//     refined towards sigma_1), so it converges to R in 4-6 steps; for reflected A the
//     result is checked to be the maximiser (newtonRotation).
//   - otherwise, or when the iteration fails: JacobiSVD.

/// q = |cof A|_F / |A|_F^2 at or above which the Newton iteration is used (see above).
constexpr double kNewtonMinQ = 1e-7;

/// cof A = det(A) A^-T, defined for every A (columns a_1 x a_2, a_2 x a_0, a_0 x a_1).
inline Mat3 cofactor(const Mat3& a) {
    Mat3 c;
    c.col(0) = a.col(1).cross(a.col(2));
    c.col(1) = a.col(2).cross(a.col(0));
    c.col(2) = a.col(0).cross(a.col(1));
    return c;
}

/// |cof A|_F^2 in scalars (the fast path needs only this; cofactor()'s Mat3 here missed
/// store forwarding).
inline double cofactorSquaredNorm(const Mat3& a) {
    double sum = 0.0;
    for (int j = 0; j < 3; ++j) {
        const int j1 = j == 2 ? 0 : j + 1, j2 = j == 0 ? 2 : j - 1;  // column j = a_j1 x a_j2
        const double cx = a(1, j1) * a(2, j2) - a(2, j1) * a(1, j2);
        const double cy = a(2, j1) * a(0, j2) - a(0, j1) * a(2, j2);
        const double cz = a(0, j1) * a(1, j2) - a(1, j1) * a(0, j2);
        sum += cx * cx + cy * cy + cz * cz;
    }
    return sum;
}

/// The reference: R from a 3x3 JacobiSVD (unconditionally convergent and accurate).
EIGEN_DONT_INLINE Mat3 svdRotation(const Mat3& a) {
    const Eigen::JacobiSVD<Mat3, Eigen::NoQRPreconditioner> svd(a, Eigen::ComputeFullU | Eigen::ComputeFullV);
    const Vec3& sigma = svd.singularValues();
    if (!(sigma(0) > 0.0)) return Mat3::Identity();
    if (sigma(1) <= kRankOneTolerance * sigma(0)) {
        // Rank 1: A ~ sigma_1 u_1 v_1^T. The smallest rotation taking v_1 to u_1 (sign
        // pairs of u_1, v_1 are consistent, so the pair is well defined).
        return Quat::FromTwoVectors(svd.matrixV().col(0), svd.matrixU().col(0)).normalized().toRotationMatrix();
    }
    Mat3 u = svd.matrixU();
    const Mat3& v = svd.matrixV();
    if (u.determinant() * v.determinant() < 0.0) u.col(2) = -u.col(2);
    return u * v.transpose();
}

/// The smallest rotation taking p to q when they are (nearly) opposite: the axis is
/// ill-defined, and Eigen's FromTwoVectors picks one. Out of line: rare.
EIGEN_DONT_INLINE void halfTurnRotation(const Vec3& p, const Vec3& q, Mat3& r) {
    r = Quat::FromTwoVectors(p, q).normalized().toRotationMatrix();
}

/// Rotations of rank-1 A (|A|_F^2 = n2 in [1e-100, 1e100]), kLanes at a time: the
/// smallest rotation taking v_1 to u_1.
///
/// From A's longest column a_j = sigma_1 u_1 v_1j (|v_1j| >= 1/sqrt(3)), p = A^T a_j / n2
/// lies along v_1 and q = A p along u_1, with consistent signs and an error of
/// (sigma_2/sigma_1)^2. R comes from the unnormalised quaternion (w, k), k = p x q,
/// w = |p||q| + p.q, computed as |k|^2 / (|p||q| + |p.q|) + (p.q + |p.q|) so that an obtuse
/// angle does not cancel; near a half turn (1 + cos < 1e-6) halfTurnRotation. Structure of
/// arrays, so the lane loops vectorise with the bits of one region at a time. A queued
/// rotation is written when the batch fills or at solve(); A is copied in.
class RankOneBatch {
public:
    void add(const Mat3& a, double n2, Mat3& r) {
        for (int e = 0; e < 9; ++e) a_[e][count_] = a.data()[e];
        // The longest column is picked here, one region at a time: a selection in the lane
        // loops would become a branch and stop them vectorising.
        const double n0 = a.col(0).squaredNorm(), n1 = a.col(1).squaredNorm(), nn2 = a.col(2).squaredNorm();
        const int j = n0 >= n1 ? (n0 >= nn2 ? 0 : 2) : (n1 >= nn2 ? 1 : 2);
        for (int i = 0; i < 3; ++i) u_[i][count_] = a(i, j);
        inv_n2_[count_] = 1.0 / n2;
        out_[count_] = &r;
        if (++count_ == kLanes) solve();
    }

    void solve() {
        if (count_ == 0) return;
        for (int l = count_; l < kLanes; ++l) {  // idle lanes repeat lane 0
            for (int e = 0; e < 9; ++e) a_[e][l] = a_[e][0];
            for (int i = 0; i < 3; ++i) u_[i][l] = u_[i][0];
            inv_n2_[l] = inv_n2_[0];
        }
        powerSteps();
        for (int l = 0; l < kLanes; ++l) s_[l] = std::sqrt(s_[l]);  // apart: sqrt with errno does not vectorise
        rotations();
        for (int l = 0; l < count_; ++l) {
            if (w_[l] > 1e-6 * s_[l]) {
                for (int e = 0; e < 9; ++e) out_[l]->data()[e] = r_[e][l];
            } else {
                halfTurnRotation(Vec3(p_[0][l], p_[1][l], p_[2][l]), Vec3(q_[0][l], q_[1][l], q_[2][l]), *out_[l]);
            }
        }
        count_ = 0;
    }

private:
    static constexpr int kLanes = 8;

    /// p, q, k = p x q, |k|^2, |p|^2 |q|^2 (in s_) and p.q of every lane.
    void powerSteps() {
        for (int l = 0; l < kLanes; ++l) {
            double col[3][3];  // col[c][i] = a(i, c)
            for (int e = 0; e < 9; ++e) col[e / 3][e % 3] = a_[e][l];
            auto dot = [](const double* u, const double* v) { return u[0] * v[0] + u[1] * v[1] + u[2] * v[2]; };
            const double u[3] = {u_[0][l], u_[1][l], u_[2][l]};
            double p[3], q[3];
            for (int c = 0; c < 3; ++c) p[c] = dot(col[c], u) * inv_n2_[l];  // along v_1
            for (int i = 0; i < 3; ++i) q[i] = col[0][i] * p[0] + col[1][i] * p[1] + col[2][i] * p[2];  // along u_1
            const double k[3] = {p[1] * q[2] - p[2] * q[1], p[2] * q[0] - p[0] * q[2], p[0] * q[1] - p[1] * q[0]};
            for (int i = 0; i < 3; ++i) {
                p_[i][l] = p[i];
                q_[i][l] = q[i];
                k_[i][l] = k[i];
            }
            kk_[l] = dot(k, k);
            s_[l] = dot(p, p) * dot(q, q);
            pq_[l] = dot(p, q);
        }
    }

    /// w and R = I + (2 / (w^2 + |k|^2)) (w [k]x + [k]x^2) (orthogonal to rounding for any
    /// (w, k)) of every lane, s_ = |p||q|.
    void rotations() {
        for (int l = 0; l < kLanes; ++l) {
            const double kx = k_[0][l], ky = k_[1][l], kz = k_[2][l], kk = kk_[l], s = s_[l], pq = pq_[l];
            // w = (|p||q| - |p.q|) + (p.q + |p.q|), the first part as |k|^2 / (|p||q| + |p.q|).
            const double w = kk / (s + std::fabs(pq)) + (pq + std::fabs(pq));
            const double g = 2.0 / (w * w + kk);
            const double c = 1.0 - g * kk, sw = g * w;
            const double gx = g * kx, gy = g * ky, gz = g * kz;
            w_[l] = w;
            // Column-major.
            r_[0][l] = c + gx * kx, r_[3][l] = gx * ky - sw * kz, r_[6][l] = gx * kz + sw * ky;
            r_[1][l] = gy * kx + sw * kz, r_[4][l] = c + gy * ky, r_[7][l] = gy * kz - sw * kx;
            r_[2][l] = gz * kx - sw * ky, r_[5][l] = gz * ky + sw * kx, r_[8][l] = c + gz * kz;
        }
    }

    int count_ = 0;
    Mat3* out_[kLanes];
    alignas(16) double a_[9][kLanes];  // A column-major
    alignas(16) double inv_n2_[kLanes];
    alignas(16) double u_[3][kLanes];  // A's longest column
    alignas(16) double p_[3][kLanes], q_[3][kLanes], k_[3][kLanes];
    alignas(16) double kk_[kLanes], s_[kLanes], pq_[kLanes], w_[kLanes];
    alignas(16) double r_[9][kLanes];
};

/// One step of the scaled Newton iteration X <- (zeta X + X^-T / zeta) / 2 on x (3x3,
/// column-major), in scalars. False when det X <= 0; else delta2 = |X_next - X|_F^2.
inline bool newtonStep(double (&x)[9], double& delta2) {
    auto cross = [](const double* u, const double* v, double* out) {
        out[0] = u[1] * v[2] - u[2] * v[1];
        out[1] = u[2] * v[0] - u[0] * v[2];
        out[2] = u[0] * v[1] - u[1] * v[0];
    };
    double cx[9];  // cof X = det X X^-T
    cross(x + 3, x + 6, cx);
    cross(x + 6, x, cx + 3);
    cross(x, x + 3, cx + 6);
    const double d = x[0] * cx[0] + x[1] * cx[1] + x[2] * cx[2];
    if (!(d > 0.0)) return false;
    double xx = 0.0, cc = 0.0;
    for (int e = 0; e < 9; ++e) {
        xx += x[e] * x[e];
        cc += cx[e] * cx[e];
    }
    const double zeta = std::sqrt(std::sqrt(cc / xx) / d);
    const double half_zeta = 0.5 * zeta, half_inv = 0.5 / (zeta * d);
    delta2 = 0.0;
    for (int e = 0; e < 9; ++e) {
        const double next = half_zeta * x[e] + half_inv * cx[e];
        delta2 += (next - x[e]) * (next - x[e]);
        x[e] = next;
    }
    return true;
}

/// Scaled Newton iteration for R (see the header comment); a with |a|_F^2 in [1e-100,
/// 1e100], n2 = |a|_F^2, c2 = |cof a|_F^2. False when it does not converge or,
/// for reflected a, when the result is not the maximiser of tr(R^T a): the caller then
/// takes the SVD.
EIGEN_DONT_INLINE bool newtonRotation(const Mat3& a, double n2, double c2, Mat3& r) {
    const Mat3 c = cofactor(a);
    const double det = a.col(0).dot(c.col(0));
    // s ~ sigma_1: |A|_F >= sigma_1 (all that B needs when det A >= 0). For det A < 0, B's
    // smallest values are sigma_2 - sigma_3 sigma_1/s and sigma_2 sigma_1/s - sigma_3, so s
    // must not exceed sigma_1 by more than sigma_2/sigma_3: Newton on the characteristic
    // polynomial of A^T A, p(l) = l^3 - |A|^2 l^2 + |cof A|^2 l - det^2, from l = |A|_F^2
    // (above the largest root, where p is convex) decreases monotonically to sigma_1^2.
    double s1sq = n2;
    if (det < 0.0) {
        for (int it = 0; it < 8; ++it) {
            const double p = ((s1sq - n2) * s1sq + c2) * s1sq - det * det;
            const double dp = (3.0 * s1sq - 2.0 * n2) * s1sq + c2;
            const double step = p / dp;
            s1sq -= step;
            if (!(step > 1e-6 * s1sq)) break;
        }
    }
    const Mat3 b = a + c / std::sqrt(s1sq);
    double x[9];
    std::copy(b.data(), b.data() + 9, x);
    for (int k = 0; k < 12; ++k) {
        double delta2;
        if (!newtonStep(x, delta2)) return false;
        // Quadratic convergence: |X_k - R| ~ |X_k+1 - X_k| = delta, |X_k+1 - R| ~ delta^2 / 2.
        if (delta2 > 1e-16) continue;
        if (det < 0.0) {
            // R maximises tr(R^T A) iff S = R^T A is symmetric and M = tr(S) I - S >= 0; M's
            // eigenvalues are the pair sums of S's, det M = (s1+s2)(s1+s3)(s2+s3). Another
            // stationary rotation makes one pair sum negative.
            const Mat3 sm = Eigen::Map<const Mat3>(x).transpose() * a;
            Mat3 m = -0.5 * (sm + sm.transpose());
            m.diagonal().array() += sm.trace();
            if (!(m.determinant() > 1e-12 * n2 * std::sqrt(n2))) return false;
        }
        r = Eigen::Map<const Mat3>(x);
        return true;
    }
    return false;
}

/// csmRotation into r of an A whose |A|_F^2 = n2 is in [1e-100, 1e100] (cof A, |A|^4 and
/// the Newton iteration's det^2 neither overflow nor underflow); a rank-1 A is queued on
/// `batch` (r written at its solve()).
inline void rotationInRange(const Mat3& a, double n2, Mat3& r, RankOneBatch& batch) {
    const double c2 = cofactorSquaredNorm(a);
    constexpr double kSurelyRankOne = kRankOneTolerance / 6.0;
    if (c2 <= kSurelyRankOne * kSurelyRankOne * n2 * n2) return batch.add(a, n2, r);
    if (c2 >= kNewtonMinQ * kNewtonMinQ * n2 * n2 && newtonRotation(a, n2, c2, r)) return;
    r = svdRotation(a);
}

/// A = 0, non-finite, or |A|_F^2 outside [1e-100, 1e100]: scaled by a power of two (exact)
/// so that its largest entry is in [1, 2).
EIGEN_DONT_INLINE void rotationOutOfRange(const Mat3& a_in, Mat3& r) {
    const double largest = a_in.cwiseAbs().maxCoeff();  // NaN compares false
    if (!a_in.allFinite() || !(largest > 0.0)) {
        r = Mat3::Identity();  // non-finite, or A = 0 (a single point)
        return;
    }
    const Mat3 a = std::ldexp(1.0, -std::ilogb(largest)) * a_in;
    RankOneBatch batch;
    rotationInRange(a, a.squaredNorm(), r, batch);
    batch.solve();
}

/// csmRotation into r, which may be a itself (every path reads all of a before it writes
/// r): pass 3 turns A_k into R_k in place. Rank 1: r is written at batch.solve().
inline void rotationInto(const Mat3& a, Mat3& r, RankOneBatch& batch) {
    const double n2 = a.squaredNorm();  // NaN or infinite for non-finite A
    if (n2 >= 1e-100 && n2 <= 1e100) return rotationInRange(a, n2, r, batch);
    rotationOutOfRange(a, r);
}

}  // namespace

Mat3 csmRotation(const Mat3& a) {
    Mat3 r;
    RankOneBatch batch;
    rotationInto(a, r, batch);
    batch.solve();
    return r;
}

namespace {

/// The regions, blocks and chunks of a piece of n particles at half-width w (both kernels).
/// Sliding windows (van Herk / Gil-Werman): blocks of B = 2w+1 particles keep prefix sums
/// about the block's first particle and suffix sums about the next block's first. A region
/// (at most B particles) is a suffix plus the next block's prefix, about the same particle,
/// so every sum is local and A = S - M c c0^T loses only a couple of digits (global prefix
/// sums cancel catastrophically: docs/notes-strings.md). Chunks of whole blocks go through
/// all passes while in cache; the regions and blocks a chunk shares with a neighbour are
/// computed again by the same operations, so the bits are those of one pass.
struct PieceLayout {
    struct Chunk {
        std::size_t p0, p1;  // its particles
        std::size_t r0, r1;  // the regions they need
        std::size_t b0, b1;  // the blocks those need
    };
    std::size_t n, hw, block, chunk, chunks;

    PieceLayout(std::size_t particles, int w)
        : n(particles),
          // A half-width beyond the piece gives the same regions as n-1 (whole piece).
          hw(std::min(static_cast<std::size_t>(w), particles - 1)),
          block(2 * hw + 1),
          chunk(std::max<std::size_t>(1, kCsmChunkParticles / block) * block),
          chunks((particles + chunk - 1) / chunk) {}
    std::size_t regionLo(std::size_t k) const { return k > hw ? k - hw : 0; }
    std::size_t regionHi(std::size_t k) const { return std::min(n - 1, k + hw); }
    /// Region k's particles lo..hi as block sums, all about particle `reference` (the
    /// first of hi's block): within one block, a region shorter than a block touches the
    /// piece's start (a prefix, up to hi) or its end (the last block's suffix, from lo), a
    /// full-size one is the whole block; across two blocks, a suffix of the first (from lo)
    /// plus a prefix of the second (up to hi).
    struct Region {
        std::size_t lo, hi, reference;
        bool prefix_only;  // the prefix up to hi alone
        bool two_blocks;   // the suffix from lo plus the prefix up to hi
    };
    Region region(std::size_t k) const {
        Region g;
        g.lo = regionLo(k);
        g.hi = regionHi(k);
        const std::size_t blo = g.lo - g.lo % block;  // first particle of lo's block
        g.reference = g.hi - g.hi % block;             // and of hi's
        g.prefix_only = blo == g.reference && g.lo == blo;
        g.two_blocks = blo != g.reference;
        return g;
    }
    Chunk at(std::size_t c) const {
        Chunk h;
        h.p0 = c * chunk;
        h.p1 = std::min(n, h.p0 + chunk);
        h.r0 = regionLo(h.p0);
        h.r1 = regionHi(h.p1 - 1) + 1;
        h.b0 = regionLo(h.r0) / block;
        h.b1 = regionHi(h.r1 - 1) / block + 1;
        return h;
    }
};

/// Checks both kernels' arguments, moves their arrays to the piece's first particle and
/// returns the piece's layout.
PieceLayout enterPiece(const Vec3*& x, const Vec3*& rest, const double*& mass, Vec3*& goal, std::size_t first,
                       std::size_t last, int w) {
    if (w < 1) throw InvalidInput("w", "region half-width must be >= 1");
    if (first > last) throw InvalidInput("first", "piece is empty (first > last)");
    x += first;
    rest += first;
    mass += first;
    goal += first;
    return PieceLayout(last - first + 1, w);
}

/// Calls body(chunk, work) for every chunk of the piece; chunks go to the pool in
/// contiguous ranges (a piece of kParallelItems particles or more), each range with work
/// buffers of its own.
template <class Body>
void forChunks(const PieceLayout& layout, CsmScratch& scratch, ThreadPool* pool, Body&& body) {
    const std::size_t min_count = layout.n >= kParallelItems ? 0 : std::numeric_limits<std::size_t>::max();
    if (scratch.work.size() < kMaxRanges) scratch.work.resize(kMaxRanges);
    forRanges(pool, layout.chunks, min_count, [&](std::size_t c0, std::size_t c1, std::size_t part) {
        for (std::size_t c = c0; c < c1; ++c) body(layout.at(c), scratch.work[part]);
    });
}

}  // namespace

void chainShapeMatchingGoals(const Vec3* x, const Vec3* rest, const double* mass, std::size_t first,
                             std::size_t last, int w, Vec3* goal, CsmScratch& scratch, ThreadPool* pool) {
    const PieceLayout layout = enterPiece(x, rest, mass, goal, first, last, w);
    const std::size_t n = layout.n;
    const std::size_t block = layout.block;

    if (scratch.rotation.size() < n) scratch.rotation.resize(n);
    if (scratch.centroid.size() < n) scratch.centroid.resize(n);
    if (scratch.rest_centroid.size() < n) scratch.rest_centroid.resize(n);

    // One chunk: the regions straight into the scratch's (no copy).
    const bool whole = layout.chunks == 1;
    forChunks(layout, scratch, pool, [&](const PieceLayout::Chunk& h, CsmScratch::Work& work) {
        const std::size_t first_particle = h.b0 * block;
        const std::size_t particles = std::min(n, h.b1 * block) - first_particle;
        if (work.prefix.size() < particles) work.prefix.resize(particles);
        if (work.suffix.size() < particles) work.suffix.resize(particles);
        if (!whole && work.rotation.size() < h.r1 - h.r0) {
            work.rotation.resize(h.r1 - h.r0);
            work.centroid.resize(h.r1 - h.r0);
            work.rest_centroid.resize(h.r1 - h.r0);
        }
        // By particle and region number within the piece.
        const auto prefix = [&work, first_particle](std::size_t i) -> CsmMoments& { return work.prefix[i - first_particle]; };
        const auto suffix = [&work, first_particle](std::size_t i) -> CsmMoments& { return work.suffix[i - first_particle]; };
        Mat3* const rot_base = whole ? scratch.rotation.data() : work.rotation.data();
        Vec3* const centroid_base = whole ? scratch.centroid.data() : work.centroid.data();
        Vec3* const rest_centroid_base = whole ? scratch.rest_centroid.data() : work.rest_centroid.data();
        const std::size_t r0 = h.r0;
        const auto rot = [rot_base, r0](std::size_t k) -> Mat3& { return rot_base[k - r0]; };
        const auto centroid = [centroid_base, r0](std::size_t k) -> Vec3& { return centroid_base[k - r0]; };
        const auto rest_centroid = [rest_centroid_base, r0](std::size_t k) -> Vec3& { return rest_centroid_base[k - r0]; };

        // Pass 1: per block, prefix moments about the block's first particle and suffix
        // moments about the next block's (the last block's about its own), mass m_i / N_i.
        for (std::size_t b = h.b0; b < h.b1; ++b) {
            const std::size_t s = b * block;
            const std::size_t e = std::min(s + block, n) - 1;
            FlatMoments run;
            for (std::size_t i = s; i <= e; ++i) {
                const double m = mass[i] / static_cast<double>(layout.regionHi(i) - layout.regionLo(i) + 1);
                addParticle(run, m, x[i] - x[s], rest[i] - rest[s]);
                store(run, prefix(i));
            }
            const std::size_t q = s + block < n ? s + block : s;  // the suffixes' reference
            run = FlatMoments();
            for (std::size_t i = e + 1; i-- > s;) {
                const double m = mass[i] / static_cast<double>(layout.regionHi(i) - layout.regionLo(i) + 1);
                addParticle(run, m, x[i] - x[q], rest[i] - rest[q]);
                store(run, suffix(i));
            }
        }

        // Pass 2: fit every region about its reference particle r (PieceLayout::Region);
        // A_k is kept in rot(k) for pass 3.
        for (std::size_t k = h.r0; k < h.r1; ++k) {
            const PieceLayout::Region g = layout.region(k);
            const std::size_t r = g.reference;
            FlatMoments f = flat(g.prefix_only ? prefix(g.hi) : suffix(g.lo));
            if (g.two_blocks) add(f, flat(prefix(g.hi)));
            const Vec3 dc = Vec3(f.v[kMx], f.v[kMx + 1], f.v[kMx + 2]) / f.v[0];     // c - x_r
            const Vec3 dc0 = Vec3(f.v[kMx0], f.v[kMx0 + 1], f.v[kMx0 + 2]) / f.v[0];  // c0 - x0_r
            Mat3 a;
            for (int col = 0; col < 3; ++col)
                for (int row = 0; row < 3; ++row) a(row, col) = f.v[kMxx0 + 3 * col + row] - f.v[kMx + row] * dc0[col];
            rot(k) = a;
            centroid(k) = x[r] + dc;
            rest_centroid(k) = rest[r] + dc0;
        }

        // Pass 3: R_k from A_k, in place, in a pass of its own (A_k reloaded straight after
        // its computation missed store forwarding).
        RankOneBatch batch;
        for (std::size_t k = h.r0; k < h.r1; ++k) rotationInto(rot(k), rot(k), batch);
        batch.solve();

        // Pass 4: blend, g_i = x_i + mean over regions k containing i of (g_ik - x_i);
        // those are regionLo(i) .. regionHi(i).
        for (std::size_t i = h.p0; i < h.p1; ++i) {
            const std::size_t lo = layout.regionLo(i);
            const std::size_t hi = layout.regionHi(i);
            // In scalars: Eigen's 3-vector expressions here mixed packet and scalar work.
            const double px = x[i].x(), py = x[i].y(), pz = x[i].z();
            const double qx = rest[i].x(), qy = rest[i].y(), qz = rest[i].z();
            double ax = 0.0, ay = 0.0, az = 0.0;
            for (std::size_t k = lo; k <= hi; ++k) {
                const double* rk = rot(k).data();  // column-major
                const Vec3& ck = centroid(k);
                const Vec3& c0k = rest_centroid(k);
                const double dx = qx - c0k.x(), dy = qy - c0k.y(), dz = qz - c0k.z();
                ax += (rk[0] * dx + rk[3] * dy + rk[6] * dz) + (ck.x() - px);
                ay += (rk[1] * dx + rk[4] * dy + rk[7] * dz) + (ck.y() - py);
                az += (rk[2] * dx + rk[5] * dy + rk[8] * dz) + (ck.z() - pz);
            }
            const double count = static_cast<double>(hi - lo + 1);
            goal[i] = Vec3(px + ax / count, py + ay / count, pz + az / count);
        }
        // The chunk's own regions into the scratch (what it reports after the call).
        if (!whole) {
            for (std::size_t k = h.p0; k < h.p1; ++k) {
                scratch.rotation[k] = rot(k);
                scratch.centroid[k] = centroid(k);
                scratch.rest_centroid[k] = rest_centroid(k);
            }
        }
    });
}

namespace {

/// The 8 sums of a run of particles for a straight rest shape along v, about a reference
/// pair (p, p0), with s = (x0 - p0) . v: m, m (x - p), m s, m (x - p) s.
struct LineMoments {
    alignas(16) double v[8] = {};
};
constexpr int kLineMx = 1, kLineMs = 4, kLineMxs = 5;  // offsets in LineMoments::v
/// The most particles of a block, 2 w + 1 at the largest half-width w = 8 (validate).
constexpr std::size_t kMaxBlock = 17;

inline void add(LineMoments& a, const LineMoments& b) {
    for (int j = 0; j < 8; ++j) a.v[j] += b.v[j];
}

inline void addParticle(LineMoments& sums, double m, const Vec3& dx, double ds) {
    LineMoments f;
    f.v[0] = m;
    for (int r = 0; r < 3; ++r) f.v[kLineMx + r] = m * dx[r];
    f.v[kLineMs] = m * ds;
    for (int r = 0; r < 3; ++r) f.v[kLineMxs + r] = f.v[kLineMx + r] * ds;
    add(sums, f);
}

/// a / |a|, or `fallback` where a is zero or not finite (csmRotation's identity for A = 0
/// or a non-finite A). Scaled by its largest entry first, so that a tiny a keeps its
/// direction (as csmRotation's power-of-two scaling does).
Vec3 unitOr(const Vec3& a, const Vec3& fallback) {
    const double n2 = a.squaredNorm();  // NaN or infinite for a non-finite a
    if (n2 >= 1e-200 && n2 <= 1e200) return a * (1.0 / std::sqrt(n2));
    const double largest = a.cwiseAbs().maxCoeff();  // NaN compares false
    if (!a.allFinite() || !(largest > 0.0)) return fallback;
    const Vec3 b = a / largest;
    return b / b.norm();
}

}  // namespace

// Straight rest shape (StringDesc::straight): every region has rank 1, A = a v^T, and only
// R v = a / |a| enters the goals, c + ((x0_i - c0) . v) a / |a|: 8 moment sums instead of
// 16, no rotation. The same goals as the general kernel to rounding (tested).
void straightChainShapeMatchingGoals(const Vec3* x, const Vec3* rest, const double* mass, std::size_t first,
                                     std::size_t last, int w, const Vec3& direction, Vec3* goal, CsmScratch& scratch,
                                     ThreadPool* pool) {
    if (w > static_cast<int>((kMaxBlock - 1) / 2)) throw InvalidInput("w", "region half-width must be <= 8");
    const PieceLayout layout = enterPiece(x, rest, mass, goal, first, last, w);
    const std::size_t n = layout.n;
    const std::size_t block = layout.block;
    const Vec3 v = direction;
    // N_i, the regions particle i belongs to (= the particles of region i).
    const auto count = [&layout](std::size_t i) { return static_cast<double>(layout.regionHi(i) - layout.regionLo(i) + 1); };
    forChunks(layout, scratch, pool, [&](const PieceLayout::Chunk& h, CsmScratch::Work& work) {
        const std::size_t first_particle = h.b0 * block;
        const std::size_t particles = std::min(n, h.b1 * block) - first_particle;
        if (work.line_prefix.size() < 8 * particles) work.line_prefix.resize(8 * particles);
        if (work.line_suffix.size() < 8 * particles) work.line_suffix.resize(8 * particles);
        if (work.direction.size() < h.r1 - h.r0) {
            work.direction.resize(h.r1 - h.r0);
            work.centroid.resize(h.r1 - h.r0);
            work.rest_centroid.resize(h.r1 - h.r0);
        }
        const auto prefix = [&work, first_particle](std::size_t i) { return work.line_prefix.data() + 8 * (i - first_particle); };
        const auto suffix = [&work, first_particle](std::size_t i) { return work.line_suffix.data() + 8 * (i - first_particle); };
        const std::size_t r0 = h.r0;
        const auto centroid = [&work, r0](std::size_t k) -> Vec3& { return work.centroid[k - r0]; };
        const auto rest_centroid = [&work, r0](std::size_t k) -> Vec3& { return work.rest_centroid[k - r0]; };
        const auto along = [&work, r0](std::size_t k) -> Vec3& { return work.direction[k - r0]; };

        // Pass 1: as chainShapeMatchingGoals' pass 1, rest offsets along v; the eight
        // running sums are four lane pairs with addParticle's products (the same bits).
        for (std::size_t b = h.b0; b < h.b1; ++b) {
            const std::size_t s = b * block;
            const std::size_t e = std::min(s + block, n) - 1;
            double weight[kMaxBlock];
            for (std::size_t i = s; i <= e; ++i) weight[i - s] = mass[i] / count(i);
            const auto add = [&](std::size_t i, std::size_t ref, Lanes2 (&run)[4], double* out) {
                const double m = weight[i - s];
                const Vec3 dx = x[i] - x[ref];
                const double ds = (rest[i] - rest[ref]).dot(v);
                const Lanes2 mx = Lanes2{m, m * dx.x()}, myz = Lanes2{m * dx.y(), m * dx.z()};
                run[0] += mx;
                run[1] += myz;
                run[2] += Lanes2{m * ds, mx[1] * ds};
                run[3] += myz * ds;
                for (int k = 0; k < 4; ++k) storeLanes(out + 2 * k, run[k]);
            };
            Lanes2 run[4] = {};
            for (std::size_t i = s; i <= e; ++i) add(i, s, run, prefix(i));
            const std::size_t q = s + block < n ? s + block : s;
            Lanes2 back[4] = {};
            for (std::size_t i = e + 1; i-- > s;) add(i, q, back, suffix(i));
        }

        // Pass 2: every region's centroids and the direction R v = a / |a| its rotation
        // takes v to, with a = sum m (x - c) s about the region's reference particle r.
        for (std::size_t k = h.r0; k < h.r1; ++k) {
            const PieceLayout::Region g = layout.region(k);
            const std::size_t r = g.reference;
            // The sums straight from the buffers into registers (not through a local copy).
            const double* one = g.prefix_only ? prefix(g.hi) : suffix(g.lo);
            const double* other = g.two_blocks ? prefix(g.hi) : nullptr;
            LineMoments f;
            for (int j = 0; j < 8; ++j) f.v[j] = other ? one[j] + other[j] : one[j];
            const Vec3 dc = Vec3(f.v[kLineMx], f.v[kLineMx + 1], f.v[kLineMx + 2]) / f.v[0];  // c - x_r
            const double ds = f.v[kLineMs] / f.v[0];                                         // (c0 - x0_r) . v
            const Vec3 a(f.v[kLineMxs] - f.v[kLineMx] * ds, f.v[kLineMxs + 1] - f.v[kLineMx + 1] * ds,
                         f.v[kLineMxs + 2] - f.v[kLineMx + 2] * ds);
            along(k) = unitOr(a, v);
            centroid(k) = x[r] + dc;
            rest_centroid(k) = rest[r] + ds * v;
        }

        // Pass 3: blend, g_i = x_i + mean over i's regions k of (c_k + ((x0_i - c0_k) . v)
        // R_k v - x_i).
        for (std::size_t i = h.p0; i < h.p1; ++i) {
            const std::size_t lo = layout.regionLo(i);
            const std::size_t hi = layout.regionHi(i);
            const double px = x[i].x(), py = x[i].y(), pz = x[i].z();
            double ax = 0.0, ay = 0.0, az = 0.0;
            for (std::size_t k = lo; k <= hi; ++k) {
                const Vec3& ck = centroid(k);
                const Vec3& uk = along(k);
                const double d = (rest[i] - rest_centroid(k)).dot(v);
                ax += d * uk.x() + (ck.x() - px);
                ay += d * uk.y() + (ck.y() - py);
                az += d * uk.z() + (ck.z() - pz);
            }
            const double n_i = count(i);
            goal[i] = Vec3(px + ax / n_i, py + ay / n_i, pz + az / n_i);
        }
    });
}

}  // namespace tearables::detail

// The stage: CSM on every piece of a string (Strings Sec. 3).
#include "string/string_state.hpp"

namespace tearables::detail {

namespace {

/// The shift of the free particles of piece [first, last] that gives back the momentum
/// the colliding particles' weight (csm_mass above their mass) takes from the goals:
/// alpha sum (m~ - m)(g - x) / sum m over the free particles (zero without a colliding one).
/// Only for a piece whose momentum is its own and its movable bodies' (free and glued to
/// movable bodies): a pin or a static body takes what the goals leave, as in the paper.
Vec3 collidingMomentum(const StringState& s, std::size_t first, std::size_t last, double alpha) {
    Vec3 lost = Vec3::Zero();
    double free_mass = 0.0;
    bool any = false;
    for (std::size_t q = first; q <= last; ++q) {
        // glue_movable is the last strain limit's (empty before a string's first).
        const bool movable = q < s.glue_movable.size() && s.glue_movable[q];
        if (s.hold[q].kind == ParticleHold::Kind::Pin || (s.hold[q].kind == ParticleHold::Kind::Glue && !movable))
            return Vec3::Zero();
        if (s.hold[q].kind != ParticleHold::Kind::Free) continue;
        free_mass += s.mass[q];
        if (!s.colliding[q]) continue;
        lost += (s.csm_mass[q] - s.mass[q]) * (s.scratch.csm_goal[q] - s.x[q]);
        any = true;
    }
    return any && free_mass > 0.0 ? Vec3(alpha * lost / free_mass) : Vec3::Zero();
}

}  // namespace

void updateRestShape(StringState& s) {
    // The rest shape has the lengths the material currently allows, L_max = L_rest
    // (1 + sigma/E), along the directions the string was created with: shape matching,
    // which fits rigid motions, then leaves the stretch to the material and only bends.
    Vec3 point = s.desc.points[0];
    s.rest_shape[0] = point;
    for (std::size_t j = 0; j < s.segments(); ++j) {
        point = point + s.rest_direction[j] * s.max_length[j];
        s.rest_shape[j + 1] = point;
    }
}

// Deviation from the paper's order (prediction, then CSM): we match the shape at the start
// of the step, after the last strain limiting, and add the goal displacement to the
// prediction. CSM conserves momentum, so on the prediction it would carry part of every
// external load and the momentum-balance tension would read low; here it sees bending only.
/// Rest directions within this of each other (per coordinate) make a straight rest shape:
/// a rest point then lies off the line by at most this times its distance along it, and
/// the goals differ from those of chainShapeMatchingGoals by as little.
constexpr double kStraightRest = 1e-12;

void shapeMatch(StringState& s, ThreadPool* pool) {
    const std::size_t n = s.particles();
    if (n < 3 || s.desc.bending <= 0.0) {  // nothing to bend
        std::fill(s.scratch.csm_goal.begin(), s.scratch.csm_goal.end(), Vec3::Zero());
        return;
    }
    updateRestShape(s);
    const double alpha = s.desc.bending;
    // Long strings run on the pool, each item writing its own entries: the same bits on any
    // thread count. Held particles weigh as if immovable (a clamp holds the string's
    // direction, a cantilever); particles that hit a string last step weigh 3x (Sec. 6).
    const double heaviest = forRangesMax(pool, n, kParallelItems, [&](std::size_t p0, std::size_t p1) {
        double most = 0.0;
        for (std::size_t p = p0; p < p1; ++p) most = std::max(most, s.mass[p]);
        return most;
    });
    forRanges(pool, n, kParallelItems, [&](std::size_t p0, std::size_t p1, std::size_t) {
        for (std::size_t p = p0; p < p1; ++p) {
            s.csm_mass[p] = s.hold[p].kind == ParticleHold::Kind::Free ? s.mass[p] * (s.colliding[p] ? 3.0 : 1.0) : 1e6 * heaviest;
            s.scratch.csm_goal[p] = Vec3::Zero();  // where no piece is matched
        }
    });
    std::size_t first = 0;
    for (std::size_t p = 0; p < n; ++p) {
        const bool piece_ends = p + 1 == n || s.broken[p];
        if (!piece_ends) continue;
        if (p > first + 1) {
            // A piece created straight stays straight (plasticity only lengthens segments).
            const Vec3& along = s.rest_direction[first];
            const bool straight = !forRangesAny(pool, p - first - 1, kParallelItems, [&](std::size_t k0, std::size_t k1) {
                for (std::size_t j = first + 1 + k0; j < first + 1 + k1; ++j)
                    if (!((s.rest_direction[j] - along).cwiseAbs().maxCoeff() <= kStraightRest)) return true;  // curved
                return false;
            });
            if (straight)
                straightChainShapeMatchingGoals(s.x.data(), s.rest_shape.data(), s.csm_mass.data(), first, p,
                                                s.desc.csm_half_width, along, s.scratch.csm_goal.data(),
                                                s.scratch.csm_scratch, pool);
            else
                chainShapeMatchingGoals(s.x.data(), s.rest_shape.data(), s.csm_mass.data(), first, p, s.desc.csm_half_width,
                                        s.scratch.csm_goal.data(), s.scratch.csm_scratch, pool);
            // Particles move all the way to their goals (the paper's full step); held
            // particles stay at their hold and only anchor their regions. The goals keep
            // the piece's momentum (sum m~ g = sum m~ x), so what the free particles gain
            // a held one gives: a glued particle's share, m~ alpha (g - x) (kg m), is its
            // body's to take (prepareStrainLimit), not lost to the clamp.
            // A colliding particle weighs 3 m in the goals but moves with its mass m, so
            // the goals' balance leaves the free particles a momentum of
            // -alpha sum (m~ - m)(g - x) over the colliding ones; it is given back as one
            // shift of every free particle of the piece, `restore` (a velocity change of
            // the piece as a whole: its shape's correction stays the goals').
            const Vec3 restore = collidingMomentum(s, first, p, alpha);
            forRanges(pool, p - first + 1, kParallelItems, [&](std::size_t k0, std::size_t k1, std::size_t) {
                for (std::size_t q = first + k0; q < first + k1; ++q) {
                    const Vec3 toward = alpha * (s.scratch.csm_goal[q] - s.x[q]);
                    switch (s.hold[q].kind) {
                        case ParticleHold::Kind::Free: s.scratch.csm_goal[q] = toward + restore; break;
                        case ParticleHold::Kind::Glue: s.scratch.csm_goal[q] = s.csm_mass[q] * toward; break;
                        case ParticleHold::Kind::Pin: s.scratch.csm_goal[q] = Vec3::Zero(); break;
                    }
                }
            });
        }
        first = p + 1;
    }
}

}  // namespace tearables::detail
