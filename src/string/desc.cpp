// StringDesc construction and validation: check at creation, so the hot loop can assume.
#include "base/validate.hpp"
#include "sim/validate_material.hpp"
#include "tearables/string.hpp"
#include "tearables/world.hpp"

#include <algorithm>
#include <cmath>

namespace tearables {

namespace {

using detail::num;
using detail::requireFinite;
using detail::requirePositive;
using detail::requirePhysical;
using detail::requireRange;

// Physical ranges: wide enough for every real string (a 0.1 um fibre to a 10 m hawser),
// narrow enough that nothing derived from them under- or overflows.
constexpr double kMinRadius = 1e-7, kMaxRadius = 10.0;        // m
constexpr double kMinDensity = 1e-3, kMaxDensity = 1e5;       // kg/m^3
constexpr double kMinMass = 1e-15, kMaxMass = 1e12;           // kg

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
        detail::requirePosition(f, d.points[i]);
        if (i > 0) {
            const double len = (d.points[i] - d.points[i - 1]).norm();
            if (!(len > 1e-9))
                throw InvalidInput(f, "zero-length segment " + std::to_string(i - 1) + " (points " + std::to_string(i - 1) +
                                          " and " + std::to_string(i) + " coincide)");
        }
    }
    requirePhysical("radius", d.radius, kMinRadius, kMaxRadius);
    requirePhysical("density", d.density, kMinDensity, kMaxDensity);
    const int n = static_cast<int>(d.points.size());
    std::vector<int> massed;
    for (const auto& [index, mass] : d.particle_masses) {
        const std::string f = "particle_masses[" + std::to_string(index) + "]";
        if (index < -n || index >= n)
            throw InvalidInput(f, "particle index out of range (the string has " + std::to_string(n) + " particles)");
        requirePhysical(f, mass, kMinMass, kMaxMass);
        const int resolved = index < 0 ? index + n : index;
        if (std::find(massed.begin(), massed.end(), resolved) != massed.end())
            throw InvalidInput(f, "particle " + std::to_string(resolved) + " already has a mass");
        massed.push_back(resolved);
    }
    // Segment masses from the geometry: a segment so long that its mass overflows.
    const double area = 3.14159265358979323846 * d.radius * d.radius;
    for (std::size_t i = 1; i < d.points.size(); ++i) {
        const double mass = d.density * area * (d.points[i] - d.points[i - 1]).norm();
        if (!std::isfinite(mass) || !(mass > 0.0) || !std::isfinite(1.0 / mass))
            throw InvalidInput("points[" + std::to_string(i) + "]",
                               "segment " + std::to_string(i - 1) + " has no usable mass (" + num(mass) + " kg)");
    }
    detail::validateMaterial(d.material, "material");
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
    if (d.tension != TensionEstimator::Momentum && d.tension != TensionEstimator::Local)
        throw InvalidInput("tension", "must be TensionEstimator::Momentum or TensionEstimator::Local (got " +
                                          std::to_string(static_cast<int>(d.tension)) + ")");
    if (d.integrator != StringIntegrator::BackwardEuler && d.integrator != StringIntegrator::BDF2)
        throw InvalidInput("integrator", "must be StringIntegrator::BackwardEuler or StringIntegrator::BDF2 (got " +
                                             std::to_string(static_cast<int>(d.integrator)) + ")");
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
    if (s.threads < 0 || s.threads > 64)
        throw InvalidInput("threads", "must be in [0, 64] (0: one per core; got " + std::to_string(s.threads) + ")");
}

}  // namespace tearables
