// The strings' step as a sequence of stages (string_system.hpp). Each stage runs the
// strings that share nothing on the pool, each call touching only its own string and
// reading the bodies; whatever strings share (bodies they pull or touch, string-string
// contacts, events) stays on this thread, in slot order.
#include "string/string_system.hpp"

#include "base/constants.hpp"
#include "base/stage_timer.hpp"
#include "base/thread_pool.hpp"
#include "base/validate.hpp"
#include "sim/freeze.hpp"

#include <algorithm>
#include <cmath>
#include <string>

namespace tearables::detail {

namespace {

bool live(const StringState& s) { return s.alive && !s.frozen; }

/// True when the string is glued to, or touches, a body that moves.
bool touchesMovableBody(const StringState& s) {
    return !s.body_nodes.empty() || std::find(s.glue_movable.begin(), s.glue_movable.end(), 1) != s.glue_movable.end();
}

/// A string that holds a body (glue) writes to it in several stages: it stays serial.
bool ownsNothing(const StringState& s) {
    for (const ParticleHold& hold : s.hold)
        if (hold.kind == ParticleHold::Kind::Glue) return false;
    return true;
}

/// Overlaps deeper than this fraction of a string's radius where the step started are
/// pushed out gradually, kOverlapRecovery of them a step (collideBodies).
constexpr double kDeepOverlap = 0.1;
constexpr double kOverlapRecovery = 0.2;
/// A segment is buried in a body (exemptBuriedEnds) when its axis started the step inside
/// it: an overlap of more than its radius.
constexpr double kBuried = 1.0;

/// A string held (glued or pinned) inside a body, as when it is created through a block or
/// glued at a body's centre: the run of segments from the held particle that started the
/// step with its axis inside the body has no contact with it, as Bullet's soft-body anchors may
/// disable collision with their body (btSoftBody::appendAnchor). Pushed out, the run would
/// only stretch between the hold and the body's surface, and tear. The run goes on
/// through segments the host reports no contact for (wholly inside, or clear of the body)
/// and ends at the first contact whose axis is outside the body, so the rest of the string, and
/// the run once it has left, collides as before (a rope pinned above a floor lying on it,
/// a rope glued on a drum and wound round it). A glued particle's own segments never touch
/// its body: one end is on it by construction (and inside it the host's normal is
/// arbitrary); a pinned particle's own segments may report such a contact without ending
/// the run.
void exemptBuriedEnds(StringState& s, std::vector<std::uint8_t>& buried) {
    buried.assign(s.segments(), 0);
    if (s.contacts.empty()) return;
    std::vector<std::uint8_t> exempt(s.contacts.size(), 0);
    bool any = false;
    for (std::size_t p = 0; p < s.hold.size(); ++p) {
        const ParticleHold& hold = s.hold[p];
        if (hold.kind == ParticleHold::Kind::Free) continue;
        const bool glued = hold.kind == ParticleHold::Kind::Glue;
        for (const int dir : {-1, 1}) {
            const long first = dir > 0 ? static_cast<long>(p) : static_cast<long>(p) - 1;
            for (long j = first; j >= 0 && static_cast<std::size_t>(j) < s.segments(); j += dir) {
                bool clear = false;
                for (std::size_t k = 0; k < s.contacts.size(); ++k) {
                    const RigidSegmentContact& c = s.contacts[k];
                    if (c.segment != static_cast<std::uint32_t>(j) || (glued && !(c.body == hold.body))) continue;
                    const bool inside = s.made_inside[c.segment] && c.start_depth > kBuried * s.radius[c.segment];
                    if ((glued && j == first) || inside) {
                        exempt[k] = 1;
                        buried[c.segment] = 1;
                        any = true;
                    } else if (j != first) {
                        clear = true;
                    }
                }
                if (clear) break;
            }
        }
    }
    if (!any) return;
    std::size_t kept = 0;
    for (std::size_t k = 0; k < s.contacts.size(); ++k)
        if (!exempt[k]) s.contacts[kept++] = s.contacts[k];
    s.contacts.resize(kept);
}

/// A remembered contact faces the same way as the new one when their normals (in the
/// body's frame) are within about 25 degrees: the same face, edge or side of the body.
constexpr double kSameFacing = 0.9;

/// Normals within this angle's cosine (2.6 degrees) at one particle are one contact.
constexpr double kSameNormal = 0.999;

/// Whether contact c, at an end of its segment, repeats the first contact at that particle
/// (the end of the segment before, or the start of the one after) with the same body and
/// normal, as a host answers for two segments lying along one face; else, where it is the
/// first with its body, it is recorded as such (StringScratch::end_contact, reset by
/// collideBodies). Where the host gives each body's contacts together (the Bullet plugin
/// does), a record of another body is of one done with, and what is merged does not
/// depend on the order of the bodies. A second penalty there would double the contact's
/// stiffness and split its force, and friction's weight, between the two at random from
/// pass to pass.
bool repeatsEndContact(StringState& s, const RigidSegmentContact& c) {
    if (c.s != 0.0 && c.s != 1.0) return false;
    const std::size_t p = c.s == 0.0 ? c.segment : c.segment + 1;
    std::int32_t& first = s.scratch.end_contact[p];
    if (first >= 0) {
        const RigidSegmentContact& other = s.contacts[static_cast<std::size_t>(first)];
        if (other.body == c.body) return other.normal.dot(c.normal) > kSameNormal;
    }
    first = static_cast<std::int32_t>(s.contacts.size());
    return false;
}

/// Friction from where the last step left it (ContactMemory): the normal force of the
/// entry with the same body, facing the same way, nearest to c along the string (within
/// a segment's length either side: a host may name either segment for a contact at a
/// particle, and a contact slides along the string from step to step); of entries as
/// near, the closest in direction. Nearest, not any entry of the segment: two contacts
/// either side of a particle (a ball on a rope) each take their own entry, where taking
/// the segment's first would give one of them the other's force, or none, and its
/// friction would act on one side only, a couple that spins the body up from rest.
/// Returns the entry taken (an index into contact_memory), -1 if none.
std::int32_t rememberFriction(const StringState& s, RigidSegmentContact& c) {
    if (!(c.friction > 0.0)) return -1;
    const double at = static_cast<double>(c.segment) + c.s;
    double nearest = 1.0;
    double best = kSameFacing;
    std::int32_t taken = -1;
    const std::uint32_t first = c.segment > 0 ? c.segment - 1 : 0;
    const std::uint32_t last = std::min<std::uint32_t>(c.segment + 1, static_cast<std::uint32_t>(s.segments() - 1));
    ContactMemory key;
    key.body = c.body;
    for (std::uint32_t segment = first; segment <= last; ++segment) {
        key.segment = segment;
        const auto range = std::equal_range(s.contact_memory.begin(), s.contact_memory.end(), key);
        for (auto it = range.first; it != range.second; ++it) {
            const double facing = it->normal.dot(c.local_normal);
            const double distance = std::abs(static_cast<double>(it->segment) + it->s - at);
            if (facing < kSameFacing || distance > nearest) continue;
            if (distance == nearest && facing <= best) continue;
            nearest = distance;
            best = facing;
            taken = static_cast<std::int32_t>(it - s.contact_memory.begin());
        }
    }
    if (taken >= 0) {
        c.friction_normal = s.contact_memory[static_cast<std::size_t>(taken)].force;
        c.remembered = true;
    }
    return taken;
}

/// Where k contacts took one entry (the host now gives more contacts than the step
/// before, a face settling onto the string), they share its force, N / k each: the
/// force the step before carried, not k times it.
void shareRememberedFriction(StringState& s) {
    std::vector<std::uint32_t>& takers = s.scratch.memory_takers;
    takers.assign(s.contact_memory.size(), 0);
    for (const std::int32_t e : s.scratch.memory_taken)
        if (e >= 0) ++takers[static_cast<std::size_t>(e)];
    for (std::size_t i = 0; i < s.contacts.size(); ++i) {
        const std::int32_t e = s.scratch.memory_taken[i];
        if (e >= 0 && takers[static_cast<std::size_t>(e)] > 1)
            s.contacts[i].friction_normal /= static_cast<double>(takers[static_cast<std::size_t>(e)]);
    }
}

}  // namespace

int resolveIndex(int particle, std::size_t count, const char* field) {
    return static_cast<int>(resolveSignedIndex(particle, count, field, "particle", "string", "particles"));
}

StringId StringSystem::add(const StringDesc& desc) {
    validate(desc);
    StringState s;
    s.desc = desc;
    const std::size_t n = desc.points.size();
    const std::size_t m = n - 1;
    s.x = desc.points;
    s.v.assign(n, Vec3::Zero());
    s.v_prev = s.v;
    s.x_prev = s.x;
    s.x_older = s.x;
    s.x_pred = s.x;
    s.force.assign(n, Vec3::Zero());
    s.mass.assign(n, 0.0);
    s.hold.assign(n, ParticleHold{});
    s.made_inside.assign(m, 1);
    s.glue_impulse.assign(n, Vec3::Zero());
    s.glue_movable.assign(n, 0);
    s.rest_length.resize(m);
    const double area = kPi * desc.radius * desc.radius;
    for (std::size_t j = 0; j < m; ++j) {
        s.rest_length[j] = (desc.points[j + 1] - desc.points[j]).norm();
        // Strings input: mass per segment = density * pi r^2 * length, half to each end.
        const double half = 0.5 * desc.density * area * s.rest_length[j];
        s.mass[j] += half;
        s.mass[j + 1] += half;
    }
    for (const auto& [index, mass] : desc.particle_masses) s.mass[resolveIndex(index, n, "particle_masses")] = mass;
    s.inv_mass.resize(n);
    for (std::size_t p = 0; p < n; ++p) s.inv_mass[p] = 1.0 / s.mass[p];
    s.original_length = s.rest_length;
    s.max_length = s.rest_length;
    s.tension.assign(m, 0.0);
    s.twist.assign(m, 0.0);
    s.radius.assign(m, desc.radius);
    s.broken.assign(m, 0);
    s.yielded.assign(m, 0);
    s.peak_stress.assign(m, 0.0);
    s.rng.seed(desc.seed);
    s.material.resize(m);
    const Material& mat = desc.material;
    for (std::size_t j = 0; j < m; ++j) {
        SegmentMaterial& sm = s.material[j];
        sm.young = vary(s.rng, mat.tensile.young, mat.variation);
        sm.yield = vary(s.rng, mat.tensile.yield, mat.variation);
        sm.plastic_modulus = vary(s.rng, mat.tensile.plastic_modulus, mat.variation);
        sm.rupture = std::max(vary(s.rng, mat.tensile.rupture, mat.variation), sm.yield * (1.0 + 1e-12));
        sm.shear_modulus = vary(s.rng, mat.torsion.modulus, mat.variation);
        sm.torsion_yield = vary(s.rng, mat.torsion.yield, mat.variation);
        sm.torsion_plastic = vary(s.rng, mat.torsion.plastic_modulus, mat.variation);
        sm.torsion_rupture = std::max(vary(s.rng, mat.torsion.rupture, mat.variation), sm.torsion_yield * (1.0 + 1e-12));
        s.peak_stress[j] = sm.yield;
    }
    s.compliance.resize(m);
    for (std::size_t j = 0; j < m; ++j) s.compliance[j] = s.rest_length[j] / (s.material[j].young * area);
    s.scratch.dir.resize(m);
    for (std::size_t j = 0; j < m; ++j) s.scratch.dir[j] = (s.x[j + 1] - s.x[j]) / s.rest_length[j];
    s.scratch.diag.assign(m, 0.0);
    s.scratch.off.assign(m, 0.0);
    s.scratch.rhs.assign(m, 0.0);
    s.scratch.segment_work.assign(m, 0.0);
    s.scratch.active.assign(m, 0);
    s.scratch.blk_diag.assign(n, Mat3::Zero());
    s.scratch.blk_off.assign(n, Mat3::Zero());
    s.scratch.blk_rhs.assign(n, Vec3::Zero());
    s.scratch.blk_factor_gain.assign(n, Mat3::Zero());
    s.scratch.blk_factor.resize(n);
    s.scratch.chain_inverse.assign(6 * n + 12, 0.0);
    s.scratch.chain_coupled.assign(n, 0);
    s.scratch.row_projector.assign(n, Mat3::Identity());
    s.colliding.assign(n, 0);
    s.spring_force.assign(m, 0.0);
    s.scratch.geometric_tension.assign(m, 0.0);
    s.prev_stretch.assign(m, 0.0);
    s.rest_direction.resize(m);
    for (std::size_t j = 0; j < m; ++j) s.rest_direction[j] = (desc.points[j + 1] - desc.points[j]) / s.rest_length[j];
    s.rest_shape.assign(n, Vec3::Zero());
    s.scratch.csm_goal.assign(n, Vec3::Zero());
    s.csm_mass = s.mass;
    updateRestShape(s);
    s.twist_velocity.assign(m, 0.0);
    s.twist_old.assign(m, 0.0);
    s.twist_inertia.resize(m);
    s.twist_width.resize(m);
    for (std::size_t j = 0; j < m; ++j) {
        const double seg_mass = desc.density * area * s.rest_length[j];
        s.twist_inertia[j] = 0.5 * seg_mass * desc.radius * desc.radius;
        s.twist_width[j] = desc.twist_half_width.size() == 1 ? desc.twist_half_width[0] : desc.twist_half_width[j];
    }
    const std::size_t joints = m > 0 ? m - 1 : 0;
    s.rest_twist.assign(joints, 0.0);
    s.joint_stiffness.assign(joints, 0.0);
    s.torsion_peak.assign(joints, 0.0);
    s.joint_strain.assign(joints, 0.0);
    s.torsion_yielded.assign(joints, 0);
    s.twist_force.assign(n, Vec3::Zero());
    updateTwistStiffness(s);
    s.shortest_rest = *std::min_element(s.rest_length.begin(), s.rest_length.end());

    // Reuse a free slot so ids stay small; the order of strings is the slot order.
    for (std::size_t i = 0; i < strings_.size(); ++i)
        if (!strings_[i].alive) {
            s.generation = strings_[i].generation;
            strings_[i] = std::move(s);
            return idAt(i);
        }
    strings_.push_back(std::move(s));
    // The step's per-string index lists get their room here, not in a step (own_ is empty
    // while every string touches a movable body, and would grow in the step in which one
    // stops touching it).
    live_.reserve(strings_.size());
    own_.reserve(strings_.size());
    return idAt(strings_.size() - 1);
}

void StringSystem::remove(StringId id) {
    StringState& s = get(id);
    const std::uint32_t generation = s.generation + 1;
    s = StringState{};
    s.alive = false;
    s.generation = generation;
}

StringState& StringSystem::get(StringId id) {
    return const_cast<StringState&>(static_cast<const StringSystem&>(*this).get(id));
}

const StringState& StringSystem::get(StringId id) const {
    if (!contains(id)) {
        if (id.index < strings_.size() && id.generation < strings_[id.index].generation)
            throw InvalidInput("string", "stale id: the string in slot " + std::to_string(id.index) + " was removed");
        throw InvalidInput("string", "no such string");
    }
    return strings_[id.index];
}

bool StringSystem::contains(StringId id) const {
    return id.index < strings_.size() && strings_[id.index].alive && strings_[id.index].generation == id.generation;
}

StringId StringSystem::idAt(std::size_t slot) const {
    return StringId{static_cast<std::uint32_t>(slot), strings_[slot].generation};
}

std::vector<StringId> StringSystem::ids() const {
    std::vector<StringId> out;
    for (std::size_t i = 0; i < strings_.size(); ++i)
        if (strings_[i].alive) out.push_back(idAt(i));
    return out;
}

bool StringSystem::usesBody(RigidId body) const {
    for (const StringState& s : strings_) {
        if (!s.alive) continue;
        if (holdsBody(s.hold, body)) return true;
    }
    return false;
}

void StringSystem::releaseBody(RigidId body, double time, std::int64_t step, std::vector<Event>& pending) {
    for (std::size_t i = 0; i < strings_.size(); ++i) {
        StringState& s = strings_[i];
        if (!s.alive) continue;
        for (std::size_t p = 0; p < s.particles(); ++p)
            if (s.hold[p].gluedTo(body))
                release(idAt(i), p, EventCause::BodyRemoved, time, step, pending);
        // The slot may hold another body by the next step.
        s.contact_memory.erase(std::remove_if(s.contact_memory.begin(), s.contact_memory.end(),
                                              [&](const ContactMemory& c) { return c.body == body; }),
                               s.contact_memory.end());
    }
}

void StringSystem::release(StringId id, std::size_t particle, EventCause cause, double time, std::int64_t step,
                           std::vector<Event>& pending) {
    StringState& s = get(id);
    if (releaseHold(s.hold, particle, s.desc.name, cause, time, step, pending)) pending.back().string = id;
}

void StringSystem::step(RigidTable& rigids, const StepContext& ctx, const HostContacts& host, std::vector<Event>& events) {
    StageTimes& t = times_;
    t = StageTimes{};
    pool_ = ctx.pool;
    listLive();
    StageTimer timer;
    shapeMatch();                                     timer.lap(t.shape_matching);
    predict(rigids, ctx);                             timer.lap(t.predict);
    collideBodies(rigids, host, ctx, events);         timer.lap(t.collision);
    limitStrain(rigids, ctx);                         timer.lap(t.strain_limit);
    // The strings that touch are solved again, together, before the tension stage reads
    // their motion; what overlap that leaves is projected away after it (so it never
    // counts as tension).
    if (ctx.settings->string_collisions) {
        pairs_.couple(strings_, rigids, ctx, ctx.settings->island_string_contacts ? in_island_ : no_island_);
        solveCoupledClusters(rigids, ctx);            timer.lap(t.collision);
    }
    solveTwist(rigids, ctx);                          timer.lap(t.twist);
    estimateTension(ctx);                             timer.lap(t.tension);
    if (ctx.settings->string_collisions) {
        pairs_.finish(strings_);                      timer.lap(t.collision);
    }
    respondMaterial(ctx, events);                     timer.lap(t.material);
    updateVelocities(ctx, events);                    timer.lap(t.velocities);
}

void StringSystem::listLive() {
    live_.clear();
    for (std::size_t i = 0; i < strings_.size(); ++i)
        if (live(strings_[i])) live_.push_back(static_cast<std::uint32_t>(i));
}

template <class Fn>
void StringSystem::eachLive(Fn&& fn) {
    pool_->forEach(live_.size(), [&](std::size_t k) { fn(strings_[live_[k]]); });
}

void StringSystem::shapeMatch() {
    ThreadPool* pool = pool_;
    eachLive([pool](StringState& s) { detail::shapeMatch(s, pool); });
}

void StringSystem::predict(const RigidTable& rigids, const StepContext& ctx) {
    eachLive([&](StringState& s) { detail::predict(s, rigids, ctx); });
}

/// Collision with rigid bodies: the host's narrow phase on the predicted positions. Each
/// string gets its own contacts, checked (a bad contact from the host is dropped, never
/// trusted).
void StringSystem::collideBodies(RigidTable& rigids, const HostContacts& host, const StepContext& ctx,
                                 std::vector<Event>& events) {
    const double h = ctx.h;
    pool_->forEach(strings_.size(), [this](std::size_t i) {
        StringState& s = strings_[i];
        s.contacts.clear();
        s.scratch.end_contact.assign(s.particles(), -1);
        s.scratch.memory_taken.clear();
        s.body_nodes.clear();
        if (s.scratch.rows_pressed)
            std::fill(s.scratch.row_projector.begin(), s.scratch.row_projector.end(), Mat3::Identity());
        s.scratch.rows_pressed = false;
        std::fill(s.colliding.begin(), s.colliding.end(), 0);
    });
    contacts_.clear();
    if (!host.segments) return;
    query_.strings.clear();
    query_.start.clear();
    query_.predicted.clear();
    query_.radius.clear();
    query_.broken.clear();
    query_.glued.clear();
    for (std::size_t i = 0; i < strings_.size(); ++i) {
        const StringState& s = strings_[i];
        if (!s.alive || s.frozen) continue;
        const std::size_t first_glued = query_.glued.size();
        for (const ParticleHold& hold : s.hold) {
            if (hold.kind != ParticleHold::Kind::Glue || !(rigids.bodies[hold.body.index].inverse_mass > 0.0)) continue;
            const auto listed = std::find_if(query_.glued.begin() + static_cast<std::ptrdiff_t>(first_glued), query_.glued.end(),
                                             [&](const std::pair<StringId, RigidId>& g) { return g.second == hold.body; });
            if (listed == query_.glued.end()) query_.glued.emplace_back(idAt(i), hold.body);
        }
        query_.strings.push_back(idAt(i));
        query_.start.push_back(&s.x_prev);
        query_.predicted.push_back(&s.x);
        query_.radius.push_back(&s.radius);
        query_.broken.push_back(&s.broken);
    }
    host.segments(query_, contacts_);
    for (const RigidContact& c : contacts_) {
        if (!contains(c.string)) continue;
        StringState& s = strings_[c.string.index];
        if (s.frozen || c.segment >= s.segments() || s.broken[c.segment]) continue;
        if (c.body.index >= rigids.bodies.size() || !rigids.used[c.body.index]) continue;
        if (!finite(c.normal) || !finite(c.point) || !std::isfinite(c.s) || !std::isfinite(c.friction)) continue;
        const double len = c.normal.norm();
        if (!(len > 0.5)) continue;
        // A string glued to a MOVABLE body does not collide with it: the glue already
        // moves that body in the string's solve, and a second coupling through
        // contacts would count the same body twice (a limitation: a rope cannot yet
        // wrap around the crate it holds). A static or kinematic body is no unknown,
        // so a string glued to it (a winch drum) collides with it (glue it on the
        // surface: the contacts push the rest of the string out of the body).
        if (rigids.bodies[c.body.index].inverse_mass > 0.0 && holdsBody(s.hold, c.body)) continue;
        RigidSegmentContact sc;
        sc.segment = c.segment;
        sc.s = std::clamp(c.s, 0.0, 1.0);
        sc.normal = c.normal / len;
        const RigidState& body = rigids.bodies[c.body.index];
        sc.spherical = c.spherical;
        sc.local = c.spherical ? Vec3(c.point - body.position) : Vec3(body.orientation.conjugate() * (c.point - body.position));
        sc.local_normal = c.spherical ? sc.normal : Vec3(body.orientation.conjugate() * sc.normal);
        sc.body = c.body;
        sc.friction = std::max(0.0, c.friction);
        sc.gap = s.radius[c.segment];
        const Vec3 xs = (1.0 - sc.s) * s.x[c.segment] + sc.s * s.x[c.segment + 1];
        sc.depth = std::max(0.0, -(sc.normal.dot(xs - c.point) - s.radius[c.segment]));
        // Where the step started: the string at x_prev, the body's point back along its
        // velocity (the host has moved it by h v).
        const Vec3 xs0 = (1.0 - sc.s) * s.x_prev[c.segment] + sc.s * s.x_prev[c.segment + 1];
        const Vec3 p0 = c.point - h * (body.linear_velocity + body.angular_velocity.cross(c.point - body.position));
        sc.start_depth = std::max(0.0, -(sc.normal.dot(xs0 - p0) - s.radius[c.segment]));
        // An overlap the step did not make (a string created inside a body, a body placed
        // on it) is pushed out over several steps, a fraction a step (Bullet's contact ERP
        // for bodies, 0.2), not in one: all at once would stretch the string past its
        // rupture and fling it out at depth / h. Shallower overlaps, the contacts' own give
        // under load (F / k_c, micrometres), keep the exact constraint. A body added since
        // the last step was placed where the step starts: its deep overlaps are such starts.
        if (c.segment < s.made_inside.size() && rigids.isFresh(c.body) && sc.start_depth > kDeepOverlap * sc.gap)
            s.made_inside[c.segment] = 1;
        if (c.segment < s.made_inside.size() && s.made_inside[c.segment] && sc.start_depth > kDeepOverlap * sc.gap)
            sc.gap -= (1.0 - kOverlapRecovery) * sc.start_depth;
        if (repeatsEndContact(s, sc)) continue;
        const std::int32_t taken = rememberFriction(s, sc);
        if (rigids.movable(c.body)) {
            int node = -1;
            for (std::size_t b = 0; b < s.body_nodes.size(); ++b)
                if (s.body_nodes[b].body == c.body) node = static_cast<int>(b);
            if (node < 0) {
                s.body_nodes.emplace_back(c.body);
                s.scratch.node_step.resize(s.body_nodes.size());
                node = static_cast<int>(s.body_nodes.size() - 1);
            }
            sc.node = node;
        }
        s.contacts.push_back(sc);
        s.scratch.memory_taken.push_back(taken);
    }
    // The memory is this step's now (finishChain writes the next).
    for (StringState& s : strings_) {
        if (!s.contact_memory.empty()) shareRememberedFriction(s);
        s.contact_memory.clear();
    }
    eachLive([&](StringState& s) {
        std::vector<std::uint8_t>& inside = s.made_inside;
        if (inside.size() != s.segments()) inside.assign(s.segments(), 0);
        if (std::find(inside.begin(), inside.end(), 1) == inside.end()) return;
        std::vector<std::uint8_t> buried;
        exemptBuriedEnds(s, buried);
        // Segments clear of every body (no deep overlap where the step started, and not
        // in a buried run) are done with their start.
        std::vector<std::uint8_t> deep(inside.size(), 0);
        // A contact at a particle (s = 0 or 1) stands for both segments that share it
        // (which of the two a host names may change from step to step).
        for (const RigidSegmentContact& c : s.contacts) {
            if (!(c.start_depth > kDeepOverlap * s.radius[c.segment])) continue;
            deep[c.segment] = 1;
            if (c.s == 0.0 && c.segment > 0) deep[c.segment - 1] = 1;
            if (c.s == 1.0 && c.segment + 1 < deep.size()) deep[c.segment + 1] = 1;
        }
        for (std::size_t j = 0; j < inside.size(); ++j) inside[j] = inside[j] && (deep[j] || buried[j]);
    });
    reportStartOverlaps(ctx, events);
}

/// One Overlap event per string and body, at the first step a start overlap with that
/// body is pushed out (the contacts left after exemptBuriedEnds: a buried run next to a
/// hold is meant to overlap and is not reported), naming its deepest segment.
void StringSystem::reportStartOverlaps(const StepContext& ctx, std::vector<Event>& events) {
    for (const std::uint32_t i : live_) {
        StringState& s = strings_[i];
        if (s.contacts.empty() || std::find(s.made_inside.begin(), s.made_inside.end(), 1) == s.made_inside.end()) continue;
        const std::size_t first = events.size();
        for (const RigidSegmentContact& c : s.contacts) {
            if (!s.made_inside[c.segment] || !(c.start_depth > kDeepOverlap * s.radius[c.segment])) continue;
            if (std::find(s.overlap_reported.begin(), s.overlap_reported.end(), c.body) != s.overlap_reported.end()) continue;
            auto same = std::find_if(events.begin() + static_cast<std::ptrdiff_t>(first), events.end(),
                                     [&](const Event& e) { return e.rigid == c.body; });
            if (same == events.end()) {
                Event e;
                e.type = EventType::Overlap;
                e.string = idAt(i);
                e.object = s.desc.name;
                e.rigid = c.body;
                e.time = ctx.time;
                e.step = ctx.step;
                events.push_back(e);
                same = events.end() - 1;
            }
            if (c.start_depth > same->depth) {
                same->depth = c.start_depth;
                same->segment = static_cast<int>(c.segment);
            }
        }
        for (std::size_t k = first; k < events.size(); ++k) s.overlap_reported.push_back(events[k].rigid);
    }
}



/// Strain limiting. Strings that neither hold nor touch a movable body are solved alone
/// (their solve is exact), in parallel. Those that do are members of islands, each island
/// solved as one system with its bodies (src/island/, through ctx.islands); without an
/// island solve, each alone in turn. The rest (holding only bodies that do not move) are
/// solved alone in order. prepareStrainLimit touches bodies only for glued particles:
/// strings that hold none are prepared in parallel.
void StringSystem::limitStrain(RigidTable& rigids, const StepContext& ctx) {
    eachLive([&](StringState& s) {
        if (ownsNothing(s)) prepareStrainLimit(s, rigids, ctx);
    });
    own_.clear();
    is_own_.assign(strings_.size(), 0);
    used_members_ = 0;
    for (std::size_t i = 0; i < strings_.size(); ++i) {
        StringState& s = strings_[i];
        if (!live(s)) continue;
        const bool owns_nothing = ownsNothing(s);
        if (!owns_nothing) prepareStrainLimit(s, rigids, ctx);
        if (!touchesMovableBody(s) && owns_nothing) {
            own_.push_back(static_cast<std::uint32_t>(i));
            is_own_[i] = 1;
        }
    }
    pool_->forEach(own_.size(), [&](std::size_t k) { detail::limitStrain(strings_[own_[k]], rigids, ctx); });
    in_island_.assign(strings_.size(), 0);
    for (std::size_t i = 0; i < strings_.size(); ++i) {
        StringState& s = strings_[i];
        if (!live(s) || is_own_[i]) continue;
        if (ctx.islands && touchesMovableBody(s)) {
            if (members_.size() == used_members_) members_.emplace_back();
            members_[used_members_++].start(s, rigids, ctx);
            in_island_[i] = 1;
        } else {
            detail::limitStrain(s, rigids, ctx);
        }
    }
    if (used_members_ > 0 || (ctx.islands && ctx.islands->hasOwnMembers())) {
        member_list_.clear();
        for (std::size_t k = 0; k < used_members_; ++k) member_list_.push_back(&members_[k]);
        if (ctx.settings->string_collisions && ctx.settings->island_string_contacts && used_members_ > 0)
            island_start_ = rigids.bodies;
        ctx.islands->solve(member_list_, rigids, ctx);
    }
    eachLive([&](StringState& s) { clampTravel(s, ctx); });
}

/// Strings that touch each other where one of them is in an island
/// (WorldSettings::island_string_contacts): the islands are solved again, each such
/// cluster one member (ClusterIslandMember) in place of its strings', so that the bodies
/// move with the strings' contacts instead of being held still in the joint solve. The
/// solve starts where the first one ended (its bodies' displacements, IslandSolve::restart;
/// the strings where it left them), not warm (the warm start reads each string's last
/// correction, which the first solve overwrote). Where it does not converge it is undone
/// and the clusters take the joint solve with the bodies held.
void StringSystem::solveCoupledClusters(RigidTable& rigids, const StepContext& ctx) {
    if (used_members_ == 0 || !ctx.islands || !ctx.settings->island_string_contacts) return;
    kept_mark_.assign(strings_.size(), 0);
    pairs_.markCoupled(kept_mark_);
    if (std::find(kept_mark_.begin(), kept_mark_.end(), 1) == kept_mark_.end()) return;
    StepContext cold = ctx;
    cold.cold_strain_starts = true;
    // The first solve's outcome, for a solve again that does not converge: the strings it
    // may change (the islands' and the clusters'), the bodies and the islands' own.
    for (std::size_t k = 0; k < used_members_; ++k) kept_mark_[static_cast<std::size_t>(&members_[k].string() - strings_.data())] = 1;
    std::size_t kept = 0;
    for (std::size_t i = 0; i < strings_.size(); ++i) {
        if (!kept_mark_[i]) continue;
        if (kept_strings_.size() == kept) kept_strings_.emplace_back();
        kept_strings_[kept].first = i;
        kept_strings_[kept++].second = strings_[i];
    }
    first_bodies_ = rigids.bodies;
    ctx.islands->keepOutcome();
    in_cluster_.assign(strings_.size(), 0);
    const std::vector<IslandMember*>& coupled = pairs_.startCoupled(rigids, cold, in_cluster_);
    if (coupled.empty()) return;
    rigids.bodies = island_start_;
    ctx.islands->restart();
    member_list_.clear();
    for (std::size_t k = 0; k < used_members_; ++k) {
        StringState& s = members_[k].string();
        if (in_cluster_[static_cast<std::size_t>(&s - strings_.data())]) continue;
        members_[k].start(s, rigids, cold);
        member_list_.push_back(&members_[k]);
    }
    member_list_.insert(member_list_.end(), coupled.begin(), coupled.end());
    ctx.islands->solve(member_list_, rigids, cold);
    if (ctx.islands->converged()) {
        pairs_.finishCoupled();
    } else {
        // Undone: the strings and bodies as the first solve left them, the clusters solved
        // with the bodies held (momentum leaks there, docs/island-plan.md).
        for (std::size_t k = 0; k < kept; ++k) strings_[kept_strings_[k].first] = kept_strings_[k].second;
        rigids.bodies = first_bodies_;
        ctx.islands->restoreOutcome();
        pairs_.solveCoupledHeld(rigids, ctx);
    }
    eachLive([&](StringState& s) { clampTravel(s, ctx); });
}

void StringSystem::solveTwist(RigidTable& rigids, const StepContext& ctx) {
    pool_->forEach(own_.size(), [&](std::size_t k) { detail::solveTwist(strings_[own_[k]], rigids, ctx); });
    for (std::size_t i = 0; i < strings_.size(); ++i)
        if (live(strings_[i]) && !is_own_[i]) detail::solveTwist(strings_[i], rigids, ctx);
}

void StringSystem::estimateTension(const StepContext& ctx) {
    eachLive([&](StringState& s) { detail::estimateTension(s, ctx); });
}

/// Each string's response is its own; its events are collected per string and appended
/// in string order (the order of a serial loop).
void StringSystem::respondMaterial(const StepContext& ctx, std::vector<Event>& events) {
    if (live_events_.size() < live_.size()) live_events_.resize(live_.size());
    pool_->forEach(live_.size(), [&](std::size_t k) {
        live_events_[k].clear();
        detail::respondMaterial(strings_[live_[k]], idAt(live_[k]), ctx, live_events_[k]);
    });
    for (std::size_t k = 0; k < live_.size(); ++k) events.insert(events.end(), live_events_[k].begin(), live_events_[k].end());
}

/// Twist forces and velocities; a string left non-finite is frozen at the start of the
/// step (a non-finite start at the origin).
void StringSystem::updateVelocities(const StepContext& ctx, std::vector<Event>& events) {
    bad_state_.assign(live_.size(), 0);
    pool_->forEach(live_.size(), [&](std::size_t k) {
        StringState& s = strings_[live_[k]];
        computeTwistForces(s);
        detail::updateVelocities(s, ctx);
        // A long string alone checks and clears its particles on the pool (forRanges).
        bad_state_[k] = forRangesAny(pool_, s.particles(), kParallelItems, [&](std::size_t p0, std::size_t p1) {
            bool ok = true;
            for (std::size_t p = p0; p < p1 && ok; ++p) ok = finite(s.x[p]) && finite(s.v[p]);
            std::fill(s.force.begin() + static_cast<std::ptrdiff_t>(p0), s.force.begin() + static_cast<std::ptrdiff_t>(p1), Vec3::Zero());
            return !ok;
        });
    });
    for (std::size_t k = 0; k < live_.size(); ++k) {
        if (!bad_state_[k]) continue;
        StringState& s = strings_[live_[k]];
        for (std::size_t p = 0; p < s.particles(); ++p) {
            if (!finite(s.x_prev[p])) s.x_prev[p].setZero();
            s.x[p] = s.x_prev[p];
        }
        std::fill(s.tension.begin(), s.tension.end(), 0.0);
        Event e = freezeNonFinite(s.v, s.frozen, s.desc.name, ctx);
        e.string = idAt(live_[k]);
        events.push_back(e);
    }
}

}  // namespace tearables::detail
