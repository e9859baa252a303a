// Closest points of two segments (Ericson, Real-Time Collision Detection, Sec. 5.1.9).
//
// Derivation. Write the segments as P(s) = p0 + s d1 and Q(t) = q0 + t d2 with
// d1 = p1 - p0, d2 = q1 - q0, s, t in [0, 1], and let r = p0 - q0. The squared distance
//
//     F(s, t) = |P(s) - Q(t)|^2 = |r + s d1 - t d2|^2
//             = a s^2 - 2 b s t + e t^2 + 2 c s - 2 f t + r.r,
//
// with a = d1.d1, b = d1.d2, e = d2.d2, c = d1.r, f = d2.r, is a convex quadratic
// (its Hessian [[a, -b], [-b, e]] has determinant a e - b^2 = |d1 x d2|^2 >= 0).
// Setting its gradient to zero gives the closest points of the two infinite lines:
//
//     a s - b t = -c,   b s - e t = -f   =>   s = (b f - c e) / (a e - b^2),
//                                             t = (a f - b c) / (a e - b^2).
//
// For fixed s the best t is the projection of P(s) on the second line,
// t(s) = (P(s) - q0).d2 / e = (b s + f) / e, clamped to [0, 1]; for fixed t the best s is
// s(t) = (Q(t) - p0).d1 / a = (b t - c) / a, clamped. Ericson's argument: because F is
// convex, the minimiser over the square [0, 1]^2 lies either at the line minimiser (when
// it is inside), or on the edge of the square that the line minimiser is clamped to.
// So: clamp the line minimiser's s to [0, 1]; take t = t(s); if t is inside [0, 1] the
// pair is optimal (F restricted to that s-edge is minimised there, and the s-edge is the
// right one); if t had to be clamped to 0 or 1, the optimum lies on that t-edge, where
// the best s is s(t) clamped. The formulas need a > 0, e > 0 and a e - b^2 > 0:
//
//  * a (or e) ~ 0: that segment is a point; its parameter is 0 and the other one is the
//    clamped projection of the point on the other segment (both ~ 0: s = t = 0).
//  * a e - b^2 ~ 0: the segments are parallel and the line minimiser is a whole line of
//    pairs. Any s gives the same line distance as long as t(s) stays in [0, 1]; we take
//    the middle of the overlap of [0, 1] with the interval that the second segment
//    projects to on the first line (s of q0 is -c/a, s of q1 is (b - c)/a), or the nearer
//    end of [0, 1] when they do not overlap, then continue as above.
//
// Conditioning. Computed as written, a e - b^2 cancels catastrophically for nearly
// parallel segments (relative error eps / sin^2 of their angle). With Lagrange's identity
// (A x B).(C x D) = (A.C)(B.D) - (A.D)(B.C) both terms come from cross products instead:
//     a e - b^2 = |n|^2,   b f - c e = n.(d2 x r),   n = d1 x d2,
// which are accurate to eps / sin relative. An error ds in s moves the distance by at
// most sin * |ds| * |d1| along nearly parallel lines, so the distance stays accurate to a
// few eps * |d1| at every angle.
//
// Tolerances. A segment is a point when its squared length is below 1e-28 times the
// largest of a, e and |r|^2 (a length 1e-14 of the problem's scale; the error made by
// treating it as a point is that small). The segments are parallel when
// |n|^2 = a e sin^2(angle) <= 1e-24 a e, i.e. sin(angle) <= 1e-12; the midpoint rule is
// then off by at most sin * |d1| = 1e-12 of the length.
#include "collision/capsule.hpp"

#include <algorithm>

namespace tearables::detail {

namespace {

double clamp01(double x) { return x < 0.0 ? 0.0 : (x > 1.0 ? 1.0 : x); }

constexpr double kPointTolerance = 1e-28;     // squared relative length of a "point" segment
constexpr double kParallelTolerance = 1e-24;  // sin^2 of the angle of "parallel" segments

}  // namespace

SegmentClosest closestPointsOfSegments(const Vec3& p0, const Vec3& p1, const Vec3& q0, const Vec3& q1) {
    const Vec3 d1 = p1 - p0;
    const Vec3 d2 = q1 - q0;
    const Vec3 r = p0 - q0;
    const double a = d1.squaredNorm();
    const double e = d2.squaredNorm();
    const double f = d2.dot(r);
    const double scale2 = std::max({a, e, r.squaredNorm()});
    const bool point1 = a <= kPointTolerance * scale2;
    const bool point2 = e <= kPointTolerance * scale2;

    double s = 0.0;
    double t = 0.0;
    if (point1 && point2) {
        // Two points (or everything coincides): s = t = 0.
    } else if (point1) {
        // The first segment is the point p0: project it on the second segment.
        t = clamp01(f / e);
    } else {
        const double c = d1.dot(r);
        if (point2) {
            // The second segment is the point q0: project it on the first segment.
            s = clamp01(-c / a);
        } else {
            const double b = d1.dot(d2);
            const Vec3 n = d1.cross(d2);
            const double denom = n.squaredNorm();  // = a e - b^2, without cancellation
            if (denom > kParallelTolerance * a * e) {
                s = clamp01(n.dot(d2.cross(r)) / denom);  // (b f - c e) / (a e - b^2)
            } else {
                // Parallel: the middle of the overlap of the projections (see above).
                const double sq0 = -c / a;
                const double sq1 = (b - c) / a;
                const double lo = std::max(0.0, std::min(sq0, sq1));
                const double hi = std::min(1.0, std::max(sq0, sq1));
                // No overlap: either hi < 0 (the second segment projects entirely before
                // p0) or lo > 1 (entirely after p1); take the nearer end.
                s = lo <= hi ? 0.5 * (lo + hi) : (hi < 0.0 ? 0.0 : 1.0);
            }
            // Best t for this s; if it must be clamped, redo s for the clamped t.
            t = (b * s + f) / e;
            if (t < 0.0) {
                t = 0.0;
                s = clamp01(-c / a);
            } else if (t > 1.0) {
                t = 1.0;
                s = clamp01((b - c) / a);
            }
        }
    }

    SegmentClosest out;
    out.s = s;
    out.t = t;
    out.p = p0 + s * d1;
    out.q = q0 + t * d2;
    out.distance = (out.p - out.q).norm();
    return out;
}

}  // namespace tearables::detail
