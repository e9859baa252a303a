// Per-segment tension (the tension stage of StringSystem::step).
//
// Momentum balance (default; Yarn Sec. 3.2). With forward Euler, a particle i of mass m_i
// whose constrained motion is x''_i, x'_i its position before strain limiting, satisfies
//     m_i (x''_i - x'_i) / h^2 = sum_j T_j a_ij,     a_ij = +e_j if i starts segment j, -e_j if it ends it.
// The free particles' equations A T = b (3 per particle, one unknown per segment) are solved
// in least squares, (A^T A + lambda) T = A^T b + lambda T_s, in newtons as Yarn writes them:
// tridiagonal on a chain, O(n). Clamped particles carry an unknown support force and give
// no equation; a particle glued to a body gives "the segments pull the body with the
// impulse the limiter gave it" (glue_impulse). Tikhonov lambda = 1e-6 of the largest
// diagonal (Yarn's value), divided by the segment count, toward T_s, the strain solve's
// spring forces (Yarn's is toward 0): a uniform tension t is biased by (t - T_s) n lambda,
// and one the balance cannot see (a chain between pins) is T_s's mean.
//
// Local (Strings Eq. 12): T_j = k (|x'_{j+1} - x'_j| - |x_{j+1} - x_j|), k the reduced mass
// of the segment's ends over h^2 (a single free segment then agrees with the momentum
// solve). It sees only this step's stretch: a rope hanging at rest reads one particle's
// weight at its clamp and ~0 below; momentum balance sees the weight below every segment.
#include "base/lanes.hpp"
#include "base/thread_pool.hpp"
#include "linalg/tridiagonal.hpp"
#include "string/string_state.hpp"

#include <algorithm>

namespace tearables::detail {

namespace {

constexpr double kRegularisation = 1e-6;
/// A string of this many segments or more splits the tension's assembly and read-out over
/// the pool (StepContext::pool). The tridiagonal solve itself stays serial (a few ns a
/// segment).
constexpr std::size_t kParallelSegments = kParallelItems;

// The row helpers are forced inline (GCC kept rowImpulse a call; the same bits either way).

/// Weight of particle p's equation (1), or 0 when it gives none: clamped, or glued to an
/// immovable body; both carry an unknown support force.
[[gnu::always_inline]] inline double rowWeight(const StringState& s, std::size_t p) {
    const ParticleHold& hold = s.hold[p];
    if (hold.kind == ParticleHold::Kind::Pin) return 0.0;
    if (hold.kind == ParticleHold::Kind::Glue) return s.glue_movable[p] ? 1.0 : 0.0;
    return 1.0;
}

/// Whether particle p's projector is exactly I (no body presses it), entry by entry, where
/// any projector of the string may differ from I (rows_pressed).
[[gnu::always_inline]] inline bool wholeRow(const StringState& s, std::size_t p) {
    return !s.scratch.rows_pressed || s.scratch.row_projector[p] == Mat3::Identity();
}

/// u . (P_p v) for particle p's projector P_p, with `whole` = wholeRow(s, p): then P_p = I
/// and the product is u . v (I v is v exactly, up to the sign of a zero).
[[gnu::always_inline]] inline double projectedDot(const StringState& s, std::size_t p, bool whole, const Vec3& u, const Vec3& v) {
    return whole ? u.dot(v) : u.dot(s.scratch.row_projector[p] * v);
}

/// b_p: the impulse (x h, kg m) the segments gave particle p: its motion away from the
/// prediction. A particle a body presses has its equation projected across the body's
/// normal (row_projector), where the unknown contact force does not act.
[[gnu::always_inline]] inline Vec3 rowImpulse(const StringState& s, std::size_t p) {
    if (s.hold[p].kind == ParticleHold::Kind::Glue) return s.glue_impulse[p];
    return s.inertia_gain * s.mass[p] * (s.x[p] - s.x_pred[p]);
}

void momentumTension(StringState& s, const StepContext& ctx) {
    const std::size_t m = s.segments();
    // Each range of segments writes only its own entries, and the largest diagonal is the
    // largest of the ranges' (max is exact): the same bits on any number of threads.
    forRanges(ctx.pool, m, kParallelSegments, [&](std::size_t j0, std::size_t j1, std::size_t) {
        // Two segments at a time: their roots and divisions in lanes (unitPair).
        std::size_t j = j0;
        for (; j + 1 < j1; j += 2) {
            const UnitPair d = unitPair(s.x[j + 1] - s.x[j], s.x[j + 2] - s.x[j + 1]);
            if (d.length[0] > 1e-15) s.scratch.dir[j] = d.unit[0];
            if (d.length[1] > 1e-15) s.scratch.dir[j + 1] = d.unit[1];
        }
        if (j < j1) {
            const Vec3 d = s.x[j + 1] - s.x[j];
            const double len = d.norm();
            if (len > 1e-15) s.scratch.dir[j] = d / len;
        }
    });
    // Each particle's weight, whole row and impulse are found once and carried from the
    // segment it ends to the one it starts (the same bits as per segment).
    struct Row {
        double weight;
        bool whole;
        Vec3 impulse;  // only where weight > 0
    };
    auto row = [&s](std::size_t p) {
        Row r{rowWeight(s, p), wholeRow(s, p), Vec3::Zero()};
        if (r.weight > 0.0) r.impulse = rowImpulse(s, p);
        return r;
    };
    const double max_diag = forRangesMax(ctx.pool, m, kParallelSegments, [&](std::size_t j0, std::size_t j1) {
        double most = 0.0;
        Row a = row(j0);
        for (std::size_t j = j0; j < j1; ++j) {
            const Row b = row(j + 1);
            if (s.broken[j]) {
                s.scratch.diag[j] = 1.0;
                s.scratch.off[j] = 0.0;
                s.scratch.rhs[j] = 0.0;
                a = b;
                continue;
            }
            const Vec3& e = s.scratch.dir[j];
            s.scratch.diag[j] =
                a.weight * projectedDot(s, j, a.whole, e, e) + b.weight * projectedDot(s, j + 1, b.whole, e, e);
            s.scratch.rhs[j] = (a.weight > 0.0 ? a.weight * projectedDot(s, j, a.whole, e, a.impulse) : 0.0) -
                       (b.weight > 0.0 ? b.weight * projectedDot(s, j + 1, b.whole, e, b.impulse) : 0.0);
            s.scratch.off[j] = 0.0;
            if (j + 1 < m && !s.broken[j + 1])
                s.scratch.off[j] = -b.weight * projectedDot(s, j + 1, b.whole, e, s.scratch.dir[j + 1]);
            most = std::max(most, s.scratch.diag[j]);
            a = b;
        }
        return most;
    });
    // The regularisation pulls toward the converged solve's spring forces (x h^2, the
    // system's units), not toward zero: where the momentum balance leaves a tension
    // undetermined (a chain between two pins, or glued to bodies that do not move, carries
    // any uniform tension with the same motion), the stretch decides it, so a rope pulled
    // apart between its pins loads up and tears.
    const double reg = kRegularisation * (max_diag > 0.0 ? max_diag : 1.0) / static_cast<double>(m);
    const double h2 = ctx.h * ctx.h;
    forRanges(ctx.pool, m, kParallelSegments, [&](std::size_t j0, std::size_t j1, std::size_t) {
        for (std::size_t j = j0; j < j1; ++j)
            if (!s.broken[j]) {
                s.scratch.diag[j] += reg;
                s.scratch.rhs[j] += reg * s.spring_force[j] * h2;
            }
    });
    solveSymmetricTridiagonal(s.scratch.diag, s.scratch.off, s.scratch.rhs, s.scratch.segment_work);
    const double inv_h2 = ctx.inv_h * ctx.inv_h;
    // Where a body presses the string, its motion cannot tell tension from contact force:
    // there the tension is the spring force of the converged solve (the same quantity,
    // which the momentum balance recovers elsewhere more robustly).
    forRanges(ctx.pool, m, kParallelSegments, [&](std::size_t j0, std::size_t j1, std::size_t) {
        bool whole_a = wholeRow(s, j0);
        for (std::size_t j = j0; j < j1; ++j) {
            const bool whole_b = wholeRow(s, j + 1);
            s.tension[j] = s.broken[j] ? 0.0 : s.scratch.rhs[j] * inv_h2;
            if (!s.broken[j] && (!whole_a || !whole_b)) s.tension[j] = s.spring_force[j];
            whole_a = whole_b;
        }
    });
}

void localTension(StringState& s, const StepContext& ctx) {
    const std::size_t m = s.segments();
    const double inv_h2 = ctx.inv_h * ctx.inv_h;
    for (std::size_t j = 0; j < m; ++j) {
        if (s.broken[j]) {
            s.tension[j] = 0.0;
            continue;
        }
        const double wa = s.hold[j].kind == ParticleHold::Kind::Free ? s.inv_mass[j] : 0.0;
        const double wb = s.hold[j + 1].kind == ParticleHold::Kind::Free ? s.inv_mass[j + 1] : 0.0;
        const double w = wa + wb;
        const double k = w > 0.0 ? s.inertia_gain * inv_h2 / w : 0.0;
        const double stretch = (s.x_pred[j + 1] - s.x_pred[j]).norm() - (s.x[j + 1] - s.x[j]).norm();
        s.tension[j] = k * stretch;
    }
}

}  // namespace

void estimateTension(StringState& s, const StepContext& ctx) {
    if (s.desc.tension == TensionEstimator::Local)
        localTension(s, ctx);
    else
        momentumTension(s, ctx);
}

}  // namespace tearables::detail
