// Stage 5: strain limiting and rigid attachments, solved directly for the whole chain.
//
// Strings, Sec. 5.2 limits every segment to L <= L_max by sweeping position corrections
// from a clamped end (one end clamped), back and forth (both ends), or per piece between
// clamps (several points). Those sweeps move one particle at a time and need many passes
// when masses differ; a rope holding a body 1000x heavier than itself then stretches
// (this is why Bullet's anchored soft-body ropes do). We choose the exact mass-weighted
// projection instead, which covers all three cases at once:
//
//   For the active (stretched) segments j, with C_j = |x_{j+1} - x_j| - L_max_j and unit
//   direction e_j, find impulses mu_j >= 0 (kg m: force x h^2) such that moving every
//   particle p by  dx_p = K_p * sum_j a_pj mu_j  (a_pj = +e_j if p starts segment j,
//   -e_j if it ends it) removes C to first order:  (J K J^T) mu = C.
//
// J K J^T is tridiagonal for a chain (segment j shares one particle with j-1 and j+1),
// so one Newton iteration is an O(n) Thomas solve; 2-4 iterations reach the tolerance.
// Clamped particles (pins) have K = 0, which splits the system into independent pieces
// exactly as case 3 of the paper prescribes. A particle glued to a rigid body has the
// body's generalised inverse mass at the glue point, K = 1/M - [r]x I^-1 [r]x, so the
// rope holds the body with its real mass and inertia and the body pulls the rope; the
// body is moved by the same impulses (two-way). Strings that share a body are coupled
// by Gauss-Seidel sweeps over the strings in World::step.
#include "core/tridiagonal.hpp"
#include "string/string_state.hpp"

#include <cmath>

namespace tearables::detail {

namespace {

/// A segment shorter than L_max by less than this fraction counts as taut.
constexpr double kTautSlack = 1e-3;

Mat3 cross(const Vec3& r) {
    Mat3 m;
    m << 0.0, -r.z(), r.y(), r.z(), 0.0, -r.x(), -r.y(), r.x(), 0.0;
    return m;
}

/// Moves a body by a position-level impulse P (kg m) applied at lever arm r.
void applyBodyImpulse(RigidState& body, const Vec3& r, const Vec3& impulse) {
    body.position += body.inverse_mass * impulse;
    const Vec3 rotation = body.inverseInertiaWorld() * r.cross(impulse);
    const Quat dq(0.0, 0.5 * rotation.x(), 0.5 * rotation.y(), 0.5 * rotation.z());
    body.orientation.coeffs() += (dq * body.orientation).coeffs();
    body.orientation.normalize();
}

/// Inverse-mass operator of particle p: isotropic w, or a body's 3x3 K at the glue point.
struct Mobility {
    double w = 0.0;
    bool matrix = false;
    Mat3 K = Mat3::Zero();
    double along(const Vec3& a, const Vec3& b) const { return matrix ? a.dot(K * b) : w * a.dot(b); }
};

Mobility mobility(const StringState& s, const RigidTable& rigids, std::size_t p) {
    Mobility m;
    const ParticleHold& hold = s.hold[p];
    if (hold.kind == ParticleHold::Kind::Free) {
        m.w = s.inv_mass[p];
    } else if (hold.kind == ParticleHold::Kind::Glue && rigids.movable(hold.body)) {
        const RigidState& b = rigids.bodies[hold.body.index];
        const Mat3 rx = cross(s.x[p] - b.position);
        m.matrix = true;
        m.K = b.inverse_mass * Mat3::Identity() - rx * b.inverseInertiaWorld() * rx;
    }
    return m;
}

}  // namespace

void prepareStrainLimit(StringState& s, RigidTable& rigids, const StepContext& ctx) {
    const std::size_t n = s.particles();
    for (std::size_t p = 0; p < n; ++p) {
        s.glue_impulse[p].setZero();
        const ParticleHold& hold = s.hold[p];
        s.glue_movable[p] = hold.kind == ParticleHold::Kind::Glue && rigids.movable(hold.body);
        if (s.glue_movable[p]) {
            // The glued particle is part of the body now: its weight and force act on it.
            RigidState& b = rigids.bodies[hold.body.index];
            const Vec3 load = (s.mass[p] * ctx.gravity + s.force[p]) * (ctx.h * ctx.h);
            applyBodyImpulse(b, s.x[p] - b.position, load);
            s.x[p] = gluePoint(b, hold.point);
        }
    }
    s.x_pred = s.x;
    std::fill(s.impulse.begin(), s.impulse.end(), 0.0);
}

void limitStrain(StringState& s, RigidTable& rigids, const StepContext& ctx) {
    const std::size_t m = s.segments();
    const std::size_t n = s.particles();
    const double tol = ctx.settings->strain_tolerance;
    for (int iter = 0; iter < ctx.settings->strain_iterations; ++iter) {
        // Glued particles sit on their (possibly just moved) bodies.
        for (std::size_t p = 0; p < n; ++p) {
            const ParticleHold& hold = s.hold[p];
            if (hold.kind == ParticleHold::Kind::Glue) s.x[p] = gluePoint(rigids.bodies[hold.body.index], hold.point);
        }
        // Geometry and the active set: segments stretched past L_max.
        bool any = false;
        for (std::size_t j = 0; j < m; ++j) {
            s.active[j] = 0;
            s.violation[j] = 0.0;
            if (s.broken[j]) continue;
            const Vec3 d = s.x[j + 1] - s.x[j];
            const double len = d.norm();
            if (len > 1e-15) s.dir[j] = d / len;
            const double c = len - s.max_length[j];
            s.violation[j] = c;
            // Taut segments join the system too (a correction of their neighbours would
            // stretch them); those that would have to push drop out in the passes below.
            if (c > -kTautSlack * s.max_length[j]) s.active[j] = 1;
            if (c > tol * s.max_length[j]) any = true;
        }
        if (!any) break;

        auto w_of = [&](std::size_t p, const Vec3& a, const Vec3& b) -> double {
            const ParticleHold::Kind kind = s.hold[p].kind;
            if (kind == ParticleHold::Kind::Free) return s.inv_mass[p] * a.dot(b);
            if (kind == ParticleHold::Kind::Pin) return 0.0;
            return mobility(s, rigids, p).along(a, b);
        };

        // Up to three passes: a segment that would need to push (mu < 0) is slack and
        // leaves the active set (a rope resists stretching only).
        for (int pass = 0; pass < 3; ++pass) {
            for (std::size_t j = 0; j < m; ++j) {
                if (!s.active[j]) {
                    s.diag[j] = 1.0;
                    s.off[j] = 0.0;
                    s.rhs[j] = 0.0;
                    continue;
                }
                const Vec3& e = s.dir[j];
                const double d = w_of(j, e, e) + w_of(j + 1, e, e);
                if (!(d > 0.0)) {  // both ends immovable: nothing can be done
                    s.active[j] = 0;
                    s.diag[j] = 1.0;
                    s.off[j] = 0.0;
                    s.rhs[j] = 0.0;
                    continue;
                }
                s.diag[j] = d;
                s.rhs[j] = s.violation[j];
                s.off[j] = (j + 1 < m && s.active[j + 1]) ? -w_of(j + 1, e, s.dir[j + 1]) : 0.0;
            }
            for (std::size_t j = 0; j + 1 < m; ++j)
                if (!s.active[j + 1]) s.off[j] = 0.0;
            solveSymmetricTridiagonal(s.diag, s.off, s.rhs, s.scratch);
            bool slack = false;
            for (std::size_t j = 0; j < m; ++j)
                if (s.active[j] && s.rhs[j] < 0.0) {
                    s.active[j] = 0;
                    slack = true;
                }
            if (!slack) break;
        }

        // Apply dx_p = K_p sum_j a_pj mu_j.
        for (std::size_t p = 0; p < n; ++p) {
            Vec3 pull = Vec3::Zero();
            if (p > 0 && s.active[p - 1]) pull -= s.rhs[p - 1] * s.dir[p - 1];
            if (p < m && s.active[p]) pull += s.rhs[p] * s.dir[p];
            if (pull.isZero(0.0)) continue;
            const ParticleHold& hold = s.hold[p];
            if (hold.kind == ParticleHold::Kind::Free) {
                s.x[p] += s.inv_mass[p] * pull;
            } else if (hold.kind == ParticleHold::Kind::Glue && rigids.movable(hold.body)) {
                RigidState& b = rigids.bodies[hold.body.index];
                s.glue_impulse[p] += pull;
                b.impulse += pull * ctx.inv_h;
                applyBodyImpulse(b, s.x[p] - b.position, pull);
            }
        }
        for (std::size_t j = 0; j < m; ++j)
            if (s.active[j]) s.impulse[j] += s.rhs[j];
    }
    // Leave glued particles on their bodies.
    for (std::size_t p = 0; p < n; ++p) {
        const ParticleHold& hold = s.hold[p];
        if (hold.kind == ParticleHold::Kind::Glue) s.x[p] = gluePoint(rigids.bodies[hold.body.index], hold.point);
    }
}

}  // namespace tearables::detail
