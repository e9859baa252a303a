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
/// Contact penalty over the stiffest spring, particle and body inertia it competes with.
constexpr double kContactStiffnessFactor = 100.0;
/// Active-set passes of the contact solve, and the iteration budget of a pass with
/// contacts relative to WorldSettings::strain_iterations.
constexpr int kContactPasses = 4;
constexpr int kContactIterationFactor = 4;
/// A segment within this fraction of its radius of a body counts as touching it.
constexpr double kContactSlop = 0.1;

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

/// Where a contact's surface point is now: on its body (following it), or a fixed point
/// (another string's segment, for string-string contacts).
Vec3 contactPoint(const SegmentContact& c, const RigidTable& rigids) {
    return c.body.valid() ? gluePoint(rigids.bodies[c.body.index], c.local) : c.local;
}

/// The contact's gap function: >= 0 when the string is clear of the surface.
double contactGap(const StringState& s, const SegmentContact& c, const Vec3& xs, const Vec3& p) {
    (void)s;
    return c.normal.dot(xs - p) - c.gap;
}

/// True when particle p does not move in the solve (pinned, or glued to an immovable body).
bool fixedRow(const StringState& s, std::size_t p) {
    const ParticleHold& hold = s.hold[p];
    return hold.kind == ParticleHold::Kind::Pin || (hold.kind == ParticleHold::Kind::Glue && !s.glue_movable[p]);
}

/// Factorises the symmetric block-tridiagonal system (3x3 blocks blk_diag, blk_off):
/// block Thomas algorithm, O(n). The blocks are mass/h^2 plus spring and contact
/// Hessians, symmetric positive definite, so no pivoting is needed.
void factorBlockTridiagonal(StringState& s) {
    const std::size_t n = s.particles();
    s.blk_factor[0].compute(s.blk_diag[0]);
    for (std::size_t i = 1; i < n; ++i) {
        const Mat3& u = s.blk_off[i - 1];  // couples i-1 and i
        Mat3 d = s.blk_diag[i];
        if (u.isZero(0.0)) {
            s.blk_factor_gain[i].setZero();
        } else {
            const Mat3 w = s.blk_factor[i - 1].solve(u);  // D'^-1 U
            d -= u.transpose() * w;
            s.blk_factor_gain[i] = w.transpose();
        }
        s.blk_factor[i].compute(d);
    }
}

/// Solves the factorised system for `rhs` in place.
void solveFactored(const StringState& s, std::vector<Vec3>& rhs) {
    const std::size_t n = s.particles();
    for (std::size_t i = 1; i < n; ++i)
        if (!s.blk_factor_gain[i].isZero(0.0)) rhs[i] -= s.blk_factor_gain[i] * rhs[i - 1];
    rhs[n - 1] = s.blk_factor[n - 1].solve(rhs[n - 1]);
    for (std::size_t i = n - 1; i-- > 0;) rhs[i] = s.blk_factor[i].solve(rhs[i] - s.blk_off[i] * rhs[i + 1]);
}

using Vec6 = Eigen::Matrix<double, 6, 1>;
using Mat6 = Eigen::Matrix<double, 6, 6>;
using Mat36 = Eigen::Matrix<double, 3, 6>;

/// Generalised mass of a body (translation, rotation about its centre), world frame.
Mat6 bodyMass(const RigidState& b) {
    Mat6 m = Mat6::Zero();
    m.topLeftCorner<3, 3>() = Mat3::Identity() / b.inverse_mass;
    m.bottomRightCorner<3, 3>() = b.inverseInertiaWorld().inverse();
    return m;
}

/// Moves a body by a generalised displacement (translation, rotation vector).
void displaceBody(RigidState& b, const Vec6& u) {
    b.position += u.head<3>();
    const Vec3 rotation = u.tail<3>();
    const double angle = rotation.norm();
    if (angle > 0.0) b.orientation = (Quat(Eigen::AngleAxisd(angle, rotation / angle)) * b.orientation).normalized();
}

/// The energy the Newton iteration minimises, at the current state moved by alpha times
/// the step held in blk_rhs (particles) and node_step (bodies): inertia of particles,
/// glued bodies and touched bodies, the material's springs and the contact penalties.
double stepEnergy(const StringState& s, const RigidTable& rigids, const StepContext& ctx, double alpha) {
    const std::size_t n = s.particles();
    const std::size_t m = s.segments();
    const double inv_h2 = ctx.inv_h * ctx.inv_h;
    double e = 0.0;
    auto trial = [&](std::size_t p) -> Vec3 { return fixedRow(s, p) ? s.x[p] : Vec3(s.x[p] + alpha * s.blk_rhs[p]); };
    for (std::size_t p = 0; p < n; ++p) {
        if (fixedRow(s, p)) continue;
        if (s.hold[p].kind == ParticleHold::Kind::Free) {
            e += 0.5 * s.mass[p] * inv_h2 * (trial(p) - s.x_pred[p]).squaredNorm();
        } else {  // glued to a movable body: its displacement this step is K P
            const Mat3 k = mobility(s, rigids, p).K;
            const Vec3 u = k * s.glue_impulse[p] + alpha * s.blk_rhs[p];
            e += 0.5 * inv_h2 * u.dot(k.ldlt().solve(u));
        }
    }
    for (std::size_t b = 0; b < s.body_nodes.size(); ++b) {
        const RigidState& body = rigids.bodies[s.body_nodes[b].body.index];
        const Mat6 mass = bodyMass(body);
        const Vec6 u = mass.ldlt().solve(s.body_nodes[b].impulse) + alpha * s.node_step[b];
        e += 0.5 * inv_h2 * u.dot(mass * u);
    }
    const double rate_gain = s.desc.axial_damping * ctx.inv_h;
    for (std::size_t j = 0; j < m; ++j) {
        if (s.broken[j]) continue;
        const double stretch = (trial(j + 1) - trial(j)).norm() - s.rest_length[j];
        const double effective = std::max(0.0, stretch + rate_gain * (stretch - s.prev_stretch[j]));
        e += 0.5 / (s.compliance[j] * (1.0 + rate_gain)) * effective * effective;
    }
    for (const SegmentContact& c : s.contacts) {
        const std::size_t j = c.segment;
        if (s.broken[j] || c.stiffness <= 0.0) continue;
        Vec3 p = contactPoint(c, rigids);
        if (c.node >= 0) {
            const RigidState& body = rigids.bodies[c.body.index];
            const Vec6& u = s.node_step[static_cast<std::size_t>(c.node)];
            p += alpha * (u.head<3>() + u.tail<3>().cross(p - body.position));
        }
        if (!c.active) continue;
        const Vec3 xs = (1.0 - c.s) * trial(j) + c.s * trial(j + 1);
        const double g = contactGap(s, c, xs, p);
        e += 0.5 * c.stiffness * g * g;
    }
    return e;
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
    const std::size_t nodes = s.body_nodes.size();

    // Body unknowns (contacts with movable bodies), reused across iterations.
    std::vector<Mat6> node_diag(nodes);
    std::vector<Vec6> node_rhs(nodes);
    std::vector<std::vector<std::pair<std::size_t, Mat36>>> coupling(nodes);

    // Contacts start active where the prediction touches or nearly touches the body.
    for (SegmentContact& c : s.contacts) {
        const std::size_t j = c.segment;
        const Vec3 xs = (1.0 - c.s) * s.x[j] + c.s * s.x[j + 1];
        c.active = !s.broken[j] && contactGap(s, c, xs, contactPoint(c, rigids)) < 0.0;
    }
    const int passes = s.contacts.empty() ? 1 : kContactPasses;
    // Impacts are strongly nonlinear (a rope deflected by centimetres in one step): with
    // contacts a pass may take more iterations before its active set is judged.
    const int iterations = ctx.settings->strain_iterations * (s.contacts.empty() ? 1 : kContactIterationFactor);
    for (int pass = 0; pass < passes; ++pass) {
    bool converged = false;
    for (int iter = 0; iter < iterations; ++iter) {
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
            s.spring_force[j] = 0.0;
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
            s.spring_force[j] = k * c;
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

        // Contacts with rigid bodies: g = n . (x(s) - p) - r >= 0, a stiff penalty
        // k_c g^2 / 2 while penetrating, with x(s) = (1-s) x_j + s x_{j+1} and p the
        // contact point on the body. A movable body takes part with its 6 unknowns and
        // its mass and inertia (below), so a rope catches a crate with its tension.
        for (std::size_t b = 0; b < nodes; ++b) {
            const RigidState& body = rigids.bodies[s.body_nodes[b].body.index];
            node_diag[b] = bodyMass(body) * inv_h2;
            node_rhs[b] = -s.body_nodes[b].impulse * inv_h2;
            coupling[b].clear();
        }
        double heaviest = 0.0;
        for (double mass : s.mass) heaviest = std::max(heaviest, mass);
        for (SegmentContact& c : s.contacts) {
            const std::size_t j = c.segment;
            if (s.broken[j]) continue;
            const Vec3 p = contactPoint(c, rigids);
            const Vec3 xs = (1.0 - c.s) * s.x[j] + c.s * s.x[j + 1];
            // Active contacts are held as equalities during a pass (smooth, so Newton
            // converges fast); the passes below release those that pull and add those
            // that penetrate (a primal active-set method).
            if (!c.active) continue;
            const double g = contactGap(s, c, xs, p);
            // Stiff enough to dominate the rope's springs, the particles' and the body's
            // inertia: under a load F it gives way by F / k_c only. Fixed for the step, so
            // that the line search below sees one energy.
            if (c.stiffness <= 0.0) {
                double kc = std::max({1.0 / *std::min_element(s.compliance.begin(), s.compliance.end()), heaviest * inv_h2, 1e-12});
                if (c.node >= 0) kc = std::max(kc, inv_h2 / rigids.bodies[c.body.index].inverse_mass);
                c.stiffness = kc * kContactStiffnessFactor;
            }
            const double kc = c.stiffness;
            const Vec3& nrm = c.normal;
            const Mat3 nnt = nrm * nrm.transpose();
            const double wa = 1.0 - c.s, wb = c.s;
            const bool fa = !fixedRow(s, j), fb = !fixedRow(s, j + 1);
            if (fa) {
                s.blk_diag[j] += kc * wa * wa * nnt;
                s.blk_rhs[j] -= kc * g * wa * nrm;
            }
            if (fb) {
                s.blk_diag[j + 1] += kc * wb * wb * nnt;
                s.blk_rhs[j + 1] -= kc * g * wb * nrm;
            }
            if (fa && fb) s.blk_off[j] += kc * wa * wb * nnt;
            if (c.node < 0) continue;
            const std::size_t b = static_cast<std::size_t>(c.node);
            const RigidState& body = rigids.bodies[c.body.index];
            Vec6 au;
            au.head<3>() = -nrm;
            au.tail<3>() = -(p - body.position).cross(nrm);
            node_diag[b] += kc * au * au.transpose();
            node_rhs[b] -= kc * g * au;
            if (fa) coupling[b].emplace_back(j, kc * wa * nrm * au.transpose());
            if (fb) coupling[b].emplace_back(j + 1, kc * wb * nrm * au.transpose());
        }

        factorBlockTridiagonal(s);
        solveFactored(s, s.blk_rhs);  // y = A^-1 r
        for (std::size_t b = 0; b < nodes; ++b) s.node_step[b].setZero();
        if (nodes > 0) {
            // Schur complement on the bodies' unknowns: (D - C^T A^-1 C) du = r_b - C^T y,
            // then dx = y - A^-1 C du. Each body costs six more O(n) solves.
            const std::size_t dim = 6 * nodes;
            Eigen::MatrixXd schur = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(dim), static_cast<Eigen::Index>(dim));
            Eigen::VectorXd rs(static_cast<Eigen::Index>(dim));
            s.node_columns.resize(dim);
            for (std::size_t b = 0; b < nodes; ++b) {
                schur.block<6, 6>(static_cast<Eigen::Index>(6 * b), static_cast<Eigen::Index>(6 * b)) = node_diag[b];
                rs.segment<6>(static_cast<Eigen::Index>(6 * b)) = node_rhs[b];
                for (const auto& [p, blk] : coupling[b]) rs.segment<6>(static_cast<Eigen::Index>(6 * b)) -= blk.transpose() * s.blk_rhs[p];
                for (int col = 0; col < 6; ++col) {
                    std::vector<Vec3>& column = s.node_columns[6 * b + static_cast<std::size_t>(col)];
                    column.assign(n, Vec3::Zero());
                    for (const auto& [p, blk] : coupling[b]) column[p] += blk.col(col);
                    solveFactored(s, column);
                }
            }
            for (std::size_t b = 0; b < nodes; ++b)
                for (std::size_t c = 0; c < dim; ++c)
                    for (const auto& [p, blk] : coupling[b])
                        schur.block<6, 1>(static_cast<Eigen::Index>(6 * b), static_cast<Eigen::Index>(c)) -=
                            blk.transpose() * s.node_columns[c][p];
            const Eigen::VectorXd du = schur.ldlt().solve(rs);
            for (std::size_t c = 0; c < dim; ++c) {
                const double f = du[static_cast<Eigen::Index>(c)];
                if (f != 0.0)
                    for (std::size_t p = 0; p < n; ++p) s.blk_rhs[p] -= f * s.node_columns[c][p];
            }
            for (std::size_t b = 0; b < nodes; ++b) s.node_step[b] = du.segment<6>(static_cast<Eigen::Index>(6 * b));
        }
        // With contacts the energy is only C^1 (penalties switch on and off), and a full
        // Newton step can overshoot: backtrack until the (convex) energy decreases.
        double alpha = 1.0;
        if (!s.contacts.empty()) {
            const double e0 = stepEnergy(s, rigids, ctx, 0.0);
            for (int halving = 0; halving < 10 && stepEnergy(s, rigids, ctx, alpha) > e0; ++halving) alpha *= 0.5;
        }
        if (alpha != 1.0)
            for (std::size_t p = 0; p < n; ++p) s.blk_rhs[p] *= alpha;
        for (std::size_t b = 0; b < nodes; ++b) {
            const Vec6 u = alpha * s.node_step[b];
            if (!u.allFinite()) continue;
            RigidState& body = rigids.bodies[s.body_nodes[b].body.index];
            const Vec6 impulse = bodyMass(body) * u;
            s.body_nodes[b].impulse += impulse;
            body.impulse += impulse.head<3>() * ctx.inv_h;
            displaceBody(body, u);
            worst = std::max(worst, u.head<3>().norm());
        }
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
        if (worst < tol * s.shortest_rest) {
            converged = true;
            break;
        }
    }
    // Release contacts that pull (the body would have to hold the string), engage those
    // the solve pushed into the body; solve again if the set changed. An unconverged
    // state says nothing reliable about pulling, so contacts are only released after
    // convergence.
    bool changed = false;
    for (SegmentContact& c : s.contacts) {
        const std::size_t j = c.segment;
        if (s.broken[j]) continue;
        const Vec3 xs = (1.0 - c.s) * s.x[j] + c.s * s.x[j + 1];
        const double g = contactGap(s, c, xs, contactPoint(c, rigids));
        if (c.active && converged && g > kContactSlop * s.radius[j] * 1e-3) {
            c.active = false;
            changed = true;
        } else if (!c.active && g < 0.0) {
            c.active = true;
            changed = true;
        }
    }
    if (!changed) break;
    }
    // Leave glued particles on their bodies.
    for (std::size_t p = 0; p < n; ++p) {
        const ParticleHold& hold = s.hold[p];
        if (hold.kind == ParticleHold::Kind::Glue) s.x[p] = gluePoint(rigids.bodies[hold.body.index], hold.point);
    }
    // The springs' forces in the final state (the tension where bodies press the string).
    const double rate_gain = s.desc.axial_damping * ctx.inv_h;
    for (std::size_t j = 0; j < m; ++j) {
        if (s.broken[j]) continue;
        const double stretch = (s.x[j + 1] - s.x[j]).norm() - s.rest_length[j];
        s.spring_force[j] = std::max(0.0, stretch + rate_gain * (stretch - s.prev_stretch[j])) / s.compliance[j];
    }
    // Particles pressed by a body carry an unknown contact force along its normal: the
    // tension solve uses only their equations across the normal (tension.cpp).
    for (std::size_t p = 0; p < n; ++p) s.row_projector[p].setIdentity();
    for (const SegmentContact& c : s.contacts) {
        const std::size_t j = c.segment;
        if (s.broken[j]) continue;
        const Vec3 xs = (1.0 - c.s) * s.x[j] + c.s * s.x[j + 1];
        if (contactGap(s, c, xs, contactPoint(c, rigids)) > kContactSlop * s.radius[j]) continue;  // not touching
        for (std::size_t q : {j, j + 1}) {
            const Vec3 dir = s.row_projector[q] * c.normal;  // what is left of this normal
            const double len = dir.norm();
            if (len > 1e-6) s.row_projector[q] -= (dir / len) * (dir / len).transpose();
        }
    }
}

void applyFriction(StringState& s, RigidTable& rigids, const StepContext& ctx) {
    // Coulomb friction as a position correction (PBD style): the contact point's
    // tangential motion relative to the body this step is undone up to mu times the
    // normal impulse the solve applied there (k_c |g| h^2: it includes the pressure of
    // the string's tension around an edge, not only its weight); the body gets the
    // opposite impulse.
    const double h2 = ctx.h * ctx.h;
    for (const SegmentContact& c : s.contacts) {
        const std::size_t j = c.segment;
        if (s.broken[j] || c.friction <= 0.0 || c.stiffness <= 0.0) continue;
        const Vec3 p = contactPoint(c, rigids);
        const Vec3 xs = (1.0 - c.s) * s.x[j] + c.s * s.x[j + 1];
        const double g = contactGap(s, c, xs, p);
        const double normal_impulse = c.stiffness * std::max(0.0, -g) * h2;
        const double wa = 1.0 - c.s, wb = c.s;
        const double inv_a = s.hold[j].kind == ParticleHold::Kind::Free ? s.inv_mass[j] : 0.0;
        const double inv_b = s.hold[j + 1].kind == ParticleHold::Kind::Free ? s.inv_mass[j + 1] : 0.0;
        const double w_point = wa * wa * inv_a + wb * wb * inv_b;  // inverse mass at the contact point
        if (!(w_point > 0.0) || normal_impulse <= 0.0) continue;
        const Vec3 p0 = c.body.valid() ? Vec3(rigids.start_position[c.body.index] + rigids.start_orientation[c.body.index] * c.local) : p;
        const Vec3 xs0 = (1.0 - c.s) * s.x_prev[j] + c.s * s.x_prev[j + 1];
        Vec3 rel = (xs - xs0) - (p - p0);
        rel -= c.normal * c.normal.dot(rel);
        const double slip = rel.norm();
        if (slip <= 0.0) continue;
        const Vec3 corr = -rel * std::min(1.0, c.friction * normal_impulse * w_point / slip);
        // Move the two ends so that the contact point moves by corr, by inverse mass.
        const Vec3 impulse = corr / w_point;
        s.x[j] += wa * inv_a * impulse;
        s.x[j + 1] += wb * inv_b * impulse;
        if (c.node >= 0 && rigids.movable(c.body)) {
            RigidState& body = rigids.bodies[c.body.index];
            applyBodyImpulse(body, p - body.position, -impulse);
        }
    }
}

}  // namespace tearables::detail
