// Paper sheets: creation, attachments and the order of a sheet's stages in a step:
// rigid contacts (one PointQuery of all sheets to the host) -> bodies lend their mass to
// the vertices they touch or hold -> forces and the implicit solve -> bodies get their
// shares' motion, contacts enforced -> edge tensions -> positions -> creases and hinges
// -> tears -> finite check. Topology changes happen only in the crease and tear stages,
// after the positions are final, never inside a solver loop.
#include "paper/system.hpp"

#include "base/stage_timer.hpp"
#include "base/validate.hpp"
#include "sim/freeze.hpp"
#include "sim/rigid_table.hpp"
#include "sim/sheet_attachments.hpp"

#include <algorithm>
#include <cmath>

namespace tearables::detail {

namespace {

bool live(const PaperSheet& s) { return s.alive && !s.frozen; }

void checkVertex(const PaperSheet& s, std::uint32_t vertex) {
    if (vertex >= s.vertices())
        throw InvalidInput("vertex", "index " + std::to_string(vertex) + " out of range (the sheet has " + std::to_string(s.vertices()) +
                                         " vertices)");
}

void checkBody(const RigidTable& rigids, RigidId body, const std::string& field) {
    if (body.index >= rigids.bodies.size() || !rigids.used[body.index]) throw InvalidInput(field, "no such rigid body");
}

}  // namespace

PaperId PaperSystem::add(const PaperDesc& desc, const RigidTable& rigids) {
    validate(desc);
    checkSheetAttachmentBodies(desc.attachments, rigids);
    PaperSheet s = buildSheet(desc);
    const std::vector<std::size_t> held = resolveSheetAttachments(desc.attachments, s.vertices(), "sheet");
    for (std::size_t k = 0; k < held.size(); ++k) {
        const SheetAttachment& a = desc.attachments[k];
        const std::size_t p = held[k];
        ParticleHold& hold = s.hold[p];
        if (a.body.valid()) {
            hold.kind = ParticleHold::Kind::Glue;
            hold.body = a.body;
            hold.point = a.local;
            s.x[p] = gluePoint(rigids.bodies[a.body.index], a.local);
        } else {
            hold.kind = ParticleHold::Kind::Pin;
            hold.point = a.world ? *a.world : s.x[p];
            s.x[p] = hold.point;
        }
    }
    s.x_pred = s.x;
    for (std::size_t i = 0; i < sheets_.size(); ++i)
        if (!sheets_[i].alive) {
            s.generation = sheets_[i].generation;
            sheets_[i] = std::move(s);
            return idAt(i);
        }
    sheets_.push_back(std::move(s));
    return idAt(sheets_.size() - 1);
}

void PaperSystem::remove(PaperId id) {
    const std::uint32_t generation = get(id).generation + 1;
    sheets_[id.index] = PaperSheet{};
    sheets_[id.index].alive = false;
    sheets_[id.index].generation = generation;
}

std::vector<PaperId> PaperSystem::ids() const {
    std::vector<PaperId> out;
    for (std::size_t i = 0; i < sheets_.size(); ++i)
        if (sheets_[i].alive) out.push_back(idAt(i));
    return out;
}

PaperSheet& PaperSystem::get(PaperId id) {
    return const_cast<PaperSheet&>(static_cast<const PaperSystem&>(*this).get(id));
}
const PaperSheet& PaperSystem::get(PaperId id) const {
    if (!contains(id)) {
        if (id.index < sheets_.size() && id.generation < sheets_[id.index].generation)
            throw InvalidInput("paper", "stale id: the paper sheet in slot " + std::to_string(id.index) + " was removed");
        throw InvalidInput("paper", "no such paper sheet");
    }
    return sheets_[id.index];
}

PaperView PaperSystem::view(PaperId id) const {
    const PaperSheet& s = get(id);
    PaperView v;
    v.positions = &s.x;
    v.velocities = &s.v;
    v.masses = &s.mass;
    v.triangles = &s.triangles;
    v.springs = &s.springs;
    v.tension = &s.tension;
    v.counters = s.counters;
    v.thickness = s.desc.thickness;
    v.frozen = s.frozen;
    return v;
}

void PaperSystem::attachToPoint(PaperId id, std::uint32_t vertex, const Vec3& point) {
    PaperSheet& s = get(id);
    checkVertex(s, vertex);
    requirePosition("point", point);
    s.hold[vertex] = ParticleHold{ParticleHold::Kind::Pin, point, RigidId{}};
    s.x[vertex] = point;
    s.v[vertex].setZero();
}

void PaperSystem::attachToRigid(PaperId id, std::uint32_t vertex, RigidId body, const Vec3& local, const RigidTable& rigids) {
    PaperSheet& s = get(id);
    checkVertex(s, vertex);
    checkBody(rigids, body, "body");
    requirePosition("local", local);
    s.hold[vertex] = ParticleHold{ParticleHold::Kind::Glue, local, body};
    s.x[vertex] = gluePoint(rigids.bodies[body.index], local);
}

void PaperSystem::movePin(PaperId id, std::uint32_t vertex, const Vec3& point) {
    PaperSheet& s = get(id);
    checkVertex(s, vertex);
    if (s.hold[vertex].kind != ParticleHold::Kind::Pin) throw InvalidInput("vertex", "is not pinned to a world point");
    requirePosition("point", point);
    s.hold[vertex].point = point;
}

void PaperSystem::release(PaperId id, std::uint32_t vertex, EventCause cause, double time, std::int64_t step, std::vector<Event>& events) {
    PaperSheet& s = get(id);
    checkVertex(s, vertex);
    releaseHold(s.hold, vertex, s.desc.name, cause, time, step, events);
}

void PaperSystem::applyForce(PaperId id, std::uint32_t vertex, const Vec3& force) {
    PaperSheet& s = get(id);
    checkVertex(s, vertex);
    if (!force.allFinite()) throw InvalidInput("force", "must be finite");
    s.force[vertex] += force;
}

void PaperSystem::releaseBody(RigidId body, double time, std::int64_t step, std::vector<Event>& events) {
    for (std::size_t i = 0; i < sheets_.size(); ++i) {
        if (!sheets_[i].alive) continue;
        for (std::size_t v = 0; v < sheets_[i].vertices(); ++v)
            if (sheets_[i].hold[v].gluedTo(body))
                release(idAt(i), static_cast<std::uint32_t>(v), EventCause::BodyRemoved, time, step, events);
    }
}

bool PaperSystem::usesBody(RigidId body) const {
    for (const PaperSheet& s : sheets_) {
        if (!s.alive) continue;
        if (holdsBody(s.hold, body)) return true;
    }
    return false;
}

void PaperSystem::bounds(double h, const Vec3& gravity, std::vector<std::pair<Vec3, Vec3>>& out) const {
    for (const PaperSheet& s : sheets_) {
        if (!s.alive || s.frozen || s.x.empty()) continue;
        Vec3 lo = Vec3::Constant(1e300), hi = Vec3::Constant(-1e300);
        double speed = 0.0;
        for (std::size_t i = 0; i < s.vertices(); ++i) {
            lo = lo.cwiseMin(s.x[i]);
            hi = hi.cwiseMax(s.x[i]);
            speed = std::max(speed, s.v[i].norm());
        }
        // Travel in a step: the fastest vertex, plus what gravity adds, plus slack for the
        // springs' pull (a centimetre: far more than a stiff sheet moves in a step).
        const double grow = 0.5 * s.desc.thickness + speed * h + gravity.norm() * h * h + 0.01;
        out.emplace_back(Vec3(lo.array() - grow), Vec3(hi.array() + grow));
    }
}

void PaperSystem::step(RigidTable& rigids, const StepContext& ctx, const HostContacts& host, std::vector<Event>& events) {
    PaperTimes& t = times_;
    t = PaperTimes{};
    if (sheets_.empty()) return;
    PaperStep pctx;
    pctx.h = ctx.h;
    pctx.inv_h = ctx.inv_h;
    pctx.gravity = ctx.gravity;
    pctx.max_speed = ctx.settings->max_speed;
    pctx.time = ctx.time;
    pctx.step = ctx.step;
    StageTimer timer;
    collideBodies(rigids, pctx, host);     timer.lap(t.collision);
    solve(rigids, pctx);                   timer.lap(t.solve);
    enforceContacts(rigids, pctx);         timer.lap(t.collision);
    tension(pctx);                         timer.lap(t.tension);
    positions(rigids, pctx);               timer.lap(t.positions);
    crease(pctx, events);                  timer.lap(t.crease);
    tearAndCheck(ctx, pctx, events);       timer.lap(t.tear);
}

/// Rigid bodies: one query of every live sheet's vertices, where they start and where
/// they would go without their springs (gravity's pull); the host's contacts are
/// speculative (a reach of both travels), so the springs' motion is covered. Movable
/// bodies then lend their mass to the vertices that touch or hold them, shared equally
/// among all of them (over every sheet).
void PaperSystem::collideBodies(RigidTable& rigids, const PaperStep& ctx, const HostContacts& host) {
    query_.start.clear();
    query_.predicted.clear();
    query_.radius.clear();
    query_.triangles.clear();
    query_sheet_.clear();
    for (std::size_t i = 0; i < sheets_.size(); ++i) {
        PaperSheet& s = sheets_[i];
        if (!live(s)) continue;
        // A glue to a body that left the table frees the vertex (the world's removeRigid
        // does this with an event; this guards the solve).
        for (ParticleHold& hold : s.hold)
            if (hold.kind == ParticleHold::Kind::Glue && (hold.body.index >= rigids.bodies.size() || !rigids.used[hold.body.index]))
                hold = ParticleHold{};
        s.v_start = s.v;  // before coupling changes it (momentum-balance tension)
        s.x_pred.resize(s.vertices());
        for (std::size_t v = 0; v < s.vertices(); ++v) s.x_pred[v] = s.x[v] + ctx.h * (s.v[v] + ctx.h * ctx.gravity);
        query_.start.push_back(&s.x);
        query_.predicted.push_back(&s.x_pred);
        query_.radius.push_back(0.5 * s.desc.thickness);
        query_.triangles.push_back(&s.triangles);  // a surface: bodies touch it between vertices too
        query_sheet_.push_back(static_cast<std::uint32_t>(i));
    }
    contacts_.clear();
    if (host.points && !query_.start.empty()) host.points(query_, contacts_);
    per_sheet_.resize(sheets_.size());
    for (auto& list : per_sheet_) list.clear();
    // A sheet does not collide with a body it is glued to (as strings): the glue already
    // couples them, and a second coupling through contacts would count the body twice.
    glued_.resize(sheets_.size());
    for (std::size_t i = 0; i < sheets_.size(); ++i) {
        glued_[i].clear();
        if (!live(sheets_[i]) || contacts_.empty()) continue;
        for (const ParticleHold& hold : sheets_[i].hold)
            if (hold.kind == ParticleHold::Kind::Glue) glued_[i].push_back(hold.body.index);
        std::sort(glued_[i].begin(), glued_[i].end());
    }
    for (const PointContact& c : contacts_) {
        const std::uint32_t sheet = query_sheet_[c.object];
        if (!std::binary_search(glued_[sheet].begin(), glued_[sheet].end(), c.body.index)) per_sheet_[sheet].push_back(c);
    }
    share_.assign(rigids.bodies.size(), 0.0);
    for (std::size_t i = 0; i < sheets_.size(); ++i)
        if (live(sheets_[i])) countCouplings(sheets_[i], per_sheet_[i], rigids, ctx, share_);
    couplings_.resize(sheets_.size());
    for (std::size_t i = 0; i < sheets_.size(); ++i)
        if (live(sheets_[i])) coupleBodies(sheets_[i], per_sheet_[i], share_, rigids, ctx, couplings_[i]);
}

void PaperSystem::solve(const RigidTable& rigids, const PaperStep& ctx) {
    for (PaperSheet& s : sheets_)
        if (live(s)) solveVelocities(s, rigids, ctx);
}

/// The bodies get what their shares gained; then every contact is made to hold at the
/// end of the step (static bodies, friction, what the coupling left).
void PaperSystem::enforceContacts(RigidTable& rigids, const PaperStep& ctx) {
    for (std::size_t i = 0; i < sheets_.size(); ++i) {
        if (!live(sheets_[i])) continue;
        releaseBodies(sheets_[i], couplings_[i], rigids, ctx);
        resolveContacts(sheets_[i], per_sheet_[i], rigids, ctx);
    }
}

void PaperSystem::tension(const PaperStep& ctx) {
    for (std::size_t i = 0; i < sheets_.size(); ++i)
        if (live(sheets_[i])) estimateTension(sheets_[i], per_sheet_[i], ctx);
}

void PaperSystem::positions(RigidTable& rigids, const PaperStep& ctx) {
    for (PaperSheet& s : sheets_)
        if (live(s)) integratePositions(s, rigids, ctx);
}

void PaperSystem::crease(const PaperStep& ctx, std::vector<Event>& events) {
    for (std::size_t i = 0; i < sheets_.size(); ++i)
        if (live(sheets_[i])) creaseAndFold(sheets_[i], idAt(i), ctx, events);
}

/// Tears, then the finite check: a sheet left non-finite is frozen where it is (its
/// non-finite vertices at the origin, so that its view stays finite).
void PaperSystem::tearAndCheck(const StepContext& step, const PaperStep& ctx, std::vector<Event>& events) {
    for (std::size_t i = 0; i < sheets_.size(); ++i) {
        PaperSheet& s = sheets_[i];
        if (!live(s)) continue;
        tear(s, idAt(i), ctx, events);
        bool ok = true;
        for (std::size_t v = 0; v < s.vertices() && ok; ++v) ok = s.x[v].allFinite() && s.v[v].allFinite();
        if (!ok) {
            for (std::size_t v = 0; v < s.vertices(); ++v)
                if (!s.x[v].allFinite()) s.x[v].setZero();
            events.push_back(freezeNonFinite(s.v, s.frozen, s.desc.name, step));
        }
        std::fill(s.force.begin(), s.force.end(), Vec3::Zero());
    }
}

}  // namespace tearables::detail
