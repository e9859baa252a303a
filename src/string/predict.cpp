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

}  // namespace

// Symplectic Euler prediction (Strings, Sec. 3: particles move independently under
// external forces before shape matching and strain limiting). Held particles follow
// their hold: a pin's target, or the glue point on the body the host has already
// integrated this step (Bullet integrates rigid bodies before actions run).
void predict(StringState& s, const RigidTable& rigids, const StepContext& ctx) {
    const double h = ctx.h;
    s.scratch.twist_scale = twistScale(s, ctx);
    const double damp = 1.0 / (1.0 + s.desc.damping * h);
    forRanges(ctx.pool, s.particles(), kParallelItems, [&](std::size_t p0, std::size_t p1, std::size_t) {
        for (std::size_t p = p0; p < p1; ++p) {
            s.x_prev[p] = s.x[p];
            const ParticleHold& hold = s.hold[p];
            switch (hold.kind) {
                case ParticleHold::Kind::Pin:
                    s.x[p] = hold.point;
                    break;
                case ParticleHold::Kind::Glue:
                    s.x[p] = gluePoint(rigids.bodies[hold.body.index], hold.point);
                    break;
                case ParticleHold::Kind::Free: {
                    // Drag damps the motion, not the load: a rope at rest still feels all of
                    // gravity (else the momentum-balance tension would miss part of the weight).
                    const Vec3 v = damp * s.v[p] + h * (ctx.gravity + s.inv_mass[p] * (s.force[p] + cappedTwistForce(s, p)));
                    s.v[p] = v;
                    s.x[p] += h * v + s.scratch.csm_goal[p];  // plus the bending correction (shape_matching.cpp)
                    break;
                }
            }
        }
    });
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
    forRanges(ctx.pool, s.particles(), kParallelItems, [&](std::size_t p0, std::size_t p1, std::size_t) {
        for (std::size_t p = p0; p < p1; ++p) {
            Vec3 v = (s.x[p] - s.x_prev[p]) * ctx.inv_h;
            const double speed2 = v.squaredNorm();
            if (speed2 > max_speed * max_speed) v *= max_speed / std::sqrt(speed2);
            s.v[p] = v;
        }
    });
}

}  // namespace tearables::detail
