// The string's motion against closed forms: an undamped rope pendulum stepped by BDF2
// keeps its energy, its large-amplitude period and its tension at the bottom; drag is the
// user's, not the step's; a catenary's shape and horizontal tension; a transverse wave's
// speed.
#include "tearables/world.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

namespace {

using tearables::StringDesc;
using tearables::StringId;
using tearables::StringIntegrator;
using tearables::Vec3;
using tearables::World;

constexpr double kPi = 3.14159265358979323846;
constexpr double kG = 9.81;

/// The complete elliptic integral of the first kind K(k), by the arithmetic-geometric mean:
/// K = pi / (2 AGM(1, sqrt(1 - k^2))) (Abramowitz & Stegun 17.6).
double ellipticK(double k) {
    double a = 1.0, b = std::sqrt(1.0 - k * k);
    for (int i = 0; i < 40 && std::fabs(a - b) > 1e-16 * a; ++i) {
        const double next = 0.5 * (a + b);
        b = std::sqrt(a * b);
        a = next;
    }
    return kPi / (2.0 * a);
}

/// What a pendulum run measured: energy kept, period, tension of the bob's segment at
/// each pass through the bottom, largest elastic strain of the thread.
struct Swing {
    double energy_kept = 0.0;     ///< E / E0 at the end, E kinetic plus potential of every particle
    double amplitude_kept = 0.0;  ///< (1 - cos a) / (1 - cos a0), a the largest angle in the last period
    double period = 0.0;          ///< mean time between upward crossings of the vertical, s
    double reference_period = 0.0;  ///< 4 sqrt(L_eq / g) K(sin(a0 / 2)), L_eq = I / (M d) of the particles
    std::vector<double> bottom_tension;  ///< N, interpolated to the crossing
    std::vector<double> turn_time, turn_kept;  ///< at each turning point: t, (1 - cos a) / (1 - cos a0)
    double strain = 0.0;          ///< largest (thread length / L - 1) after the first second
    double young_area = 0.0;      ///< E A of the thread, N
};

/// A 1 kg bob on a thread of length L (40 segments, the default nylon, 2 mm radius),
/// released at rest from `degrees`, stepped at `dt` for `seconds`.
Swing swing(double degrees, double dt, double seconds, StringIntegrator integrator, double damping = 0.0) {
    const double L = 1.2;
    const int segments = 40;
    const double a0 = degrees * kPi / 180.0;
    World world;
    StringDesc d = StringDesc::straight({0, 0, 0}, {L * std::sin(a0), -L * std::cos(a0), 0}, segments);
    d.material.variation = 0.0;
    d.damping = damping;
    d.axial_damping = 0.0;
    d.particle_masses = {{-1, 1.0}};
    d.integrator = integrator;
    const StringId id = world.addString(d);
    world.attachToPoint(id, 0, {0, 0, 0});
    Swing out;
    out.young_area = d.material.tensile.young * kPi * d.radius * d.radius;
    const auto& x = *world.view(id).positions;
    const auto& v = *world.view(id).velocities;
    const auto& m = *world.view(id).masses;
    // Energy above the thread hanging straight down; the compound pendulum's length.
    double bottom = 0.0, inertia = 0.0, moment = 0.0;
    for (std::size_t p = 0; p < x.size(); ++p) {
        const double r = L * static_cast<double>(p) / segments;
        bottom -= m[p] * kG * r;
        inertia += m[p] * r * r;
        moment += m[p] * r;
    }
    auto energy = [&] {
        double e = -bottom;
        for (std::size_t p = 0; p < x.size(); ++p) e += 0.5 * m[p] * v[p].squaredNorm() + m[p] * kG * x[p].y();
        return e;
    };
    const double e0 = energy();
    out.reference_period = 4.0 * std::sqrt(inertia / moment / kG) * ellipticK(std::sin(0.5 * a0));
    std::vector<double> upward;
    double last_x = x.back().x(), last_tension = 0.0, largest = 0.0, last_dx = 0.0;
    const int steps = static_cast<int>(std::lround(seconds / dt));
    for (int i = 1; i <= steps; ++i) {
        world.step(dt);
        const double t = i * dt;
        const double tension = world.view(id).tension->back();
        const double bob = x.back().x();
        if ((last_x > 0.0) != (bob > 0.0)) {
            const double f = last_x / (last_x - bob);
            out.bottom_tension.push_back(last_tension + f * (tension - last_tension));
            if (bob > 0.0) upward.push_back(t - dt + f * dt);
        }
        // The bob turns where its sideways motion reverses (read at the step's end: the
        // angle there is within (omega h)^2 / 8 of the turning point's).
        const double dx = bob - last_x;
        if (i > 1 && (dx > 0.0) != (last_dx > 0.0)) {
            const double angle = std::fabs(std::atan2(last_x, -x.back().y()));
            out.turn_time.push_back(t - dt);
            out.turn_kept.push_back((1.0 - std::cos(angle)) / (1.0 - std::cos(a0)));
        }
        last_dx = dx;
        // The thread starts at its rest length, unloaded: its first second holds the axial
        // overshoot of a suddenly applied load, a vibration, not a stretch of the swing.
        double length = 0.0;
        for (std::size_t p = 0; p + 1 < x.size(); ++p) length += (x[p + 1] - x[p]).norm();
        if (t > 1.0) out.strain = std::max(out.strain, length / L - 1.0);
        if (t > seconds - out.reference_period) largest = std::max(largest, std::fabs(std::atan2(bob, -x.back().y())));
        last_x = bob;
        last_tension = tension;
    }
    out.energy_kept = energy() / e0;
    out.amplitude_kept = (1.0 - std::cos(largest)) / (1.0 - std::cos(a0));
    if (upward.size() > 1) out.period = (upward.back() - upward.front()) / static_cast<double>(upward.size() - 1);
    return out;
}

}  // namespace

// An undamped 1 kg bob on a 1.2 m thread, stepped by BDF2 at dt = 0.01 s for 10 s (over
// four periods), from 10, 40 and 60 degrees: it keeps at least 95% of its energy (read
// from the particles' state and from the amplitude of its last swing); its period is the
// large-amplitude pendulum's 4 sqrt(L/g) K(sin(a0/2)) within 0.5% (L the compound
// pendulum's I / (M d), 0.3% shorter than the thread for its 1.7% of the mass); at every
// pass through the bottom the bob's segment carries m g (3 - 2 cos a0) within 3%; and the
// thread stretches only by its elastic strain T / (E A) (5% over it for the peak tension).
TEST(Dynamics, UndampedPendulumKeepsEnergyPeriodAndBottomTension) {
    for (const double degrees : {10.0, 40.0, 60.0}) {
        const Swing s = swing(degrees, 0.01, 10.0, StringIntegrator::BDF2);
        const double a0 = degrees * kPi / 180.0;
        const double tension = 1.0 * kG * (3.0 - 2.0 * std::cos(a0));
        EXPECT_GE(s.energy_kept, 0.95) << degrees << " degrees";
        EXPECT_LE(s.energy_kept, 1.0 + 1e-3) << degrees << " degrees";  // never gains
        EXPECT_GE(s.amplitude_kept, 0.95) << degrees << " degrees";
        EXPECT_NEAR(s.period, s.reference_period, 0.005 * s.reference_period) << degrees << " degrees";
        ASSERT_GE(s.bottom_tension.size(), 8u) << degrees << " degrees";
        for (std::size_t k = 0; k < s.bottom_tension.size(); ++k)
            EXPECT_NEAR(s.bottom_tension[k], tension, 0.03 * tension) << degrees << " degrees, pass " << k;
        EXPECT_LT(s.strain, 1.05 * tension / s.young_area) << degrees << " degrees";
        ASSERT_GE(s.turn_kept.size(), 8u) << degrees << " degrees";
        for (std::size_t k = 0; k < s.turn_kept.size(); ++k) EXPECT_GE(s.turn_kept[k], 0.95) << degrees << " degrees, turn " << k;
    }
}

// The bob first reaches the bottom at a quarter period, 0.545 s from 40 degrees: the
// tension read there is m g (3 - 2 cos a0) within 3% with BDF2, and within 5% with backward
// Euler, which has lost 1 - exp(-(g/L) h t) ~ 4% of the energy by then.
TEST(Dynamics, TensionAtTheFirstPassThroughTheBottom) {
    const double tension = 1.0 * kG * (3.0 - 2.0 * std::cos(40.0 * kPi / 180.0));
    const Swing bdf2 = swing(40.0, 0.01, 0.7, StringIntegrator::BDF2);
    const Swing euler = swing(40.0, 0.01, 0.7, StringIntegrator::BackwardEuler);
    ASSERT_EQ(bdf2.bottom_tension.size(), 1u);
    ASSERT_EQ(euler.bottom_tension.size(), 1u);
    EXPECT_NEAR(bdf2.bottom_tension[0], tension, 0.03 * tension);
    EXPECT_NEAR(euler.bottom_tension[0], tension, 0.05 * tension);
}

// Drag is what the user sets, not a side effect of the step: with damping c every particle
// feels -c m v, so the energy falls as dE/dt = -2 c K, and over whole periods of a small
// swing K averages E / 2: E(t) = E0 exp(-c t). From 10 degrees with c = 0.05 1/s, at every
// turning point over 10 s: exp(-c t) within 3%, at dt = 0.01 s and at 0.005 s.
TEST(Dynamics, DragIsTheUsersNotTheSteps) {
    const double c = 0.05;
    for (const double dt : {0.01, 0.005}) {
        const Swing s = swing(10.0, dt, 10.0, StringIntegrator::BDF2, c);
        ASSERT_GE(s.turn_kept.size(), 8u) << dt;
        for (std::size_t k = 0; k < s.turn_kept.size(); ++k) {
            const double expected = std::exp(-c * s.turn_time[k]);
            EXPECT_NEAR(s.turn_kept[k], expected, 0.03 * expected) << "dt " << dt << ", turn " << k;
        }
    }
}

namespace {

/// The catenary parameter a of a chain of length `length` hung between two points at the
/// same height `span` apart: length = 2 a sinh(span / (2 a)), solved by bisection (the
/// right side falls monotonically from infinity to span as a grows).
double catenaryParameter(double length, double span) {
    double lo = 1e-3 * span, hi = 1e3 * span;
    for (int i = 0; i < 200; ++i) {
        const double a = 0.5 * (lo + hi);
        (2.0 * a * std::sinh(span / (2.0 * a)) > length ? lo : hi) = a;
    }
    return 0.5 * (lo + hi);
}

}  // namespace

// A rope of 1.2 m between two pins 1 m apart, at rest: its particles lie on the catenary
// y = a (cosh((x - S/2) / a) - cosh(S / (2a))), 1.2 = 2 a sinh(S / (2a)), within 1% of the
// sag, and every segment's horizontal tension T e_x is mu g a within 1% (the horizontal
// force of a catenary is constant along it). 120 segments without bending: the lumped
// chain's equilibrium differs from the continuous curve by O(1/n^2), ~1e-4; the elastic
// stretch under 0.1 N is 1e-5.
TEST(Dynamics, CatenaryShapeAndHorizontalTension) {
    const double span = 1.0, length = 1.2;
    const int segments = 120;
    World world;
    // Laid out as a V between the pins (the pins hold it where it starts).
    StringDesc d = StringDesc::straight({0, 0, 0}, {span, 0, 0}, segments);
    const double depth = std::sqrt(0.25 * length * length - 0.25 * span * span);
    for (int p = 0; p <= segments; ++p) {
        const double f = static_cast<double>(p) / segments;
        d.points[static_cast<std::size_t>(p)] = {f * span, -depth * (1.0 - std::fabs(2.0 * f - 1.0)), 0.0};
    }
    d.material.variation = 0.0;
    d.bending = 0.0;
    d.damping = 2.0;
    const StringId id = world.addString(d);
    world.attachToPoint(id, 0, {0, 0, 0});
    world.attachToPoint(id, -1, {span, 0, 0});
    for (int i = 0; i < 3000; ++i) world.step(0.01);
    const auto v = world.view(id);
    const auto& x = *v.positions;
    for (const Vec3& u : *v.velocities) ASSERT_LT(u.norm(), 1e-6);  // at rest
    const double a = catenaryParameter(length, span);
    const double sag = a * (std::cosh(span / (2.0 * a)) - 1.0);
    EXPECT_NEAR(-x[segments / 2].y(), sag, 0.01 * sag);
    for (std::size_t p = 0; p < x.size(); ++p) {
        const double curve = a * (std::cosh((x[p].x() - 0.5 * span) / a) - std::cosh(span / (2.0 * a)));
        EXPECT_NEAR(x[p].y(), curve, 0.01 * sag) << "particle " << p;
    }
    const double mu = d.density * kPi * d.radius * d.radius;
    const double horizontal = mu * kG * a;
    for (std::size_t j = 0; j < v.segmentCount(); ++j) {
        const Vec3 e = (x[j + 1] - x[j]).normalized();
        EXPECT_NEAR((*v.tension)[j] * e.x(), horizontal, 0.01 * horizontal) << "segment " << j;
    }
}

// A transverse pulse on a taut string travels at sqrt(T / mu). A thread of 0.5 mm radius
// (E A = 2356 N) is stretched by 0.1% between two pins 2 m apart, without gravity: T = E A
// 1e-3 = 2.36 N (every segment's strain checked) and mu = its mass over 2 m, c = 51 m/s. One pin makes a pulse of 0.5 mm,
// sin^2 over 4 ms (small: the slope's second-order stretch, 3e-5, is 3% of the strain);
// the peak passes x = 0.5 m and x = 1.5 m 1 m / c apart, within 5%, with either
// integrator at dt = 1e-4 s (the pulse spans ~40 segments and ~40 steps: the chain's and
// the step's dispersion are below 1%).
TEST(Dynamics, TransverseWaveTravelsAtSqrtTensionOverLineDensity) {
    for (const StringIntegrator integrator : {StringIntegrator::BackwardEuler, StringIntegrator::BDF2}) {
        const double span = 2.0, strain = 1e-3, dt = 1e-4;
        const int segments = 200;
        World world;
        world.settings().gravity = Vec3::Zero();
        StringDesc d = StringDesc::straight({0, 0, 0}, {span / (1.0 + strain), 0, 0}, segments);
        d.radius = 0.0005;
        d.material.variation = 0.0;
        d.bending = 0.0;
        d.tearable = false;
        d.integrator = integrator;
        const StringId id = world.addString(d);
        world.attachToPoint(id, 0, {0, 0, 0});
        // Stretched slowly (0.2 s, 1 um a step), then left to settle: no axial shock.
        const double start = span / (1.0 + strain);
        for (int i = 1; i <= 2000; ++i) {
            world.attachToPoint(id, -1, {start + (span - start) * i / 2000.0, 0, 0});
            world.step(dt);
        }
        for (int i = 0; i < 1000; ++i) world.step(dt);
        const auto v = world.view(id);
        const double young_area = d.material.tensile.young * kPi * d.radius * d.radius;
        const double tension = young_area * strain;
        // Every segment holds the strain (the tension read is no check here: with both ends
        // pinned and no load, momentum balance leaves a uniform tension undetermined).
        const auto& x = *v.positions;
        for (std::size_t j = 0; j < v.segmentCount(); ++j)
            ASSERT_NEAR((x[j + 1] - x[j]).norm() / (*v.rest_length)[j] - 1.0, strain, 0.01 * strain) << j;
        double mass = 0.0;
        for (double m : *v.masses) mass += m;
        const double speed = std::sqrt(tension / (mass / span));
        // The pulse; the probes' heights until it reaches the far pin.
        const double amplitude = 5e-4, width = 4e-3;
        const int probe[2] = {segments / 4, 3 * segments / 4};
        std::vector<double> height[2];
        const int steps = static_cast<int>(span / speed / dt);
        for (int i = 1; i <= steps; ++i) {
            const double t = i * dt;
            const double s = t < width ? std::sin(kPi * t / width) : 0.0;
            world.attachToPoint(id, 0, {0, amplitude * s * s, 0});
            world.step(dt);
            for (int k = 0; k < 2; ++k) height[k].push_back((*v.positions)[static_cast<std::size_t>(probe[k])].y());
        }
        // Each probe's peak time: the highest sample refined by the parabola through it
        // and its neighbours.
        double peak[2];
        for (int k = 0; k < 2; ++k) {
            const auto& y = height[k];
            const std::size_t i = static_cast<std::size_t>(std::max_element(y.begin() + 1, y.end() - 1) - y.begin());
            const double shift = 0.5 * (y[i - 1] - y[i + 1]) / (y[i - 1] - 2.0 * y[i] + y[i + 1]);
            peak[k] = (static_cast<double>(i + 1) + shift) * dt;
            // The pulse arrived, not a ripple (backward Euler's step damps it: at the pulse's
            // omega h = 0.16 it keeps ~40% of its height over 1.5 m; BDF2 ~90%).
            EXPECT_GT(y[i], 0.25 * amplitude) << k;
        }
        const double distance = (*v.positions)[static_cast<std::size_t>(probe[1])].x() - (*v.positions)[static_cast<std::size_t>(probe[0])].x();
        EXPECT_NEAR(distance / (peak[1] - peak[0]), speed, 0.05 * speed) << static_cast<int>(integrator);
    }
}

// A mass dropped onto a rope: a 1 kg bob on 1.2 m of the default thread (k = E A / L =
// 31.4 kN/m, 1.7% of the bob's mass, no axial damping) is thrown up at 1 m/s from where the
// rope is just taut, falls back h = v0^2 / (2 g) and is caught: the rope stretches by x with
// m g (h + x) = k x^2 / 2, 6.0 mm, and pulls k x = 187 N at the bottom. Both within 5%:
// BDF2 at dt = 0.5 ms (70 steps a period of the bob on the rope's stiffness), backward
// Euler at 0.1 ms (at 0.5 ms its numerical damping leaves the peak 7% low).
TEST(Dynamics, MassDroppedOntoARopeStretchesItAsTheEnergyBalanceSays) {
    struct Case {
        StringIntegrator integrator;
        double dt;
    };
    for (const Case c : {Case{StringIntegrator::BDF2, 5e-4}, Case{StringIntegrator::BackwardEuler, 1e-4}}) {
        const double L = 1.2, m = 1.0, v0 = 1.0;
        World world;
        StringDesc d = StringDesc::straight({0, 0, 0}, {0, -L, 0}, 40);
        d.material.variation = 0.0;
        d.axial_damping = 0.0;
        d.bending = 0.0;
        d.tearable = false;
        d.particle_masses = {{-1, m}};
        d.integrator = c.integrator;
        const StringId id = world.addString(d);
        world.attachToPoint(id, 0, {0, 0, 0});
        const double k = d.material.tensile.young * kPi * d.radius * d.radius / L;
        world.applyForce(id, -1, {0, m * (v0 / c.dt + kG), 0});  // one step's impulse m v0 (and the weight)
        world.step(c.dt);
        const auto v = world.view(id);
        double lowest = 0.0, peak = 0.0;
        const int steps = static_cast<int>((2.0 * v0 / kG + 0.1) / c.dt);  // the flight and half a bounce
        for (int i = 0; i < steps; ++i) {
            world.step(c.dt);
            lowest = std::min(lowest, v.positions->back().y());
            peak = std::max(peak, v.tension->back());
        }
        const double x = (m * kG + std::sqrt(m * kG * m * kG + k * m * v0 * v0)) / k;
        EXPECT_NEAR(-lowest - L, x, 0.05 * x) << static_cast<int>(c.integrator);
        EXPECT_NEAR(peak, k * x, 0.05 * k * x) << static_cast<int>(c.integrator);
    }
}
