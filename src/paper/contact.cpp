// Paper sheets: contacts of the vertices with rigid bodies, and the position update with
// pins and glue.
//
// Each vertex is a sphere of half the sheet's thickness. The host (the Bullet plugin)
// reports a contact point on the body where the body is at the end of its step, with the
// normal from the body toward the vertex. A vertex may approach the body by no more than
// its gap (speculative contact): n . v >= -gap / h. The velocity change that enforces it
// is the vertex's normal impulse; Coulomb friction limits the tangential change of the
// velocity relative to the body's surface to mu times the normal one. The body receives
// the equal and opposite impulse (momentum is conserved), as the strings' contacts do.
// A light vertex cannot stop a heavy body in one step: the body is held over the next
// steps, as the implicit solve turns the vertex's displacement into spring force and the
// vertex passes it on through the contact (a light box comes to rest on a sheet; a sphere
// pushed by its host presses the sheet and is hardly slowed).
#include "paper/sheet.hpp"
#include "string/string_state.hpp"

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

}  // namespace

void resolveContacts(PaperSheet& s, const std::vector<PointContact>& contacts, RigidTable& rigids, const PaperStep& ctx) {
    if (contacts.empty()) return;
    const double radius = 0.5 * s.desc.thickness;
    for (int pass = 0; pass < kContactPasses; ++pass) {
        for (const PointContact& c : contacts) {
            const std::uint32_t i = c.vertex;
            if (i >= s.vertices() || s.fixed[i]) continue;
            RigidState& body = rigids.bodies[c.body.index];
            const bool movable = rigids.movable(c.body);
            const Vec3 arm = c.point - body.position;
            const Vec3 n = c.normal;
            const double gap = n.dot(s.x[i] - c.point) - radius;
            const double target = -gap * ctx.inv_h;
            const double vn = n.dot(s.v[i]);
            if (vn >= target) continue;
            const double dvn = target - vn;
            Vec3 dv = dvn * n;
            // Friction on the motion relative to the body's surface.
            const Vec3 body_v = body.linear_velocity + body.angular_velocity.cross(arm);
            Vec3 rel = s.v[i] + dv - body_v;
            rel -= n * n.dot(rel);
            const double slip = rel.norm();
            const double mu = std::max(s.desc.friction, c.friction);
            if (slip > 0.0) dv -= rel * std::min(1.0, mu * dvn / slip);
            s.v[i] += dv;
            if (movable) pushBody(body, arm, -s.mass[i] * dv);
        }
    }
}

void integratePositions(PaperSheet& s, RigidTable& rigids, const PaperStep& ctx) {
    for (std::size_t i = 0; i < s.vertices(); ++i) {
        const VertexHold& hold = s.hold[i];
        if (hold.kind == VertexHold::Kind::Pin) {
            s.x[i] = hold.point;
        } else if (hold.kind == VertexHold::Kind::Glue) {
            RigidState& body = rigids.bodies[hold.body.index];
            // The sheet pulls the body with the force on this vertex (its springs, its
            // weight): h f, kept in the solve's right-hand side.
            if (rigids.movable(hold.body)) pushBody(body, s.x[i] - body.position, s.rhs[i]);
            s.x[i] = gluePoint(body, hold.point);
        } else {
            s.x[i] += ctx.h * s.v[i];
        }
    }
}

}  // namespace tearables::detail
