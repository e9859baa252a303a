// StringDesc construction and validation: check at creation, so the hot loop can assume.
#include "tearables/string.hpp"
#include "tearables/world.hpp"

#include <cmath>
#include <sstream>

namespace tearables {

namespace {

std::string num(double v) {
    std::ostringstream s;
    s.precision(9);
    s << v;
    return s.str();
}

void requireFinite(const std::string& field, double v) {
    if (!std::isfinite(v)) throw InvalidInput(field, "must be a finite number (got " + num(v) + ")");
}

void requirePositive(const std::string& field, double v) {
    requireFinite(field, v);
    if (!(v > 0.0)) throw InvalidInput(field, "must be greater than 0 (got " + num(v) + ")");
}

void requireRange(const std::string& field, double v, double lo, double hi) {
    requireFinite(field, v);
    if (v < lo || v > hi)
        throw InvalidInput(field, "must be in [" + num(lo) + ", " + num(hi) + "] (got " + num(v) + ")");
}

}  // namespace

StringDesc StringDesc::straight(const Vec3& from, const Vec3& to, int segments) {
    StringDesc d;
    if (segments < 1) throw InvalidInput("segments", "must be at least 1 (got " + std::to_string(segments) + ")");
    d.points.reserve(static_cast<std::size_t>(segments) + 1);
    for (int i = 0; i <= segments; ++i) {
        const double s = static_cast<double>(i) / segments;
        d.points.push_back((1.0 - s) * from + s * to);
    }
    return d;
}

void validate(const StringDesc& d) {
    if (d.points.size() < 2)
        throw InvalidInput("points", "a string needs at least 2 points (got " + std::to_string(d.points.size()) + ")");
    if (d.points.size() > 10'000'000) throw InvalidInput("points", "more than 10 million particles");
    for (std::size_t i = 0; i < d.points.size(); ++i) {
        const std::string f = "points[" + std::to_string(i) + "]";
        for (int k = 0; k < 3; ++k)
            if (!std::isfinite(d.points[i][k])) throw InvalidInput(f, "must be finite (got a NaN or infinite coordinate)");
        if (i > 0) {
            const double len = (d.points[i] - d.points[i - 1]).norm();
            if (!(len > 1e-9))
                throw InvalidInput(f, "zero-length segment " + std::to_string(i - 1) + " (points " + std::to_string(i - 1) +
                                          " and " + std::to_string(i) + " coincide)");
        }
    }
    requirePositive("radius", d.radius);
    requirePositive("density", d.density);
    const int n = static_cast<int>(d.points.size());
    for (const auto& [index, mass] : d.particle_masses) {
        const std::string f = "particle_masses[" + std::to_string(index) + "]";
        if (index < -n || index >= n)
            throw InvalidInput(f, "particle index out of range (the string has " + std::to_string(n) + " particles)");
        requirePositive(f, mass);
    }
    const TensileCurve& t = d.material.tensile;
    requirePositive("material.tensile.young", t.young);
    requirePositive("material.tensile.yield", t.yield);
    requirePositive("material.tensile.plastic_modulus", t.plastic_modulus);
    requirePositive("material.tensile.rupture", t.rupture);
    if (!(t.rupture > t.yield))
        throw InvalidInput("material.tensile.rupture", "must be greater than yield (" + num(t.rupture) + " <= " + num(t.yield) + ")");
    const TorsionCurve& q = d.material.torsion;
    requirePositive("material.torsion.modulus", q.modulus);
    requirePositive("material.torsion.yield", q.yield);
    requirePositive("material.torsion.plastic_modulus", q.plastic_modulus);
    requirePositive("material.torsion.rupture", q.rupture);
    if (!(q.rupture > q.yield))
        throw InvalidInput("material.torsion.rupture", "must be greater than yield (" + num(q.rupture) + " <= " + num(q.yield) + ")");
    requireRange("material.variation", d.material.variation, 0.0, 0.5);
    if (d.csm_half_width < 1 || d.csm_half_width > 8)
        throw InvalidInput("csm_half_width", "must be in [1, 8] (got " + std::to_string(d.csm_half_width) + ")");
    requireRange("bending", d.bending, 0.0, 1.0);
    const std::size_t segments = d.points.size() - 1;
    if (d.twist_half_width.size() != 1 && d.twist_half_width.size() != segments)
        throw InvalidInput("twist_half_width", "needs one value or one per segment (" + std::to_string(segments) +
                                                   "), got " + std::to_string(d.twist_half_width.size()));
    for (std::size_t i = 0; i < d.twist_half_width.size(); ++i)
        if (d.twist_half_width[i] < 1 || d.twist_half_width[i] > 8)
            throw InvalidInput(d.twist_half_width.size() == 1 ? "twist_half_width" : "twist_half_width[" + std::to_string(i) + "]",
                               "must be in [1, 8] (got " + std::to_string(d.twist_half_width[i]) + ")");
    requireRange("damping", d.damping, 0.0, 1e3);
    requireRange("axial_damping", d.axial_damping, 0.0, 1.0);
}

void validate(const WorldSettings& s) {
    for (int k = 0; k < 3; ++k) requireFinite("gravity", s.gravity[k]);
    if (s.strain_iterations < 1 || s.strain_iterations > 64)
        throw InvalidInput("strain_iterations", "must be in [1, 64] (got " + std::to_string(s.strain_iterations) + ")");
    if (s.coupling_iterations < 1 || s.coupling_iterations > 64)
        throw InvalidInput("coupling_iterations", "must be in [1, 64] (got " + std::to_string(s.coupling_iterations) + ")");
    requireRange("strain_tolerance", s.strain_tolerance, 1e-12, 0.01);
    requirePositive("max_speed", s.max_speed);
}

}  // namespace tearables
