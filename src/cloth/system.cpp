// The cloths of a world and their step, in named stages: prediction, collision with
// rigid bodies (the host's point query), strain limiting, tension (Yarn Sec. 3.2),
// material response (tears: the only topology change, after the solves), velocities
// and friction.
#include "cloth/cloth_state.hpp"

#include "base/stage_timer.hpp"
#include "base/validate.hpp"
#include "sim/sheet_attachments.hpp"
#include "sim/freeze.hpp"

#include <algorithm>
#include <cmath>

namespace tearables::detail {

ClothId ClothSystem::add(const ClothDesc& desc, const RigidTable& rigids) {
    validate(desc);
    checkSheetAttachmentBodies(desc.attachments, rigids);
    ClothState state = makeCloth(desc);  // with the world pins
    const std::vector<std::size_t> held = resolveSheetAttachments(desc.attachments, state.vertices(), "cloth");
    for (std::size_t k = 0; k < held.size(); ++k) {
        const SheetAttachment& a = desc.attachments[k];
        if (a.body.valid()) glueVertex(state, held[k], a.body, rigids.bodies[a.body.index], a.local);
    }
    for (std::size_t i = 0; i < cloths_.size(); ++i)
        if (!cloths_[i].alive) {
            state.generation = cloths_[i].generation;
            cloths_[i] = std::move(state);
            return idAt(i);
        }
    cloths_.push_back(std::move(state));
    return idAt(cloths_.size() - 1);
}

void ClothSystem::remove(ClothId id) {
    const std::uint32_t generation = get(id).generation + 1;
    cloths_[id.index] = ClothState{};
    cloths_[id.index].alive = false;
    cloths_[id.index].generation = generation;
}

ClothState& ClothSystem::get(ClothId id) {
    return const_cast<ClothState&>(static_cast<const ClothSystem&>(*this).get(id));
}

const ClothState& ClothSystem::get(ClothId id) const {
    if (!contains(id)) {
        if (id.index < cloths_.size() && id.generation < cloths_[id.index].generation)
            throw InvalidInput("cloth", "stale id: the cloth in slot " + std::to_string(id.index) + " was removed");
        throw InvalidInput("cloth", "no such cloth");
    }
    return cloths_[id.index];
}

bool ClothSystem::contains(ClothId id) const {
    return id.index < cloths_.size() && cloths_[id.index].alive && cloths_[id.index].generation == id.generation;
}

ClothId ClothSystem::idAt(std::size_t slot) const {
    return ClothId{static_cast<std::uint32_t>(slot), cloths_[slot].generation};
}

std::vector<ClothId> ClothSystem::ids() const {
    std::vector<ClothId> out;
    for (std::size_t i = 0; i < cloths_.size(); ++i)
        if (cloths_[i].alive) out.push_back(idAt(i));
    return out;
}

bool ClothSystem::empty() const {
    return std::none_of(cloths_.begin(), cloths_.end(), [](const ClothState& c) { return c.alive; });
}

void ClothSystem::bounds(double h, const Vec3& gravity, std::vector<std::pair<Vec3, Vec3>>& out) const {
    for (const ClothState& c : cloths_) {
        if (!c.alive || c.frozen) continue;
        Vec3 lo = Vec3::Constant(1e300), hi = Vec3::Constant(-1e300);
        double speed = 0.0;
        for (std::size_t p = 0; p < c.vertices(); ++p) {
            lo = lo.cwiseMin(c.x[p]);
            hi = hi.cwiseMax(c.x[p]);
            speed = std::max(speed, c.v[p].norm());
        }
        // Grown by the vertices' radius and what they can travel in the step.
        const double grow = 2.0 * c.desc.yarn_radius + speed * h + gravity.norm() * h * h + 0.01;
        if (lo.allFinite() && hi.allFinite()) out.emplace_back(lo.array() - grow, hi.array() + grow);
    }
}

bool ClothSystem::usesBody(RigidId body) const {
    for (const ClothState& c : cloths_) {
        if (!c.alive) continue;
        if (holdsBody(c.hold, body)) return true;
    }
    return false;
}

void ClothSystem::releaseBody(RigidId body, double time, std::int64_t step, std::vector<Event>& pending) {
    for (std::size_t i = 0; i < cloths_.size(); ++i) {
        ClothState& c = cloths_[i];
        if (!c.alive) continue;
        for (std::size_t p = 0; p < c.vertices(); ++p)
            if (c.hold[p].gluedTo(body))
                release(idAt(i), p, EventCause::BodyRemoved, time, step, pending);
    }
}

void ClothSystem::release(ClothId id, std::size_t vertex, EventCause cause, double time, std::int64_t step,
                          std::vector<Event>& pending) {
    ClothState& c = get(id);
    releaseHold(c.hold, vertex, c.desc.name, cause, time, step, pending);
}

namespace {

bool live(const ClothState& c) { return c.alive && !c.frozen; }

}  // namespace

void ClothSystem::step(RigidTable& rigids, const StepContext& ctx, const HostContacts& host, std::vector<Event>& events) {
    StageTimes& t = times_;
    t = StageTimes{};
    if (empty()) return;
    StageTimer timer;
    predict(rigids, ctx);                 timer.lap(t.predict);
    collideBodies(rigids, host);          timer.lap(t.collision);
    limitStrain(rigids, ctx);             timer.lap(t.strain_limit);
    solveTension(ctx);                    timer.lap(t.tension);
    respondMaterial(ctx, events);         timer.lap(t.material);
    updateVelocities(rigids, ctx, events); timer.lap(t.velocities);
}

void ClothSystem::predict(const RigidTable& rigids, const StepContext& ctx) {
    for (ClothState& c : cloths_)
        if (live(c)) predictCloth(c, rigids, ctx);
}

/// Collision with rigid bodies: the host's narrow phase on spheres of the yarn radius,
/// swept from the start of the step to the prediction.
void ClothSystem::collideBodies(const RigidTable& rigids, const HostContacts& host) {
    query_.start.clear();
    query_.predicted.clear();
    query_.radius.clear();
    query_cloth_.clear();
    for (std::size_t i = 0; i < cloths_.size(); ++i) {
        ClothState& c = cloths_[i];
        c.contacts.clear();
        if (!live(c)) continue;
        query_.start.push_back(&c.x_prev);
        query_.predicted.push_back(&c.x_pred);
        query_.radius.push_back(c.desc.yarn_radius);
        query_cloth_.push_back(static_cast<std::uint32_t>(i));
    }
    found_.clear();
    if (!query_.start.empty() && host.points) host.points(query_, found_);
    for (const PointContact& pc : found_) {
        if (pc.onFace()) continue;  // a cloth gives no triangles: vertex contacts only
        ClothState& c = cloths_[query_cloth_[pc.object]];
        if (c.hold[pc.vertex].kind != ParticleHold::Kind::Free) continue;
        // A cloth does not collide with a body it is glued to (as strings): the glue
        // already couples them.
        if (holdsBody(c.hold, pc.body)) continue;
        VertexContact vc;
        vc.vertex = pc.vertex;
        vc.normal = pc.normal;
        vc.point = pc.point;
        vc.body = pc.body;
        const RigidState& body = rigids.bodies[pc.body.index];
        vc.local = body.orientation.conjugate() * (pc.point - body.position);
        vc.friction = std::max(0.0, pc.friction);
        c.contacts.push_back(vc);
    }
}

void ClothSystem::limitStrain(RigidTable& rigids, const StepContext& ctx) {
    for (ClothState& c : cloths_)
        if (live(c)) limitClothStrain(c, rigids, ctx);
}

void ClothSystem::solveTension(const StepContext& ctx) {
    for (ClothState& c : cloths_)
        if (live(c)) solveClothTension(c, ctx);
}

void ClothSystem::respondMaterial(const StepContext& ctx, std::vector<Event>& events) {
    for (ClothState& c : cloths_)
        if (live(c)) respondClothMaterial(c, ctx, events);
}

/// Velocities from the step's motion, capped at max_speed, then the contacts' friction; a
/// cloth left non-finite is frozen at the start of the step (a non-finite start at the
/// origin).
void ClothSystem::updateVelocities(RigidTable& rigids, const StepContext& ctx, std::vector<Event>& events) {
    const double max_speed = ctx.settings ? ctx.settings->max_speed : 500.0;
    for (std::size_t i = 0; i < cloths_.size(); ++i) {
        ClothState& c = cloths_[i];
        if (!live(c)) continue;
        bool ok = true;
        for (std::size_t p = 0; p < c.vertices(); ++p) {
            Vec3 v = (c.x[p] - c.x_prev[p]) * ctx.inv_h;
            const double speed = v.norm();
            if (speed > max_speed) v *= max_speed / speed;
            c.v[p] = v;
            ok = ok && finite(c.x[p]) && finite(v);
        }
        for (double t : c.tension) ok = ok && std::isfinite(t);
        if (ok && !c.contacts.empty()) applyClothFriction(c, rigids, ctx);
        std::fill(c.force.begin(), c.force.end(), Vec3::Zero());
        if (!ok) {
            for (std::size_t p = 0; p < c.vertices(); ++p) c.x[p] = finite(c.x_prev[p]) ? c.x_prev[p] : Vec3::Zero();
            std::fill(c.tension.begin(), c.tension.end(), 0.0);
            events.push_back(freezeNonFinite(c.v, c.frozen, c.desc.name, ctx));
        }
    }
}

}  // namespace tearables::detail
