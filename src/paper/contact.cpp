// Paper sheets: contacts of the vertices with rigid bodies, and the position update with
// pins and glue. Each vertex is a sphere of half the sheet's thickness; the host reports a
// contact point on the body at the end of its step, the normal toward the vertex. The
// contact is speculative with Coulomb friction (resolvePoint); the body receives the
// opposite impulse through its centre of mass (releaseBodies), momentum conserved.
// A light vertex cannot stop a heavy body in one step: the body is held over the next
// steps, as the implicit solve turns the vertex's displacement into spring force and the
// vertex passes it on through the contact (a light box comes to rest on a sheet; a sphere
// pushed by its host presses the sheet and is hardly slowed).
#include "paper/sheet.hpp"
#include "sim/rigid_table.hpp"

#include <algorithm>
#include <cmath>

namespace tearables::detail {

namespace {

/// Passes over the contacts: a vertex touching a body at two points, or two bodies,
/// settles in a few.
constexpr int kContactPasses = 3;

void pushBody(RigidState& body, const Vec3& arm, const Vec3& impulse) {
    body.linear_velocity += body.inverse_mass * impulse;
    body.angular_velocity += body.inverseInertiaWorld() * arm.cross(impulse);
    body.impulse += impulse;
}

/// One contact at the point p = sum_k w_k x_k of the sheet: a vertex (one corner, weight
/// 1) or a point inside a triangle (its three corners, barycentric weights). The vertex
/// may approach the body by no more than its gap, n . v_p >= -gap / h, on the point's
/// velocity v_p = sum_k w_k v_k. The change dv of v_p that enforces it (with Coulomb
/// friction on the slip relative to the body's surface: at most mu times the normal
/// change) is shared by the corners in proportion to w_k / m_k, with the point's
/// effective mass 1 / sum_k w_k^2 / m_k (a pinned or glued corner takes no share, as if
/// infinitely heavy); for a vertex that is dv itself. The body gets the opposite impulse,
/// through its centre of mass (see releaseBodies).
void resolvePoint(PaperSheet& s, const PointContact& c, RigidTable& rigids, const PaperStep& ctx, double radius) {
    const std::uint32_t vertex[1] = {c.vertex};
    const double unit[1] = {1.0};
    const bool face = c.onFace();
    const std::uint32_t* corner = face ? c.face.data() : vertex;
    const double* weight = face ? c.weights.data() : unit;
    const int corners = face ? 3 : 1;
    double w2m = 0.0;  // sum w_k^2 / m_k over the corners that can move
    Vec3 x = Vec3::Zero(), v = Vec3::Zero();
    for (int k = 0; k < corners; ++k) {
        const std::uint32_t i = corner[k];
        if (i >= s.vertices()) return;
        x += weight[k] * s.x[i];
        v += weight[k] * s.v[i];
        if (!s.fixed[i]) w2m += weight[k] * weight[k] / s.mass[i];
    }
    if (!(w2m > 0.0)) return;
    RigidState& body = rigids.bodies[c.body.index];
    // The host found the point where the body was when the step began; the strings and
    // releaseBodies may have moved the body since (translation).
    const Vec3 point = c.point + (body.position - rigids.start_position[c.body.index]);
    const Vec3& n = c.normal;
    const double gap = n.dot(x - point) - radius;
    const double target = -gap * ctx.inv_h;
    const double vn = n.dot(v);
    if (vn >= target) return;
    const double dvn = target - vn;
    Vec3 dv = dvn * n;  // wanted change of the point's velocity
    const Vec3 body_v = body.linear_velocity + body.angular_velocity.cross(point - body.position);
    Vec3 rel = v + dv - body_v;
    rel -= n * n.dot(rel);
    const double slip = rel.norm();
    const double mu = std::max(s.desc.friction, c.friction);
    if (slip > 0.0) dv -= rel * std::min(1.0, mu * dvn / slip);
    Vec3 impulse = Vec3::Zero();  // on the sheet
    for (int k = 0; k < corners; ++k) {
        const std::uint32_t i = corner[k];
        if (s.fixed[i]) continue;
        const Vec3 change = dv * ((weight[k] / s.mass[i]) / w2m);
        s.v[i] += change;
        impulse += s.mass[i] * change;
    }
    if (rigids.movable(c.body)) pushBody(body, Vec3::Zero(), -impulse);
}

}  // namespace

void resolveContacts(PaperSheet& s, const std::vector<PointContact>& contacts, RigidTable& rigids, const PaperStep& ctx) {
    if (contacts.empty()) return;
    const double radius = 0.5 * s.desc.thickness;
    for (int pass = 0; pass < kContactPasses; ++pass)
        for (const PointContact& c : contacts) resolvePoint(s, c, rigids, ctx, radius);
}

namespace {

/// The contact's body is movable and the vertex will close the gap this step (with
/// gravity's pull and a quarter radius of slack).
bool closing(const PaperSheet& s, const PointContact& c, const RigidTable& rigids, const PaperStep& ctx) {
    // Face contacts lend no mass: they act at velocity level only (resolveContacts).
    if (c.onFace() || c.vertex >= s.vertices() || !rigids.movable(c.body)) return false;
    if (s.hold[c.vertex].kind != ParticleHold::Kind::Free) return false;
    const RigidState& body = rigids.bodies[c.body.index];
    const Vec3 body_v = body.linear_velocity + body.angular_velocity.cross(c.point - body.position);
    const double radius = 0.5 * s.desc.thickness;
    const double gap = c.normal.dot(s.x[c.vertex] - c.point) - radius;
    const double approach = c.normal.dot(s.v[c.vertex] + ctx.h * ctx.gravity - body_v);
    return gap + ctx.h * approach < 0.25 * radius;
}

}  // namespace

void countCouplings(const PaperSheet& s, const std::vector<PointContact>& contacts, const RigidTable& rigids,
                    const PaperStep& ctx, std::vector<double>& count) {
    count.resize(rigids.bodies.size(), 0.0);
    for (std::size_t i = 0; i < s.vertices(); ++i)
        if (s.hold[i].kind == ParticleHold::Kind::Glue && rigids.movable(s.hold[i].body)) count[s.hold[i].body.index] += 1.0;
    for (const PointContact& c : contacts)
        if (closing(s, c, rigids, ctx)) count[c.body.index] += 1.0;
}

void coupleBodies(PaperSheet& s, const std::vector<PointContact>& contacts, const std::vector<double>& count_of,
                  const RigidTable& rigids, const PaperStep& ctx, std::vector<BodyCoupling>& out) {
    out.clear();
    assignGrowing(s.added_mass, s.vertices(), Mat3::Zero());
    assignGrowing(s.added_force, s.vertices(), Vec3::Zero());
    for (std::size_t i = 0; i < s.vertices(); ++i) {
        const ParticleHold& hold = s.hold[i];
        if (hold.kind != ParticleHold::Kind::Glue || !rigids.movable(hold.body)) continue;
        const RigidState& body = rigids.bodies[hold.body.index];
        BodyCoupling c;
        c.vertex = static_cast<std::uint32_t>(i);
        c.body = hold.body;
        c.arm = gluePoint(body, hold.point) - body.position;
        c.body_velocity = body.linear_velocity + body.angular_velocity.cross(c.arm);
        // The body's mass as seen at the glue point, K^-1 with K = 1/M - [r] I^-1 [r]
        // (rotation included), shared among the vertices it couples to.
        c.lent = Mat3::Identity() / (body.inverse_mass * count_of[hold.body.index]);
        // The glued vertex starts where the body point was before the host's step (the
        // host has moved the body already) and as it went before the host's gravity kick:
        // the lent mass's weight goes into the solve instead (added_force), so the sheet
        // carries it implicitly, not as a velocity jump of the vertex against its
        // neighbours (which their damping and the truncated Jacobi solve resist).
        s.x[i] = gluePoint(body, hold.point) - ctx.h * c.body_velocity;  // where it was before the host's step
        s.v[i] = c.body_velocity - ctx.h * ctx.gravity;
        s.added_mass[i] += c.lent;
        s.added_force[i] += c.lent * ctx.gravity;
        out.push_back(c);
    }
    for (const PointContact& pc : contacts) {
        if (!closing(s, pc, rigids, ctx)) continue;
        const RigidState& body = rigids.bodies[pc.body.index];
        BodyCoupling c;
        c.vertex = pc.vertex;
        c.body = pc.body;
        c.arm = pc.point - body.position;
        c.body_velocity = body.linear_velocity + body.angular_velocity.cross(c.arm);
        // The body's mass along the normal at the contact point (rotation included),
        // shared among the vertices it couples to.
        const Vec3& n = pc.normal;
        const double share = 1.0 / (body.inverse_mass * count_of[pc.body.index]);
        c.lent = share * (n * n.transpose());
        // Inelastic along the normal: vertex and share start with their common velocity
        // (the body's before the host's gravity kick, whose weight goes into the solve,
        // as for glue).
        const double m = s.mass[c.vertex];
        const double common = (m * n.dot(s.v[c.vertex]) + share * n.dot(c.body_velocity - ctx.h * ctx.gravity)) / (m + share);
        s.v[c.vertex] += (common - n.dot(s.v[c.vertex])) * n;
        c.normal = n;
        s.added_mass[c.vertex] += c.lent;
        s.added_force[c.vertex] += c.lent * ctx.gravity;
        out.push_back(c);
    }
}

void releaseBodies(const PaperSheet& s, const std::vector<BodyCoupling>& couplings, RigidTable& rigids, const PaperStep& ctx) {
    for (const BodyCoupling& c : couplings) {
        RigidState& body = rigids.bodies[c.body.index];
        // What the share gained in the solve, from the velocity the body point had.
        Vec3 impulse = c.lent * (s.v[c.vertex] - c.body_velocity);
        // A contact pushes the body away from the vertex (along -n), never pulls it.
        if (c.normal.squaredNorm() > 0.0 && impulse.dot(c.normal) > 0.0) impulse.setZero();
        // Position-based, as the strings couple: the body is moved by what its share
        // moved differently from the host's step, h dv; the world turns that move into
        // the velocity change dv when the step ends (an impulse alone would leave the
        // host's fall of g h^2 per step uncorrected). Translation only: the impulse goes
        // through the centre of mass, since the torques of many vertex contacts, each
        // solved as if alone, overshoot. A limitation: the sheet does not turn a body.
        body.position += body.inverse_mass * ctx.h * impulse;
        body.impulse += impulse;
    }
}

void integratePositions(PaperSheet& s, RigidTable& rigids, const PaperStep& ctx) {
    for (std::size_t i = 0; i < s.vertices(); ++i) {
        const ParticleHold& hold = s.hold[i];
        if (hold.kind == ParticleHold::Kind::Pin) {
            s.x[i] = hold.point;
        } else if (hold.kind == ParticleHold::Kind::Glue) {
            RigidState& body = rigids.bodies[hold.body.index];
            if (rigids.movable(hold.body)) {
                s.x[i] += ctx.h * s.v[i];  // solved with the body's share; the body follows (releaseBodies)
            } else {
                s.x[i] = gluePoint(body, hold.point);
            }
        } else {
            s.x[i] += ctx.h * s.v[i];
        }
    }
}

}  // namespace tearables::detail
