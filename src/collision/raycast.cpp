// Ray tests against string capsules, so that a game can shoot or cut a rope: the first
// capsule a ray enters.
#include "tearables/queries.hpp"

#include <algorithm>
#include <cmath>

namespace tearables {

namespace {

/// Smallest root in [0, 1] of |o + t d - c|^2 = r^2 (a sphere), or -1.
double raySphere(const Vec3& o, const Vec3& d, const Vec3& c, double r) {
    const Vec3 m = o - c;
    const double a = d.squaredNorm();
    const double b = m.dot(d);
    const double cc = m.squaredNorm() - r * r;
    if (cc <= 0.0) return 0.0;  // starts inside
    const double disc = b * b - a * cc;
    if (disc < 0.0 || a <= 0.0) return -1.0;
    const double t = (-b - std::sqrt(disc)) / a;
    return (t >= 0.0 && t <= 1.0) ? t : -1.0;
}

}  // namespace

// A capsule is the union of a finite cylinder and two end spheres: the first entry is the
// smallest of the cylinder's entry (within the axis bounds) and the spheres' entries.
std::optional<std::pair<double, double>> rayCapsule(const Vec3& from, const Vec3& to, const Vec3& a, const Vec3& b,
                                                    double r) {
    const Vec3 d = to - from;
    const Vec3 axis = b - a;
    const double len2 = axis.squaredNorm();
    double best = 2.0;
    double along = 0.0;
    auto consider = [&](double t) {
        if (t < 0.0 || t > 1.0 || t >= best) return;
        best = t;
        const Vec3 p = from + t * d;
        along = len2 > 0.0 ? std::clamp((p - a).dot(axis) / len2, 0.0, 1.0) : 0.0;
    };
    if (len2 > 0.0) {
        // Cylinder: the components of (from - a) and d across the axis.
        const Vec3 u = axis / std::sqrt(len2);
        const Vec3 m = (from - a) - u * u.dot(from - a);
        const Vec3 n = d - u * u.dot(d);
        const double qa = n.squaredNorm();
        const double qb = m.dot(n);
        const double qc = m.squaredNorm() - r * r;
        if (qa > 0.0) {
            const double disc = qb * qb - qa * qc;
            if (disc >= 0.0) {
                const double t = qc <= 0.0 ? 0.0 : (-qb - std::sqrt(disc)) / qa;
                const double s = u.dot(from + t * d - a) / std::sqrt(len2);
                if (s >= 0.0 && s <= 1.0) consider(t);
            }
        }
    }
    consider(raySphere(from, d, a, r));
    consider(raySphere(from, d, b, r));
    if (best > 1.0) return std::nullopt;
    return std::make_pair(best, along);
}

std::optional<RayHit> rayTest(const World& world, const Vec3& from, const Vec3& to) {
    std::optional<RayHit> hit;
    for (StringId id : world.strings()) {
        const StringView v = world.view(id);
        const auto& x = *v.positions;
        for (std::size_t j = 0; j < v.segmentCount(); ++j) {
            if ((*v.broken)[j]) continue;
            const auto h = rayCapsule(from, to, x[j], x[j + 1], v.radius);
            if (!h || (hit && h->first >= hit->fraction)) continue;
            RayHit r;
            r.string = id;
            r.segment = static_cast<int>(j);
            r.fraction = h->first;
            r.along = h->second;
            r.point = from + h->first * (to - from);
            const Vec3 axis_point = x[j] + h->second * (x[j + 1] - x[j]);
            const Vec3 out = r.point - axis_point;
            r.normal = out.norm() > 0.0 ? Vec3(out.normalized()) : Vec3(-(to - from).normalized());
            hit = r;
        }
    }
    return hit;
}

}  // namespace tearables
