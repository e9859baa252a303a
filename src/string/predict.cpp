// The prediction and velocity stages of StringSystem::step: unconstrained prediction x'
// and velocities from positions.
#include "base/thread_pool.hpp"
#include "string/string_state.hpp"

#include <algorithm>
#include <cmath>

namespace tearables::detail {

namespace {

// The previous step's twist force (Eq. 6) is explicit: the displacement it causes is
// capped at a tenth of a segment, a safety limit for a string twisted far past its
// strength or spun hard (a light rope rolled under a sliding box). The cap scales the
// whole string's twist forces by one factor: each joint's forces on its three particles
// sum to zero, and so do the scaled ones, where capping each particle's force alone would
// push the string (and the bodies it holds) with the difference.
double twistScale(const StringState& s, const StepContext& ctx) {
    if (s.scratch.twist_force_zero) return 1.0;
    const double reach = 0.1 * s.shortest_rest * ctx.inv_h * ctx.inv_h;
    double scale = 1.0;
    for (std::size_t p = 0; p < s.particles(); ++p) {
        const double f = s.twist_force[p].norm(), cap = reach * s.mass[p];
        if (f > cap) scale = std::min(scale, cap / f);
    }
    return scale;
}

/// Free particle p's acceleration from gravity, its force and the previous step's twist
/// force (scaled by the cap: twistScale).
Vec3 acceleration(const StringState& s, std::size_t p, const StepContext& ctx) {
    return ctx.gravity + s.inv_mass[p] * (s.force[p] + cappedTwistForce(s, p));
}

/// Symplectic Euler toward backward Euler's solve, from x_n = x_prev and velocity
/// `v_start`: drag damps the motion, not the load (a rope at rest still feels all of
/// gravity, else the momentum-balance tension would miss part of the weight).
void predictEuler(StringState& s, std::size_t p, const Vec3& v_start, double damp, const StepContext& ctx) {
    const Vec3 v = damp * v_start + ctx.h * acceleration(s, p, ctx);
    s.x[p] = s.x_prev[p] + (ctx.h * v + s.scratch.csm_goal[p]);  // plus the bending correction (shape_matching.cpp)
}

/// The velocity a backward Euler step continues from after BDF2 steps: BDF2 accumulates a
/// force's impulse in (3 v_n - v_{n-1}) / 2 (its difference from one step to the next is
/// h a exactly), not in v_n; starting from it, no impulse is lost at the switch.
inline Vec3 bdf2Momentum(const StringState& s, std::size_t p) { return 0.5 * (3.0 * s.v[p] - s.v_prev[p]); }

/// Whether every segment of the string is taut at the start of the step (no shorter than
/// its rest length by kTautSlack of it, as the strain solve counts it, or broken).
bool everySegmentTaut(const StringState& s) {
    constexpr double kTautSlack = 1e-4;
    for (std::size_t j = 0; j < s.segments(); ++j) {
        if (s.broken[j]) continue;
        const double limit = (1.0 - kTautSlack) * s.rest_length[j];
        if ((s.x[j + 1] - s.x[j]).squaredNorm() < limit * limit) return false;
    }
    return true;
}

}  // namespace

// The prediction x' that the strain-limit solve pulls each free particle toward (Strings,
// Sec. 3: particles move independently under external forces before shape matching and
// strain limiting). Backward Euler's is symplectic Euler's step. BDF2's (second order and
// L-stable: a swing keeps its energy, stiff axial modes still die out) is
//   v' = (4 v_n - v_{n-1}) / 3 + (2/3) h a,   x' = (4 x_n - x_{n-1}) / 3 + (2/3) h v',
//   x_{n+1} = argmin sum 9 m / (8 h^2) |x - x'|^2 + E(x),
// the same solve with the inertia weighted by inertia_gain = 9/4; the displacement added
// here (the bending goal) takes the factor 4/9 that turns the same force into BDF2's
// displacement, and drag is implicit: v' (1 + 2/3 c h) = (4 v_n - v_{n-1}) / 3 + ...
// Held particles follow their hold: a pin's target, or the glue point on the body the host
// has already integrated this step (Bullet integrates rigid bodies before actions run).
// During the step v and v_prev stay v_n and v_{n-1} (updateVelocities moves them on).
void predict(StringState& s, const RigidTable& rigids, const StepContext& ctx) {
    const double h = ctx.h;
    s.scratch.twist_scale = twistScale(s, ctx);
    // A step that starts with a slack segment is backward Euler's: a segment that goes taut
    // in it is a catch, whose impulse BDF2's history would carry into the next steps. After
    // a step that was not BDF2, the history restarts at constant velocity:
    // x_{n-1} = x_n - h v_n, v_{n-1} = v_n.
    const bool second_order = s.desc.integrator == StringIntegrator::BDF2;
    const bool bdf2 = second_order && everySegmentTaut(s);
    const bool history = s.inertia_gain != 1.0;
    s.inertia_gain = bdf2 ? 9.0 / 4.0 : 1.0;
    const double step = (2.0 / 3.0) * h;
    const double damp = 1.0 / (1.0 + s.desc.damping * (bdf2 ? step : h));
    forRanges(ctx.pool, s.particles(), kParallelItems, [&](std::size_t p0, std::size_t p1, std::size_t) {
        for (std::size_t p = p0; p < p1; ++p) {
            const Vec3& v_start = s.v[p];
            if (second_order) {  // BDF2's history (backward Euler's strings keep none)
                s.x_older[p] = history ? s.x_prev[p] : Vec3(s.x[p] - h * v_start);
                if (!history) s.v_prev[p] = v_start;
            }
            s.x_prev[p] = s.x[p];
            const ParticleHold& hold = s.hold[p];
            switch (hold.kind) {
                case ParticleHold::Kind::Pin:
                    s.x[p] = hold.point;
                    break;
                case ParticleHold::Kind::Glue:
                    s.x[p] = gluePoint(rigids.bodies[hold.body.index], hold.point);
                    break;
                case ParticleHold::Kind::Free:
                    if (bdf2) {
                        const Vec3 v = damp * ((4.0 * v_start - s.v_prev[p]) / 3.0) + step * acceleration(s, p, ctx);
                        s.x[p] = (4.0 * s.x[p] - s.x_older[p]) / 3.0 + step * v + (4.0 / 9.0) * s.scratch.csm_goal[p];
                    } else {
                        predictEuler(s, p, history ? bdf2Momentum(s, p) : v_start, damp, ctx);
                    }
                    break;
            }
        }
    });
}

// A BDF2 step of a string that touches a rigid body or holds a movable one becomes backward
// Euler's: the bodies are stepped that way, and the impulses the two exchange must match
// within the step. Its free particles' predictions are made again from the step's start.
void predictBackwardEuler(StringState& s, const StepContext& ctx) {
    if (s.inertia_gain == 1.0) return;
    s.inertia_gain = 1.0;
    const double damp = 1.0 / (1.0 + s.desc.damping * ctx.h);
    for (std::size_t p = 0; p < s.particles(); ++p)
        if (s.hold[p].kind == ParticleHold::Kind::Free) predictEuler(s, p, bdf2Momentum(s, p), damp, ctx);
}

// The speed clamp on positions: after the strain limit, no free particle has moved farther
// than max_speed * h this step (an absurd finite force, 1e30 N, would fling a torn piece
// 1e26 m, across every other string's swept search). Held particles are left alone.
void clampTravel(StringState& s, const StepContext& ctx) {
    const double reach = ctx.settings->max_speed * ctx.h;
    const std::size_t n = s.particles();
    forRanges(ctx.pool, n, kParallelItems, [&](std::size_t p0, std::size_t p1, std::size_t) {
        for (std::size_t p = p0; p < p1; ++p) {
            if (s.hold[p].kind != ParticleHold::Kind::Free) continue;
            const Vec3 d = s.x[p] - s.x_prev[p];
            const double travel2 = d.squaredNorm();
            if (travel2 > reach * reach) {
                s.x[p] = s.x_prev[p] + d * (reach / std::sqrt(travel2));
                // A particle that no segment holds any more: its run-away prediction goes too
                // (the string-string joint solve and its collision search start from it). One
                // on a segment keeps it, so that the pull reads as tension and tears it.
                const bool before = p > 0 && !s.broken[p - 1];
                const bool after = p + 1 < n && !s.broken[p];
                if (!before && !after) s.x_pred[p] = s.x[p];
            }
        }
    });
}

// Position-based velocity update: v = (x - x_prev) / h for every particle (held ones too:
// a moved pin or a swinging body gives its particle its velocity), clamped to max_speed on
// the constrained result, as a prediction's huge speed may be removed by the limiter.
void updateVelocities(StringState& s, const StepContext& ctx) {
    const double max_speed = ctx.settings->max_speed;
    const bool second_order = s.desc.integrator == StringIntegrator::BDF2;
    forRanges(ctx.pool, s.particles(), kParallelItems, [&](std::size_t p0, std::size_t p1, std::size_t) {
        for (std::size_t p = p0; p < p1; ++p) {
            // BDF2's velocity (3 x_{n+1} - 4 x_n + x_{n-1}) / (2h) for a free particle of a
            // BDF2 step; a held particle's is its hold's motion over the step.
            Vec3 v = s.inertia_gain != 1.0 && s.hold[p].kind == ParticleHold::Kind::Free
                         ? Vec3((3.0 * s.x[p] - 4.0 * s.x_prev[p] + s.x_older[p]) * (0.5 * ctx.inv_h))
                         : Vec3((s.x[p] - s.x_prev[p]) * ctx.inv_h);
            const double speed2 = v.squaredNorm();
            if (speed2 > max_speed * max_speed) v *= max_speed / std::sqrt(speed2);
            if (second_order) s.v_prev[p] = s.v[p];
            s.v[p] = v;
        }
    });
}

}  // namespace tearables::detail
