// Closest points of two segments (Ericson, Real-Time Collision Detection, Sec. 5.1.9).
// With P(s) = p0 + s d1, Q(t) = q0 + t d2 (s, t in [0, 1]) and r = p0 - q0, the squared
// distance F(s, t) = a s^2 - 2 b s t + e t^2 + 2 c s - 2 f t + r.r (a = d1.d1, b = d1.d2,
// e = d2.d2, c = d1.r, f = d2.r) is convex; the lines' minimiser is
//     s = (b f - c e) / (a e - b^2),   t = (a f - b c) / (a e - b^2).
// Ericson: clamp s to [0, 1], take t(s) = (b s + f) / e; if t must be clamped, the optimum
// lies on that t-edge, where s(t) = (b t - c) / a, clamped. A segment of length ~0 is a
// point (its parameter 0, the other one the clamped projection); parallel segments take
// the middle of their projections' overlap.
//
// Conditioning: a e - b^2 cancels for nearly parallel segments (relative error eps /
// sin^2). By Lagrange's identity a e - b^2 = |n|^2 and b f - c e = n.(d2 x r) with
// n = d1 x d2, accurate to eps / sin; an error ds moves the distance by sin |ds| |d1|, so
// the distance stays accurate to a few eps |d1| at every angle.
#include "collision/capsule.hpp"

#include <algorithm>

namespace tearables::detail {

namespace {

double clamp01(double x) { return x < 0.0 ? 0.0 : (x > 1.0 ? 1.0 : x); }

// A point: squared length below 1e-28 of max(a, e, |r|^2) (a length 1e-14 of the scale, the
// error of treating it as a point). Parallel: |n|^2 = a e sin^2 <= 1e-24 a e, i.e. sin <=
// 1e-12, where the midpoint rule is off by at most 1e-12 of the length.
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
                // Parallel: any s whose t(s) stays in [0, 1] gives the line distance; take
                // the middle of the overlap of [0, 1] with the second segment's projection
                // on the first line (q0 at s = -c/a, q1 at (b - c)/a).
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
