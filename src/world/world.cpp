// The world: owns the materials' systems and the rigid bodies' table, and runs a step
// as a table of contents (Box2D's solver stages, MuJoCo's mj_fwdPosition): the strings,
// then the cloths, then the paper sheets, each over its own stages, then the bodies'
// velocities from what the materials moved them by.
#include "tearables/world.hpp"

#include "base/constants.hpp"
#include "base/float_mode.hpp"
#include "base/stage_timer.hpp"
#include "base/thread_pool.hpp"
#include "base/validate.hpp"
#include "cloth/cloth_state.hpp"
#include "island/island_solver.hpp"
#include "paper/system.hpp"
#include "sim/host_contacts.hpp"
#include "string/string_system.hpp"
#include "world/world_access.hpp"

#include <algorithm>
#include <cmath>
#include <string>

namespace tearables {

using detail::finite;
using detail::kPi;
using detail::ParticleHold;
using detail::RigidTable;
using detail::StageTimer;
using detail::StepContext;
using detail::StringState;
using detail::resolveIndex;

StageTimes& StageTimes::operator+=(const StageTimes& o) {
    predict += o.predict;
    shape_matching += o.shape_matching;
    twist += o.twist;
    collision += o.collision;
    strain_limit += o.strain_limit;
    tension += o.tension;
    material += o.material;
    velocities += o.velocities;
    return *this;
}

namespace {

/// The time steps World::step takes, s: shorter ones make 1/h and the penalties overflow,
/// longer ones are no simulation.
constexpr double kMinStep = 1e-7;
constexpr double kMaxStep = 1.0;

}  // namespace

struct World::Impl {
    WorldSettings settings;
    RigidTable rigids;
    detail::StringSystem strings;
    detail::ClothSystem cloths;
    detail::PaperSystem papers;
    detail::ThreadPool pool;  // independent strings' stages (WorldSettings::threads)
    detail::IslandSolver islands;  // strings coupled through movable bodies
    std::vector<BodyContact> body_found;  // the host's body contacts this step (kept: no allocation)
    std::vector<BodyJoint> joints_found;  // the host's joints handed to the islands this step
    std::vector<Event> events;
    std::vector<Event> pending;  // emitted between steps, reported with the next step
    StageTimes last;
    ContactProvider* contact_provider = nullptr;
    bool cold_strain_starts = false;  // StepContext::cold_strain_starts (tests compare)
    bool newton_strain_only = false;  // StepContext::newton_strain_only (tests compare)
    double time = 0.0;
    std::int64_t steps = 0;

    RigidState& body(RigidId id) {
        if (id.index >= rigids.bodies.size() || !rigids.used[id.index]) throw InvalidInput("body", "no such rigid body");
        return rigids.bodies[id.index];
    }

    /// The step's context; the events of the last step give way to those emitted since;
    /// the bodies' poses at the start of the step are kept (applyBodyVelocities).
    StepContext beginStep(double h) {
        events.clear();
        events.swap(pending);
        StepContext ctx;
        ctx.h = h;
        ctx.inv_h = 1.0 / h;
        ctx.gravity = settings.gravity;
        ctx.settings = &settings;
        ctx.time = time + h;
        ctx.step = steps + 1;
        ctx.pool = &pool;
        ctx.islands = &islands;
        islands.clearReports();
        ctx.cold_strain_starts = cold_strain_starts;
        ctx.newton_strain_only = newton_strain_only;
        for (std::size_t i = 0; i < rigids.bodies.size(); ++i) {
            rigids.bodies[i].impulse.setZero();
            rigids.start_position[i] = rigids.bodies[i].position;
            rigids.start_orientation[i] = rigids.bodies[i].orientation;
        }
        pool.setThreads(settings.threads);
        return ctx;
    }

    /// The host's narrow phase for this step's materials: the strings' segments only with
    /// a host and rigid contacts on; a host that throws gives no contacts this step rather
    /// than a broken step.
    detail::HostContacts hostContacts() {
        detail::HostContacts host;
        if (contact_provider && settings.rigid_contacts)
            host.segments = [this](const CollisionQuery& q, std::vector<RigidContact>& out) {
                try {
                    contact_provider->findContacts(q, out);
                } catch (...) {
                    out.clear();
                }
            };
        host.points = [this](const PointQuery& q, std::vector<PointContact>& out) { findPointContacts(q, out); };
        return host;
    }

    /// The host's contacts between bodies, for the islands; a host that throws gives none
    /// this step.
    void collideBodies() {
        body_found.clear();
        if (contact_provider && settings.rigid_contacts) {
            try {
                contact_provider->findBodyContacts(body_found);
            } catch (...) {
                body_found.clear();
            }
        }
        islands.setBodyContacts(body_found, rigids);
        // The joints the host handed over (its bodies then move only here).
        joints_found.clear();
        if (contact_provider) {
            try {
                contact_provider->findBodyJoints(joints_found);
            } catch (...) {
                joints_found.clear();
            }
        }
        islands.setBodyJoints(joints_found, rigids);
    }

    /// The host's contacts of mesh vertices (sheets, cloths) with rigid bodies: only those
    /// that name a vertex of the query and a body of the table, with finite data and a
    /// unit normal, are kept. A host that throws gives none this step.
    void findPointContacts(const PointQuery& q, std::vector<PointContact>& out) {
        out.clear();
        if (!contact_provider || !settings.rigid_contacts) return;
        try {
            contact_provider->findPointContacts(q, out);
        } catch (...) {
            out.clear();
            return;
        }
        out.erase(std::remove_if(out.begin(), out.end(),
                                 [&](const PointContact& c) {
                                     if (c.object >= q.start.size()) return true;
                                     const std::size_t n = q.start[c.object]->size();
                                     if (c.onFace()) {
                                         const auto* tris = c.object < q.triangles.size() ? q.triangles[c.object] : nullptr;
                                         if (!tris || !finite(c.weights) || c.weights.minCoeff() < 0.0 ||
                                             std::abs(c.weights.sum() - 1.0) > 1e-6 || c.face[0] != c.vertex)
                                             return true;
                                         for (std::uint32_t v : c.face)
                                             if (v >= n) return true;
                                     }
                                     return c.vertex >= n ||
                                            c.body.index >= rigids.bodies.size() || !rigids.used[c.body.index] ||
                                            !finite(c.normal) || !finite(c.point) || !std::isfinite(c.friction) ||
                                            std::abs(c.normal.norm() - 1.0) > 1e-3;
                                 }),
                  out.end());
    }

    /// Bodies moved by the materials get the matching velocity change (position-based
    /// coupling: dv = dx / h, dw = dtheta / h), so the host carries the reaction on.
    void applyBodyVelocities(const StepContext& ctx) {
        for (std::size_t i = 0; i < rigids.bodies.size(); ++i) {
            RigidState& b = rigids.bodies[i];
            if (!rigids.used[i] || b.inverse_mass <= 0.0) continue;
            const Vec3 dx = b.position - rigids.start_position[i];
            Eigen::AngleAxisd rot(b.orientation * rigids.start_orientation[i].conjugate());
            double angle = rot.angle();
            if (angle > kPi) angle -= 2.0 * kPi;
            b.linear_velocity += dx * ctx.inv_h;
            b.angular_velocity += rot.axis() * (angle * ctx.inv_h);
        }
    }
};

World::World(const WorldSettings& settings) : impl_(std::make_unique<Impl>()) {
    validate(settings);
    impl_->settings = settings;
}

World::~World() = default;

StringId World::addString(const StringDesc& desc) { return impl_->strings.add(desc); }

void World::removeString(StringId id) { impl_->strings.remove(id); }
std::vector<StringId> World::strings() const { return impl_->strings.ids(); }

std::vector<std::pair<Vec3, Vec3>> World::meshBounds(double h) const {
    std::vector<std::pair<Vec3, Vec3>> out;  // sheets and cloths add their swept bounds here
    impl_->cloths.bounds(h, impl_->settings.gravity, out);
    impl_->papers.bounds(h, impl_->settings.gravity, out);
    return out;
}

bool World::contains(StringId id) const { return impl_->strings.contains(id); }

int World::resolveParticle(StringId id, int particle) const {
    return resolveIndex(particle, impl_->strings.get(id).particles(), "particle");
}

void World::attachToPoint(StringId id, int particle, const Vec3& point) {
    StringState& s = impl_->strings.get(id);
    const int p = resolveIndex(particle, s.particles(), "particle");
    detail::requirePosition("point", point);
    s.hold[p].kind = ParticleHold::Kind::Pin;
    s.hold[p].point = point;
    s.hold[p].body = RigidId{};
    // A pinned end clamps its segment's twist at the angle it has now.
    if (p == 0) s.end_twist[0] = s.twist.front();
    if (p + 1 == static_cast<int>(s.particles())) s.end_twist[1] = s.twist.back();
    s.x[p] = point;
    s.v[p].setZero();
}

void World::attachToRigid(StringId id, int particle, RigidId body, const Vec3& local_point) {
    StringState& s = impl_->strings.get(id);
    const int p = resolveIndex(particle, s.particles(), "particle");
    const RigidState& b = impl_->body(body);
    detail::requirePosition("local", local_point);
    s.hold[p].kind = ParticleHold::Kind::Glue;
    s.hold[p].point = local_point;
    s.hold[p].body = body;
    s.x[p] = detail::gluePoint(b, local_point);
}

void World::movePin(StringId id, int particle, const Vec3& point) {
    StringState& s = impl_->strings.get(id);
    const int p = resolveIndex(particle, s.particles(), "particle");
    if (s.hold[p].kind != ParticleHold::Kind::Pin) throw InvalidInput("particle", "is not pinned to a world point");
    detail::requirePosition("point", point);
    s.hold[p].point = point;
}

void World::detach(StringId id, int particle) {
    const int p = resolveIndex(particle, impl_->strings.get(id).particles(), "particle");
    impl_->strings.release(id, static_cast<std::size_t>(p), EventCause::Request, impl_->time, impl_->steps, impl_->pending);
}

bool World::cutSegment(StringId id, int segment) {
    StringState& s = impl_->strings.get(id);
    const int n = static_cast<int>(s.segments());
    if (segment < -n || segment >= n)
        throw InvalidInput("segment", "segment index " + std::to_string(segment) + " out of range (the string has " +
                                          std::to_string(n) + " segments)");
    const std::size_t j = static_cast<std::size_t>(segment < 0 ? segment + n : segment);
    if (s.broken[j]) return false;
    s.broken[j] = 1;
    s.tension[j] = 0.0;
    Event e;
    e.type = EventType::Tear;
    e.cause = EventCause::Request;
    e.string = id;
    e.object = s.desc.name;
    e.segment = static_cast<int>(j);
    e.time = impl_->time;
    e.step = impl_->steps;
    impl_->pending.push_back(e);
    return true;
}

bool World::isAttached(StringId id, int particle) const {
    const StringState& s = impl_->strings.get(id);
    return s.hold[resolveIndex(particle, s.particles(), "particle")].kind != ParticleHold::Kind::Free;
}

bool World::pinTarget(StringId id, int particle, Vec3* point) const {
    const StringState& s = impl_->strings.get(id);
    const ParticleHold& hold = s.hold[resolveIndex(particle, s.particles(), "particle")];
    if (hold.kind != ParticleHold::Kind::Pin) return false;
    if (point) *point = hold.point;
    return true;
}

void World::turnEnd(StringId id, int end, double angle) {
    StringState& s = impl_->strings.get(id);
    if (end != 0 && end != -1) throw InvalidInput("end", "must be 0 (first) or -1 (last), got " + std::to_string(end));
    const std::size_t p = end == 0 ? 0 : s.particles() - 1;
    if (s.hold[p].kind != ParticleHold::Kind::Pin)
        throw InvalidInput("end", "is not clamped: pin its particle to a point before turning it");
    if (!std::isfinite(angle)) throw InvalidInput("angle", "must be finite");
    s.end_twist[end == 0 ? 0 : 1] += angle;
}

double World::endTwist(StringId id, int end) const {
    const StringState& s = impl_->strings.get(id);
    if (end != 0 && end != -1) throw InvalidInput("end", "must be 0 (first) or -1 (last), got " + std::to_string(end));
    return s.end_twist[end == 0 ? 0 : 1];
}

void World::applyForce(StringId id, int particle, const Vec3& force) {
    StringState& s = impl_->strings.get(id);
    const int p = resolveIndex(particle, s.particles(), "particle");
    if (!finite(force)) throw InvalidInput("force", "must be finite");
    s.force[p] += force;
}

RigidId World::addRigid(const RigidState& state) {
    if (!finite(state.position)) throw InvalidInput("body.position", "must be finite");
    if (!state.orientation.coeffs().allFinite() || std::abs(state.orientation.norm() - 1.0) > 1e-3)
        throw InvalidInput("body.orientation", "must be a finite unit quaternion");
    if (!finite(state.linear_velocity)) throw InvalidInput("body.linear_velocity", "must be finite");
    if (!finite(state.angular_velocity)) throw InvalidInput("body.angular_velocity", "must be finite");
    if (!std::isfinite(state.inverse_mass) || state.inverse_mass < 0.0)
        throw InvalidInput("body.inverse_mass", "must be finite and at least 0");
    if (!state.inverse_inertia_local.allFinite()) throw InvalidInput("body.inverse_inertia_local", "must be finite");
    RigidTable& t = impl_->rigids;
    for (std::size_t i = 0; i < t.bodies.size(); ++i)
        if (!t.used[i]) {
            t.bodies[i] = state;
            t.used[i] = 1;
            t.fresh[i] = 1;
            return RigidId{static_cast<std::uint32_t>(i)};
        }
    t.bodies.push_back(state);
    t.used.push_back(1);
    t.fresh.push_back(1);
    t.start_position.emplace_back(Vec3::Zero());
    t.start_orientation.emplace_back(Quat::Identity());
    return RigidId{static_cast<std::uint32_t>(t.bodies.size() - 1)};
}

RigidState& World::rigid(RigidId id) { return impl_->body(id); }
const RigidState& World::rigid(RigidId id) const { return const_cast<Impl&>(*impl_).body(id); }

void World::removeRigid(RigidId id) {
    impl_->body(id);
    impl_->strings.releaseBody(id, impl_->time, impl_->steps, impl_->pending);
    impl_->cloths.releaseBody(id, impl_->time, impl_->steps, impl_->pending);
    impl_->papers.releaseBody(id, impl_->time, impl_->steps, impl_->pending);
    impl_->rigids.used[id.index] = 0;
    impl_->rigids.bodies[id.index].present = false;
}

bool World::rigidInUse(RigidId id) const {
    return impl_->papers.usesBody(id) || impl_->strings.usesBody(id) || impl_->cloths.usesBody(id);
}

void World::step(double h) {
    Impl& w = *impl_;
    // Refused before anything changes: a step the solver can take, and settings that are
    // valid (settings() hands out a reference).
    if (!(h >= kMinStep && h <= kMaxStep))
        throw InvalidInput("h", "the time step must be a finite number in [1e-07, 1] s (got " + std::to_string(h) + ")");
    validate(w.settings);
    const detail::FlushSubnormals mode;  // subnormals cost ~100 cycles an operation (float_mode.hpp)
    const StepContext ctx = w.beginStep(h);
    const detail::HostContacts host = w.hostContacts();
    w.collideBodies();

    // The materials one after another, each over its own stages; each reads the bodies as
    // the one before left them.
    w.strings.step(w.rigids, ctx, host, w.events);
    w.cloths.step(w.rigids, ctx, host, w.events);
    w.papers.step(w.rigids, ctx, host, w.events);
    std::fill(w.rigids.fresh.begin(), w.rigids.fresh.end(), 0);
    StageTimer timer;
    w.applyBodyVelocities(ctx);

    // The cloths' stages are counted with the strings'; the sheets' are in lastPaperTimes().
    StageTimes& t = w.last;
    t = w.strings.lastTimes();
    t += w.cloths.lastTimes();
    timer.lap(t.velocities);
    w.time = ctx.time;
    w.steps = ctx.step;
}

StringView World::view(StringId id) const {
    const StringState& s = impl_->strings.get(id);
    StringView v;
    v.positions = &s.x;
    v.velocities = &s.v;
    v.masses = &s.mass;
    v.tension = &s.tension;
    v.twist = &s.twist;
    v.rest_length = &s.rest_length;
    v.max_length = &s.max_length;
    v.broken = &s.broken;
    v.radius = s.desc.radius;
    v.frozen = s.frozen;
    v.newton_iterations = s.diagnostics.strain_newton_iterations;
    return v;
}

const StringDesc& World::desc(StringId id) const { return impl_->strings.get(id).desc; }
const std::vector<Event>& World::events() const { return impl_->events; }

// Paper sheets: forwarded to the paper system (src/paper/system.cpp).
PaperId World::addPaper(const PaperDesc& desc) { return impl_->papers.add(desc, impl_->rigids); }
ClothId World::addCloth(const ClothDesc& desc) { return impl_->cloths.add(desc, impl_->rigids); }
void World::removePaper(PaperId id) { impl_->papers.remove(id); }
std::vector<PaperId> World::papers() const { return impl_->papers.ids(); }
bool World::contains(PaperId id) const { return impl_->papers.contains(id); }
PaperView World::viewPaper(PaperId id) const { return impl_->papers.view(id); }
const PaperDesc& World::paperDesc(PaperId id) const { return impl_->papers.get(id).desc; }
std::uint32_t World::paperVertex(PaperId id, int vertex) const {
    return static_cast<std::uint32_t>(
        detail::resolveSignedIndex(vertex, impl_->papers.get(id).vertices(), "vertex", "vertex", "sheet", "vertices"));
}
void World::attachPaperToPoint(PaperId id, int vertex, const Vec3& point) {
    impl_->papers.attachToPoint(id, paperVertex(id, vertex), point);
}
void World::attachPaperToRigid(PaperId id, int vertex, RigidId body, const Vec3& local_point) {
    impl_->papers.attachToRigid(id, paperVertex(id, vertex), body, local_point, impl_->rigids);
}
void World::movePaperPin(PaperId id, int vertex, const Vec3& point) { impl_->papers.movePin(id, paperVertex(id, vertex), point); }
void World::detachPaper(PaperId id, int vertex) {
    impl_->papers.release(id, paperVertex(id, vertex), EventCause::Request, impl_->time, impl_->steps, impl_->pending);
}
void World::applyPaperForce(PaperId id, int vertex, const Vec3& force) {
    impl_->papers.applyForce(id, paperVertex(id, vertex), force);
}
const PaperTimes& World::lastPaperTimes() const { return impl_->papers.lastTimes(); }
void World::setContactProvider(ContactProvider* provider) { impl_->contact_provider = provider; }
const std::vector<RigidContact>& World::lastContacts() const { return impl_->strings.lastContacts(); }

const std::vector<IslandSummary>& World::lastIslands() const { return impl_->islands.reports(); }
const std::vector<BodyContact>& World::lastBodyContacts() const { return impl_->islands.bodyContacts(); }
const std::vector<BodyJoint>& World::lastBodyJoints() const { return impl_->islands.bodyJoints(); }
const StageTimes& World::lastStageTimes() const { return impl_->last; }
detail::ClothSystem& World::clothSystem() { return impl_->cloths; }
const detail::ClothSystem& World::clothSystem() const { return impl_->cloths; }
std::vector<Event>& World::pendingEvents() { return impl_->pending; }
double World::time() const { return impl_->time; }
std::int64_t World::stepCount() const { return impl_->steps; }
WorldSettings& World::settings() { return impl_->settings; }
const WorldSettings& World::settings() const { return impl_->settings; }

// The parts of the state that persist from one step to the next, for snapshots.
detail::WorldParts detail::WorldAccess::parts(World& world) {
    World::Impl& w = *world.impl_;
    return {&w.settings, &w.strings.strings_, &w.cloths.cloths_, &w.papers.sheets_, &w.rigids, &w.pending,
            &w.events, &w.strings.pairs_.previous_pairs_, &w.strings.pairs_.deep_pairs_, &w.time, &w.steps};
}
void detail::WorldAccess::setStringNodePruning(World& world, bool on) { world.impl_->strings.pairs().node_pruning = on; }
void detail::WorldAccess::setSparseJointSteps(World& world, bool on) { world.impl_->strings.pairs().sparse_joint_steps = on; }
void detail::WorldAccess::setColdStrainStarts(World& world, bool on) { world.impl_->cold_strain_starts = on; }
void detail::WorldAccess::setNewtonStrainOnly(World& world, bool on) { world.impl_->newton_strain_only = on; }
std::size_t detail::WorldAccess::lastStringNodeRejects(const World& world) {
    return world.impl_->strings.pairs().lastNodeRejects();
}
void detail::WorldAccess::setStraightStringsSkip(World& world, bool on) { world.impl_->strings.pairs().straight_strings_skip = on; }
std::size_t detail::WorldAccess::lastSelfFreeStrings(const World& world) {
    return world.impl_->strings.pairs().lastSelfFreeStrings();
}
const std::vector<detail::SegmentPair>& detail::WorldAccess::lastStringSearchPairs(const World& world) {
    return world.impl_->strings.pairs().lastSearchPairs();
}

}  // namespace tearables
