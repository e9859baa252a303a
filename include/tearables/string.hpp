// tearables: the string (rope, thread) descriptor.
#pragma once

#include "tearables/material.hpp"
#include "tearables/types.hpp"

#include <string>
#include <utility>
#include <vector>

namespace tearables {

/// How per-segment tension is estimated after strain limiting.
enum class TensionEstimator {
    /// Yarn, Sec. 3.2: the tensions that explain the constrained motion by momentum
    /// balance, solved directly (O(n), tridiagonal normal equations) for a chain. Default.
    Momentum,
    /// Strings, Eq. 12: T = k (|x'_{i+1}-x'_i| - |x_{i+1}-x_i|), a local estimate.
    Local,
};

/// How a string's free particles are stepped in time (the strain-limit solve's inertia).
enum class StringIntegrator {
    /// Backward Euler: first order; every swing loses energy, about exp(-(g/L) h t) for a
    /// pendulum of length L at step h. Default.
    BackwardEuler,
    /// BDF2: second order, so an undamped swing keeps its energy (a 1.2 m pendulum at
    /// h = 0.01 s keeps over 98% over 10 s), still damping the stiff axial modes. A step in
    /// which the string touches a rigid body or holds a movable one is backward Euler
    /// (bodies are stepped that way, and an impact must not bounce).
    BDF2,
};

/// Everything needed to create a string. A string is a chain of `points.size()`
/// particles joined by `points.size() - 1` segments whose rest lengths are the
/// distances between consecutive points.
struct StringDesc {
    std::string name;              ///< for events and traces; may be empty
    std::vector<Vec3> points;      ///< particle rest positions, m; at least 2, each coordinate in [-1e6, 1e6], no zero-length segment
    double radius = 0.002;         ///< cross-section radius, m, [1e-7, 10]
    double density = 1150.0;       ///< kg/m^3, [1e-3, 1e5]; segment mass = density * pi r^2 * length, split over its ends
    /// Replaced particle masses, kg, [1e-15, 1e12], at most one per particle: (particle index, mass); a negative index counts from the end (-1 = last).
    std::vector<std::pair<int, double>> particle_masses;
    Material material;             ///< stress-strain curves
    int csm_half_width = 2;        ///< chain shape matching region half-width w, 1..8 (bending stiffness)
    /// Fraction of the shape-matching goal displacement applied per step, [0, 1]: 1 is the
    /// paper's full step (stiff as a thread or cord), small values make a floppy rope, 0
    /// turns bending off.
    double bending = 1.0;
    /// Twist region half-width, 1..8: one value for all segments, or one per segment.
    std::vector<int> twist_half_width = {2};
    TensionEstimator tension = TensionEstimator::Momentum;  ///< tension estimator (one of the enum's values)
    StringIntegrator integrator = StringIntegrator::BackwardEuler;  ///< time integrator (one of the enum's values)
    bool tearable = true;          ///< segments break where their stress passes rupture
    /// Plastic flow solved inside the strain-limit solve: a segment past its yield force is
    /// a spring of the plastic slope there, and its rest length follows the force the solve
    /// ends with (a return mapping), so that a rising load neither overshoots the curve nor
    /// leaves segments slack (docs/yield.md). False: the rest length grows after the step
    /// from the estimated tension (the default).
    bool yield_in_solve = false;
    double damping = 0.0;          ///< linear velocity damping, 1/s, [0, 1000] (air drag stand-in)
    /// Retardation time of the material's stretch (Kelvin-Voigt), s, [0, 1]: damps the
    /// axial vibration of a loaded rope; 0 = undamped.
    double axial_damping = 0.01;
    std::uint64_t seed = 1;        ///< seeds the per-segment material variation

    /// A straight string from `from` to `to` with `segments` equal segments.
    static StringDesc straight(const Vec3& from, const Vec3& to, int segments);
    /// A string of `length` (m) from `a` to `b` in `segments` segments, hanging as a uniform
    /// heavy rope does under gravity along -y: the catenary through a and b of that arc
    /// length, the particles at equal arc lengths (each segment's rest length is its chord,
    /// short of length / segments by (k l)^2 / 24 of it, k the curvature, l the segment).
    /// With `length` equal to |b - a| (to 1e-9 relative) the string is straight. Pin or glue
    /// its ends where it starts and it starts at rest in its hanging shape. Throws
    /// InvalidInput ("a", "b": finite, in range, 1e-6 m apart or more, and apart
    /// horizontally by 1e-6 of the length or more when there is slack; "length": finite,
    /// at least |b - a|, at most 1e6 m; "segments": 1..10 million).
    static StringDesc between(const Vec3& a, const Vec3& b, double length, int segments);
};

/// Throws InvalidInput naming the field when `desc` is not valid.
void validate(const StringDesc& desc);

}  // namespace tearables
