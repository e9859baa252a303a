// Stage 5: strain limiting and rigid attachments, solved directly for the whole chain.
//
// Strings, Sec. 5.2 limits every segment to L <= L_max by sweeping position corrections
// from a clamped end (one end clamped), back and forth (both ends), or per piece between
// clamps (several points). Those sweeps move one particle at a time and need many passes
// when masses differ; a rope holding a body 1000x heavier than itself then stretches
// (this is why Bullet's anchored soft-body ropes do). We choose an exact, mass-weighted
// projection instead, which covers all three cases at once:
//
//   x = argmin  sum_p m_p/(2h^2) |x_p - x'_p|^2  +  sum_j k_j/2 max(0, |x_{j+1}-x_j| - L_j)^2
//
// i.e. backward Euler on segments of the material's own stiffness k_j = E A / L_j (the
// compliance form of strain limiting: the limit L_max = L (1 + sigma/E) of Strings Sec.
// 5.4 is met implicitly in the solve instead of lagging a step behind the stress, which
// would make a loaded rope alternate between slack and caught). At fibre moduli this is
// inextensible to within sigma/E. Newton's method on it, with the geometric stiffness of
// each stretched segment, gives a symmetric block-tridiagonal system (3x3 blocks, a
// segment couples two neighbouring particles) solved directly in O(n); 2-4 iterations
// converge. Without the geometric term (plain Gauss-Newton / XPBD) a light rope under a
// heavy load converges so slowly that it stretches without bound.
//
// Clamped particles are fixed rows, which splits the system into independent pieces as
// case 3 of the paper prescribes. A particle glued to a rigid body carries the body's
// effective mass at the glue point, K^-1 with K = 1/M - [r]x I^-1 [r]x, so the rope holds
// the body with its real mass and inertia, and the body, moved by the same impulses,
// pulls the rope (two-way). Strings that share a body are coupled by Gauss-Seidel sweeps
// over the strings in World::step.
#include "core/tridiagonal.hpp"
#include "string/string_state.hpp"

#include <Eigen/Cholesky>

#include <algorithm>
#include <cmath>

namespace tearables::detail {

namespace {

/// A segment shorter than its rest length by less than this fraction counts as taut.
constexpr double kTautSlack = 1e-4;

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

/// True when particle p does not move in the solve (pinned, or glued to an immovable body).
bool fixedRow(const StringState& s, std::size_t p) {
    const ParticleHold& hold = s.hold[p];
    return hold.kind == ParticleHold::Kind::Pin || (hold.kind == ParticleHold::Kind::Glue && !s.glue_movable[p]);
}

/// Solves the symmetric block-tridiagonal system (3x3 blocks: blk_diag, blk_off) for
/// blk_rhs in place: block Thomas algorithm, O(n). The blocks are mass/h^2 plus spring
/// Hessians, symmetric positive definite, so no pivoting is needed.
void solveBlockTridiagonal(StringState& s) {
    const std::size_t n = s.particles();
    // Forward elimination: blk_diag[i] <- D'_i, blk_rhs[i] <- r'_i.
    for (std::size_t i = 1; i < n; ++i) {
        const Mat3& u = s.blk_off[i - 1];  // couples i-1 and i
        if (u.isZero(0.0)) continue;
        const Eigen::LLT<Mat3> prev(s.blk_diag[i - 1]);
        const Mat3 w = prev.solve(u);       // D'^-1 U
        s.blk_diag[i] -= u.transpose() * w;
        s.blk_rhs[i] -= w.transpose() * s.blk_rhs[i - 1];
    }
    // Back substitution.
    s.blk_rhs[n - 1] = Eigen::LLT<Mat3>(s.blk_diag[n - 1]).solve(s.blk_rhs[n - 1]);
    for (std::size_t i = n - 1; i-- > 0;)
        s.blk_rhs[i] = Eigen::LLT<Mat3>(s.blk_diag[i]).solve(s.blk_rhs[i] - s.blk_off[i] * s.blk_rhs[i + 1]);
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
    for (std::size_t j = 0; j < s.segments(); ++j)
        s.prev_stretch[j] = (s.x_prev[j + 1] - s.x_prev[j]).norm() - s.rest_length[j];
}

void limitStrain(StringState& s, RigidTable& rigids, const StepContext& ctx) {
    const std::size_t m = s.segments();
    const std::size_t n = s.particles();
    const double inv_h2 = ctx.inv_h * ctx.inv_h;
    const double tol = ctx.settings->strain_tolerance;

    for (int iter = 0; iter < ctx.settings->strain_iterations; ++iter) {
        // Inertia: free particles are pulled back toward their prediction x'; a glued
        // particle carries its body's effective mass K^-1 at the glue point and starts
        // each iteration on the body (which absorbed the earlier corrections).
        for (std::size_t p = 0; p < n; ++p) {
            const ParticleHold& hold = s.hold[p];
            s.blk_rhs[p].setZero();
            if (p < m) s.blk_off[p].setZero();
            switch (hold.kind) {
                case ParticleHold::Kind::Free:
                    s.blk_diag[p] = (s.mass[p] * inv_h2) * Mat3::Identity();
                    s.blk_rhs[p] = -(s.mass[p] * inv_h2) * (s.x[p] - s.x_pred[p]);
                    break;
                case ParticleHold::Kind::Glue:
                    s.x[p] = gluePoint(rigids.bodies[hold.body.index], hold.point);
                    if (s.glue_movable[p]) {
                        // The body's inertia resists this string's own accumulated pull
                        // (what other strings did to the body is, for this string, part
                        // of the body's prediction): M_eff (x - x') / h^2 = P / h^2.
                        s.blk_diag[p] = mobility(s, rigids, p).K.inverse() * inv_h2;
                        s.blk_rhs[p] = -s.glue_impulse[p] * inv_h2;
                        break;
                    }
                    [[fallthrough]];
                case ParticleHold::Kind::Pin:
                    s.blk_diag[p] = Mat3::Identity();  // fixed: its row is dx = 0
                    break;
            }
        }
        // Springs of the material's stiffness k = E A / L_rest on the stretched segments:
        // gradient k C e and Hessian k (e e^T + C/l (I - e e^T)) (the geometric term keeps
        // Newton convergent when a heavy load pulls light particles).
        double worst = 0.0;
        for (std::size_t j = 0; j < m; ++j) {
            s.active[j] = 0;
            if (s.broken[j]) continue;
            const Vec3 d = s.x[j + 1] - s.x[j];
            const double len = d.norm();
            if (len > 1e-15) s.dir[j] = d / len;
            const double stretch = len - s.rest_length[j];
            // Kelvin-Voigt: the segment's force is k (C + tau dC/dt), tau the material's
            // retardation time; it damps the rope's axial (bungee) vibration, which a
            // real fibre's internal friction kills within a few periods.
            const double rate_gain = s.desc.axial_damping * ctx.inv_h;
            const double effective = stretch + rate_gain * (stretch - s.prev_stretch[j]);
            // Slack segments carry nothing (a rope does not push). Taut ones (within
            // kTautSlack of rest) join with their stiffness but no force, so that one
            // Newton step sees the whole taut chain a correction would stretch; a
            // segment the step compresses leaves again at the next iteration.
            if (stretch <= -kTautSlack * s.rest_length[j] && effective <= 0.0) continue;
            const double c = std::max(effective, 0.0);
            s.active[j] = 1;
            const double k = 1.0 / s.compliance[j];
            const Vec3& e = s.dir[j];
            const Mat3 eet = e * e.transpose();
            const Mat3 hess = k * ((1.0 + rate_gain) * eet + (c / len) * (Mat3::Identity() - eet));
            const Vec3 force = k * c * e;  // pulls j toward j+1
            const bool fa = !fixedRow(s, j), fb = !fixedRow(s, j + 1);
            if (fa) {
                s.blk_diag[j] += hess;
                s.blk_rhs[j] += force;
            }
            if (fb) {
                s.blk_diag[j + 1] += hess;
                s.blk_rhs[j + 1] -= force;
            }
            if (fa && fb) s.blk_off[j] = -hess;
        }
        solveBlockTridiagonal(s);
        // Apply: free particles move, glued ones move their body by the impulse K^-1 dx.
        for (std::size_t p = 0; p < n; ++p) {
            if (fixedRow(s, p)) continue;
            const Vec3& dx = s.blk_rhs[p];
            if (!dx.allFinite()) continue;
            worst = std::max(worst, dx.norm());
            if (s.hold[p].kind == ParticleHold::Kind::Free) {
                s.x[p] += dx;
            } else {
                RigidState& b = rigids.bodies[s.hold[p].body.index];
                const Vec3 impulse = mobility(s, rigids, p).K.inverse() * dx;
                s.glue_impulse[p] += impulse;
                b.impulse += impulse * ctx.inv_h;
                applyBodyImpulse(b, s.x[p] - b.position, impulse);
            }
        }
        if (worst < tol * s.shortest_rest) break;
    }
    // Leave glued particles on their bodies.
    for (std::size_t p = 0; p < n; ++p) {
        const ParticleHold& hold = s.hold[p];
        if (hold.kind == ParticleHold::Kind::Glue) s.x[p] = gluePoint(rigids.bodies[hold.body.index], hold.point);
    }
}

}  // namespace tearables::detail
