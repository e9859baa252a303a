// Chain shape matching (Strings, Sec. 3; Rungjiratananon, Kanamori, Nishita 2010).
//
// Regions. On a piece [first, last] of N particles, region k holds the particles
// max(first, k-w) .. min(last, k+w); particle i belongs to N_i = min(last, i+w) -
// max(first, i-w) + 1 regions (2w+1 inside the chain, fewer near the piece's ends).
//
// Per-region mass. The paper weighs "the goal position of each particle in the
// overlapping regions by particle per-region mass". We read this as in lattice shape
// matching (Rivers & James, FastLSM 2007), which CSM simplifies: a particle's mass is split
// equally among the regions that contain it, m~_i = m_i / N_i, and m~_i is the mass the
// particle has in each of its regions, both when a region is fitted (centroids and the
// moment matrix A) and when its goals are blended. Blending then is a plain average over
// the particle's regions,
//     g_i = sum_k m~_i g_ik / sum_k m~_i = (1/N_i) sum_{k containing i} g_ik,
// and, because every region conserves the momentum of its per-region masses, the goals
// conserve the linear momentum of the piece exactly: sum_i m_i g_i = sum_i m_i x_i
// (fitting with the full m_i instead would break this at the piece's ends, where N_i
// varies). A heavier particle (e.g. a colliding one, made 3x heavier by the caller, Sec.
// 6) pulls its regions' centroids and rotations towards itself and so moves less.
//
// Fit of region k (per-region masses): c = sum m~ x / M, c0 = sum m~ x0 / M,
//     A = sum m~ (x - c)(x0 - c0)^T = sum m~ x x0^T - M c c0^T,
// R = rotational part of A, goals g_ik = R (x0_i - c0) + c.
//
// O(1) per region. Global prefix sums of m, m x, m x0 and m x x0^T along the chain with
// A_k = S_k - M c c0^T would cancel catastrophically: their terms grow with the distance from the origin and with the
// chain's length, while A_k is of the order of the region's own (small) extent squared
// (a 746-particle rope of 1 cm segments would lose about 8 digits in A of a w = 2 region).
// We keep the O(1) cost without any subtraction (the van Herk / Gil-Werman sliding-window
// scheme): the piece is cut into blocks of B = 2w+1 particles; inside each block we keep
// prefix sums (block start .. i) about the block's first particle and suffix sums
// (i .. block end) about the next block's first particle (the last block's about its own
// first). A region has at most B particles, so it is a suffix of one block plus a prefix
// of the next, both about the same particle of the region, which simply add (or, at the
// piece's ends, a prefix or a suffix of one block, about its first particle); every
// quantity then has the size of a few regions, and A_k = S - M c c0^T (about a particle
// of the region) loses only a couple of digits. Goals are blended as
// x_i + mean_k [R_k (x0_i - c0_k) + (c_k - x_i)], again with local differences only.
//
// Rotation: the rotational part of each region's A (csmRotation; see the rotation helpers
// below for its derivation and the paths that compute it).
//
// Straight rest shapes (straightChainShapeMatchingGoals). A string created along one line
// (StringDesc::straight, the common rope) has every region of rank 1, A = a v^T with v the
// line's direction, and only R v = a / |a| enters its goals (the rest offsets lie along
// v): c + ((x0_i - c0) . v) a / |a|. So a second kernel keeps 8 moment sums instead of 16
// (m, m x, m s and m x s, s the rest offset along v) and fits a region with one square
// root and no rotation. Its goals are the rank-1 path's to rounding (tested against it);
// the stage takes it where a piece's rest directions agree to 1e-12. The structure
// (blocks, chunks, passes) is the same.
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

/// The 16 sums of CsmMoments as one flat array: m, mx, mx0, mxx0 (column-major). The
/// passes accumulate, store and add moments in this form, element by element over an even
/// count, which the compiler keeps in registers or moves in aligned pairs (on Eigen's 3-
/// and 9-element objects it mixes packet and scalar accesses to the same spilled values,
/// and a value stored one way and reloaded the other misses store forwarding).
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

// The rotation of a region. csmRotation returns the rotation R maximising tr(R^T A): with
// A = U S V^T (an SVD, S >= 0), R = U diag(1, 1, det(U V^T)) V^T (a reflection is fixed
// by flipping the singular vector of the smallest singular value). It handles planar regions
// (rank 2) and sign-indefinite A. When A has rank <= 1 (sigma_2 <= 1e-12 sigma_1: all
// particles of the region collinear, now or at rest: a straight chain being stretched or a
// straight rest shape), every rotation taking the rest direction v_1 to the current one u_1
// is optimal and the rotation about the line is undetermined; we then take the smallest
// such rotation (about v_1 x u_1), the one closest to identity, so a curved rest shape
// pulled straight keeps its plane instead of a spin picked by round-off. A straight rest
// shape makes every region rank 1; its goals only depend on R v_1 = u_1.
//
// How R is computed. A 3x3 JacobiSVD per region is costly and most regions are easy, so the
// SVD is kept only for the cases the two cheap paths below are not sure of. Both are
// stateless (no warm start: results do not depend on call order) and agree with the SVD's R
// to rounding times the problem's own condition number sigma_1 / (sigma_2 + det-signed
// sigma_3) (tested against JacobiSVD on random, reflected, planar, nearly planar and nearly
// rank-1 matrices). The cofactor matrix cof A = det(A) A^-T (columns a_1 x a_2, a_2 x a_0,
// a_0 x a_1) gives q = |cof A|_F / |A|_F^2, which brackets the rank test: q / sqrt(3) <=
// sigma_2 / sigma_1 <= 3 q. (A with |A|_F^2 outside [1e-100, 1e100] is first scaled by a
// power of two, so that |A|^4 cannot overflow.)
//   - q <= 1e-12 / 6 (surely rank 1; every region of a straight rest shape): v_1 and u_1
//     (up to their lengths) by power steps from A's longest column u, p = A^T u / |A|_F^2,
//     q = A p (the pair has consistent signs), and R = the smallest rotation taking p to q
//     as above, from the quaternion (|p||q| + p.q, p x q).
//   - q >= 1e-7 (sigma_2 / sigma_1 >= 5.7e-8): Higham's scaled Newton iteration for the
//     polar factor, X <- (z X + X^-T / z) / 2, z = (|X^-1|_F / |X|_F)^(1/2), X^-T =
//     cof X / det X, started from B = A + cof(A) / s with s ~ sigma_1. In the SVD with
//     rotations U, V and signed s_3 = det-sign sigma_3, cof A = U diag(s2 s3, s1 s3, s1 s2)
//     V^T, so B = U diag(s1 + s2 s3/s, s2 + s1 s3/s, s3 + s1 s2/s) V^T: the same singular
//     vectors, all signed values positive (also for planar A, where A^-T does not exist,
//     and for reflected A if s is close enough to sigma_1: there s is refined from |A|_F by
//     Newton on A^T A's characteristic cubic), so the iteration converges to exactly the
//     R above, in 4-6 steps (its smallest value is sigma_2 + s3 ~ the problem's
//     conditioning). q >= 1e-7 keeps B's cofactors and determinant accurate enough (det B
//     to about 1e-16 / q^2 relative: a percent; the iteration only needs its sign and
//     size). For reflected A the converged R is checked to be the maximiser (tr(S) I - S >=
//     0 with S = R^T A symmetric), since a determinant of the wrong sign there would
//     converge to another stationary rotation.
//   - Otherwise (1e-12/6 < q < 1e-7: nearly rank 1, where cofactors lose their digits or
//     the rank test is close, or a Newton iteration that does not converge in 12 steps or
//     fails its check), JacobiSVD.
// A = 0 or non-finite A gives identity. These paths are not bit for bit the SVD: R
// differs in the last bits.

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

/// |cof A|_F^2 = |cofactor(a)|_F^2, in scalars: the fast path needs only this, and the
/// Mat3 of cofactor(), spilled and reloaded in mixed widths, missed store forwarding.
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

/// Rotations of A of rank 1 (sigma_2 <= 5e-13 sigma_1), |A|_F^2 = n2 in [1e-100, 1e100],
/// queued and computed kLanes at a time: the smallest rotation taking v_1 to u_1.
///
/// The longest column a_j is sigma_1 u_1 v_1j with |v_1j| >= 1/sqrt(3); two power steps
/// after it, p = A^T a_j / n2 (along v_1, of length in [1/sqrt(3), 1]: dividing by n2
/// keeps every product below within range) and q = A p (along u_1, of length ~ sigma_1;
/// the pair has consistent signs), leave an error of (sigma_2/sigma_1)^2 in the
/// directions, below rounding. The rotation from p to q is the unnormalised quaternion
/// (w, k), k = p x q, w = |p||q| + p.q = |p||q| (1 + c): one square root (normalising p
/// and q first took two, and the divisions by their lengths). w is
/// computed as |k|^2 / (|p||q| + |p.q|) + (p.q + |p.q|), which for an obtuse angle avoids
/// the cancellation of |p||q| + p.q, without a branch (see add()). Near a half turn
/// (1 + c < 1e-6) halfTurnRotation.
///
/// Why a batch: the computation is some 130 scalar operations with no data-dependent
/// control flow but selections, and SSE2 code for one 3x3 matrix spends as many
/// instructions again on register moves and shuffles. Stored as structure of arrays, the
/// loops over the lanes below vectorise (two regions per instruction), with the same
/// operations, so the same bits, as one region at a time. A queued rotation is written when
/// the batch fills or at solve(); its A is copied in, so it may be written over A.
class RankOneBatch {
public:
    void add(const Mat3& a, double n2, Mat3& r) {
        for (int e = 0; e < 9; ++e) a_[e][count_] = a.data()[e];
        // The longest column is picked here, one region at a time: in the loops over the
        // lanes, the compiler makes branches of any selection ahead of arithmetic (it does
        // not if-convert arithmetic, which might raise a floating-point exception), and a
        // loop with branches does not vectorise.
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
/// column-major), in scalars (Eigen's 3x3 expressions under SSE2 spend most of their
/// instructions on shuffles, and divided cof X by zeta det X entry by entry). False when
/// det X <= 0; else delta2 = |X_next - X|_F^2.
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
/// r): the fit pass turns A_k in place into R_k, and the result is stored straight where it
/// belongs (a copy into place would reload it in other widths than it was stored in).
/// Rank 1: r is written at batch.solve().
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
/// The piece is done in chunks of whole blocks, each through all four passes while its
/// moments and regions are in cache (on a long piece, pass by pass, the passes streamed
/// ~0.9 kB a particle through memory, and the stage ran at the memory's speed on one
/// thread and on two). A chunk's particles need the regions up to hw beyond it, and those
/// the blocks next to it: both are computed again by the neighbouring chunk, from the same
/// particles by the same operations, so the bits are those of one pass over the whole piece.
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
        // moments about the next block's first particle (the last block's about its own),
        // with per-region masses m_i / N_i (N_i = number of regions containing i = size of
        // region i). A region spanning two blocks is a suffix of the first plus a prefix of
        // the second, both about the second's first particle: they add without a shift.
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

        // Pass 2: fit every region, with its moments about a particle r of the region (the
        // second block's first particle, or the one block's first: within a block of the
        // centre, so A = S - M c c0^T still loses only a couple of digits). A_k is kept in
        // rot(k) for pass 3.
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

        // Pass 3: R_k from A_k, in place, in a pass of its own: A_k, stored long before, is
        // reloaded from cache; handed over straight after its computation, its reload (in
        // other widths than Eigen stored it in) missed store forwarding.
        RankOneBatch batch;
        for (std::size_t k = h.r0; k < h.r1; ++k) rotationInto(rot(k), rot(k), batch);
        batch.solve();

        // Pass 4: blend, g_i = x_i + mean over regions k containing i of (g_ik - x_i).
        // Region k contains i iff |k - i| <= hw, so those regions are regionLo(i) ..
        // regionHi(i).
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

        // Pass 1: the blocks' prefix and suffix sums, as chainShapeMatchingGoals' pass 1,
        // with the rest offsets taken along v. A particle's per-region mass is found once
        // for both, and the eight running sums are four pairs of lanes stored straight
        // from registers: (m, m dx), (m dy, m dz), (m s, m dx s), (m dy s, m dz s), the
        // products and sums of addParticle, so the same bits (not through the stack).
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
            // The sums straight from the buffers into registers (a copy into a local array
            // would be reloaded in other widths than it was stored in).
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

// ---------------------------------------------------------------------------------------
// The stage: CSM on every piece of a string (Strings Sec. 3), after the prediction.
// ---------------------------------------------------------------------------------------
#include "string/string_state.hpp"

namespace tearables::detail {

void updateRestShape(StringState& s) {
    // The rest shape follows the lengths the material currently allows, L_max = L_rest
    // (1 + sigma/E) of the last step (L_rest grows with plasticity), along the directions
    // the string was created with. Shape matching fits rigid motions, so it resists
    // stretching as well as bending; with the loaded lengths in its rest shape it leaves
    // the stretch to the material and only bends.
    // The running point carried in registers (read back from rest_shape, each point's
    // stores reached the next one's loads through memory, on the sum's dependency chain).
    Vec3 point = s.desc.points[0];
    s.rest_shape[0] = point;
    for (std::size_t j = 0; j < s.segments(); ++j) {
        point = point + s.rest_direction[j] * s.max_length[j];
        s.rest_shape[j + 1] = point;
    }
}

// Deviation from the paper's order (prediction, then CSM): we match the shape the string
// has at the start of the step, after the last strain limiting, and add the goal
// displacement to the prediction. Shape matching conserves momentum and so spreads a
// force on one particle over its region; run on the prediction it would carry part of
// every external load itself, and the momentum-balance tension, which must carry all of
// it, would read low. Run on the constrained shape it sees bending only.
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
    // The passes over the particles below run on the pool for a long string (each item
    // writes its own entries; the maxima and the straightness test do not depend on the
    // cut): the same bits on any thread count.
    // Held particles do not move, so in the fits they weigh as if immovable: a clamp then
    // holds the direction of the string (a cantilever), instead of being rotated along.
    // Particles that collided with another string last step weigh three times their mass
    // (Strings Sec. 6), so that bending barely moves them back into the contact.
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
            // A piece created straight keeps a straight rest shape (plasticity only
            // lengthens its segments): the straight kernel, without polar factors. Its
            // directions are those of points laid out along one line, equal to rounding.
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
            // Particles move all the way to their goals (the paper's full step): the goal
            // displacement is kept for the prediction. Held particles stay where their hold
            // puts them and only anchor the regions they belong to.
            forRanges(pool, p - first + 1, kParallelItems, [&](std::size_t k0, std::size_t k1, std::size_t) {
                for (std::size_t q = first + k0; q < first + k1; ++q)
                    s.scratch.csm_goal[q] = s.hold[q].kind == ParticleHold::Kind::Free
                                                ? Vec3(alpha * (s.scratch.csm_goal[q] - s.x[q]))
                                                : Vec3::Zero();
            });
        }
        first = p + 1;
    }
}

}  // namespace tearables::detail
