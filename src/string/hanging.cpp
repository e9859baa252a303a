// A string's shape from two points and a length (StringDesc::between), and a particle
// inserted along a string's points (insertParticle, tearables/controls.hpp).
//
// The hanging shape: a uniform inextensible rope of length L between points a horizontal
// distance H and a height V apart hangs as the catenary y = c (cosh((x - x_m)/c) - cosh(x_m/c))
// (x from a along the horizontal, y up), where c = T_0 / (mu g) solves
//     sqrt(L^2 - V^2) = 2 c sinh(H / (2c)),
// and the lowest point is at x_m = H/2 - c artanh(V/L) (e.g. Irvine, "Cable Structures",
// 1981, ch. 1). The arc length from a is S(x) = c (sinh((x - x_m)/c) + sinh(x_m/c)), so the
// particle at arc length s sits at x = x_m + c asinh(s/c - sinh(x_m/c)).
#include "tearables/controls.hpp"

#include "base/validate.hpp"

#include <algorithm>
#include <cmath>
#include <string>

namespace tearables {

namespace {

/// sinh(z) / z, accurate near 0.
double sinhc(double z) { return std::abs(z) < 1e-4 ? 1.0 + z * z / 6.0 : std::sinh(z) / z; }

void requireFinitePoint(const char* field, const Vec3& p) {
    if (!p.allFinite()) throw InvalidInput(field, "must be finite");
    detail::requirePosition(field, p);
}

}  // namespace

StringDesc StringDesc::between(const Vec3& a, const Vec3& b, double length, int segments) {
    requireFinitePoint("a", a);
    requireFinitePoint("b", b);
    if (segments < 1 || segments > 10'000'000)
        throw InvalidInput("segments", "must be in [1, 10000000] (got " + std::to_string(segments) + ")");
    const Vec3 d = b - a;
    const double chord = d.norm();
    if (!(chord >= 1e-6)) throw InvalidInput("b", "must be at least 1e-6 m from a");
    if (!std::isfinite(length) || length > 1e6) throw InvalidInput("length", "must be finite and at most 1e6 m");
    if (length < chord * (1.0 - 1e-9))
        throw InvalidInput("length", "must be at least |b - a| = " + std::to_string(chord) + " m (got " + std::to_string(length) + ")");
    if (length <= chord * (1.0 + 1e-9)) return StringDesc::straight(a, b, segments);
    const double H = std::hypot(d.x(), d.z()), V = d.y(), L = length;
    if (H < 1e-6 * L)
        throw InvalidInput("b", "is straight above or below a: a slack rope between them hangs in no single curve; "
                                "move b aside or give length = |b - a|");
    const Vec3 across = Vec3(d.x(), 0.0, d.z()) / H;
    // z = H / (2c) solves sinhc(z) = r, r = sqrt(L^2 - V^2) / H > 1; sinhc grows on z > 0.
    const double r = std::sqrt((L - V) * (L + V)) / H;
    double lo = 0.0, hi = 1.0;
    while (sinhc(hi) < r) hi *= 2.0;  // sinhc(hi) >= r within ~log2(log r) + 10 doublings
    for (int k = 0; k < 200 && hi - lo > 1e-15 * hi; ++k) {
        const double mid = 0.5 * (lo + hi);
        (sinhc(mid) < r ? lo : hi) = mid;
    }
    const double z = 0.5 * (lo + hi);
    const double c = H / (2.0 * z);
    const double xm = 0.5 * H - c * std::atanh(V / L);
    const double s0 = std::sinh(xm / c), c0 = std::cosh(xm / c);
    StringDesc desc;
    desc.points.resize(static_cast<std::size_t>(segments) + 1);
    for (int k = 0; k <= segments; ++k) {
        const double s = L * k / segments;
        const double x = xm + c * std::asinh(s / c - s0);
        const double y = c * (std::cosh((x - xm) / c) - c0);
        desc.points[static_cast<std::size_t>(k)] = a + x * across + y * Vec3::UnitY();
    }
    desc.points.front() = a;
    desc.points.back() = b;
    for (const Vec3& p : desc.points)
        if (!p.allFinite())
            throw InvalidInput("length", "too close to |b - a| for the hanging shape in double precision; give length = |b - a|");
    return desc;
}

int insertParticle(StringDesc& desc, double s) {
    validate(desc);
    if (!std::isfinite(s) || s < 0.0 || s > 1.0) throw InvalidInput("s", "must be a fraction of the length in [0, 1]");
    const std::size_t n = desc.points.size();
    std::vector<double> along(n, 0.0);  // arc length at each particle, m
    for (std::size_t i = 1; i < n; ++i) along[i] = along[i - 1] + (desc.points[i] - desc.points[i - 1]).norm();
    const double total = along.back(), target = s * total, near = 1e-9 * total;
    std::size_t j = 0;
    while (j + 2 < n && along[j + 1] < target) ++j;  // segment j holds the target
    if (std::abs(target - along[j]) <= near) return static_cast<int>(j);
    if (std::abs(along[j + 1] - target) <= near) return static_cast<int>(j + 1);
    const double t = (target - along[j]) / (along[j + 1] - along[j]);
    StringDesc split = desc;
    split.points.insert(split.points.begin() + static_cast<std::ptrdiff_t>(j + 1),
                        (1.0 - t) * desc.points[j] + t * desc.points[j + 1]);
    if (split.twist_half_width.size() > 1)
        split.twist_half_width.insert(split.twist_half_width.begin() + static_cast<std::ptrdiff_t>(j + 1),
                                      split.twist_half_width[j]);
    for (auto& [index, mass] : split.particle_masses)
        if (index >= static_cast<int>(j + 1)) ++index;
    validate(split);
    desc = std::move(split);
    return static_cast<int>(j + 1);
}

}  // namespace tearables
