// The core world: owns the strings, runs the stages of a step in a fixed order
// (DESIGN.md, "How a step flows"), times them and collects events.
#include "tearables/world.hpp"

#include "collision/grid.hpp"
#include "string/string_state.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>

namespace tearables {

using detail::ParticleHold;
using detail::RigidTable;
using detail::StepContext;
using detail::StringState;

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

constexpr double kPi = 3.14159265358979323846;
/// Coulomb friction between strings (fibre on fibre, dry nylon and cotton: about 0.2-0.4).
constexpr double kStringFriction = 0.3;

using Clock = std::chrono::steady_clock;

double seconds(Clock::time_point a, Clock::time_point b) { return std::chrono::duration<double>(b - a).count(); }

/// One particle of a string, by a possibly negative index.
int resolveIndex(int particle, std::size_t count, const char* field) {
    const int n = static_cast<int>(count);
    if (particle < -n || particle >= n)
        throw InvalidInput(field, "particle index " + std::to_string(particle) + " out of range (the string has " +
                                      std::to_string(n) + " particles)");
    return particle < 0 ? particle + n : particle;
}

double vary(std::mt19937_64& rng, double value, double variation) {
    if (variation <= 0.0) return value;
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    return value * (1.0 + variation * u(rng));
}

bool finite(const Vec3& v) { return std::isfinite(v.x()) && std::isfinite(v.y()) && std::isfinite(v.z()); }

/// True when the string is glued to, or touches, a body that moves.
bool touchesMovableBody(const StringState& s) {
    return !s.body_nodes.empty() || std::find(s.glue_movable.begin(), s.glue_movable.end(), 1) != s.glue_movable.end();
}

}  // namespace

struct World::Impl {
    WorldSettings settings;
    std::vector<StringState> strings;
    RigidTable rigids;
    std::vector<Event> events;
    std::vector<Event> pending;  // emitted between steps, reported with the next step
    StageTimes last;
    ContactProvider* contact_provider = nullptr;
    detail::SegmentGrid grid;
    std::vector<Vec3> grid_positions;
    std::vector<detail::CollisionSegment> grid_segments;
    std::vector<std::pair<std::uint32_t, std::uint32_t>> grid_owner;  // per grid particle: string, particle
    std::vector<detail::SegmentPair> grid_pairs;
    std::vector<RigidContact> contacts;
    CollisionQuery query;
    double time = 0.0;
    std::int64_t steps = 0;

    StringState& get(StringId id) {
        if (id.index >= strings.size() || !strings[id.index].alive) throw InvalidInput("string", "no such string");
        return strings[id.index];
    }
    const StringState& get(StringId id) const {
        if (id.index >= strings.size() || !strings[id.index].alive) throw InvalidInput("string", "no such string");
        return strings[id.index];
    }
    RigidState& body(RigidId id) {
        if (id.index >= rigids.bodies.size() || !rigids.used[id.index]) throw InvalidInput("body", "no such rigid body");
        return rigids.bodies[id.index];
    }

    void release(StringState& s, StringId id, std::size_t p, EventCause cause) {
        if (s.hold[p].kind == ParticleHold::Kind::Free) return;
        s.hold[p] = ParticleHold{};
        Event e;
        e.type = EventType::Release;
        e.cause = cause;
        e.string = id;
        e.object = s.desc.name;
        e.particle = static_cast<int>(p);
        e.time = time;
        e.step = steps;
        pending.push_back(e);
    }

    /// Asks the host for contacts on the predicted positions and hands each string its own,
    /// checked (a bad contact from the host is dropped, never trusted).
    void collectContacts(const StepContext& ctx) {
        query.strings.clear();
        query.start.clear();
        query.predicted.clear();
        query.radius.clear();
        query.broken.clear();
        for (std::size_t i = 0; i < strings.size(); ++i) {
            const StringState& s = strings[i];
            if (!s.alive || s.frozen) continue;
            query.strings.push_back(StringId{static_cast<std::uint32_t>(i)});
            query.start.push_back(&s.x_prev);
            query.predicted.push_back(&s.x);
            query.radius.push_back(&s.radius);
            query.broken.push_back(&s.broken);
        }
        try {
            contact_provider->findContacts(query, contacts);
        } catch (...) {
            contacts.clear();  // the host failed: no contacts this step rather than a broken step
        }
        (void)ctx;
        for (const RigidContact& c : contacts) {
            if (c.string.index >= strings.size() || !strings[c.string.index].alive) continue;
            StringState& s = strings[c.string.index];
            if (s.frozen || c.segment >= s.segments() || s.broken[c.segment]) continue;
            if (c.body.index >= rigids.bodies.size() || !rigids.used[c.body.index]) continue;
            if (!finite(c.normal) || !finite(c.point) || !std::isfinite(c.s) || !std::isfinite(c.friction)) continue;
            const double len = c.normal.norm();
            if (!(len > 0.5)) continue;
            // A string does not collide with a body it is glued to: the glue already moves
            // that body in the string's solve, and a second coupling through contacts would
            // count the same body twice (a limitation: a rope cannot yet wrap around the
            // crate it holds).
            bool glued = false;
            for (const ParticleHold& hold : s.hold)
                glued = glued || (hold.kind == ParticleHold::Kind::Glue && hold.body == c.body);
            if (glued) continue;
            detail::SegmentContact sc;
            sc.segment = c.segment;
            sc.s = std::clamp(c.s, 0.0, 1.0);
            sc.normal = c.normal / len;
            const RigidState& body = rigids.bodies[c.body.index];
            sc.local = body.orientation.conjugate() * (c.point - body.position);
            sc.body = c.body;
            sc.friction = std::max(0.0, c.friction);
            sc.gap = s.radius[c.segment];
            const Vec3 xs = (1.0 - sc.s) * s.x[c.segment] + sc.s * s.x[c.segment + 1];
            sc.depth = std::max(0.0, -(sc.normal.dot(xs - c.point) - s.radius[c.segment]));
            if (rigids.movable(c.body)) {
                int node = -1;
                for (std::size_t b = 0; b < s.body_nodes.size(); ++b)
                    if (s.body_nodes[b].body == c.body) node = static_cast<int>(b);
                if (node < 0) {
                    s.body_nodes.emplace_back(c.body);
                    s.node_step.resize(s.body_nodes.size());
                    node = static_cast<int>(s.body_nodes.size() - 1);
                }
                sc.node = node;
            }
            s.contacts.push_back(sc);
        }
    }

    /// String-string and self collision (Strings Sec. 6): capsules per segment, pairs from
    /// the 27-cell grid (exact; the paper's 7-cell search misses pairs, see grid.hpp) on
    /// the predicted positions. Each side of a pair gets a contact against the other's
    /// closest point held fixed for the step, clearing its mass-weighted share of the
    /// overlap (the paper moves both segments' ends "by the fractions s and t").
    void collectStringContacts() {
        grid_positions.clear();
        grid_segments.clear();
        grid_owner.clear();
        double travel = 0.0;
        std::vector<std::uint32_t> base(strings.size(), 0);
        for (std::size_t i = 0; i < strings.size(); ++i) {
            const StringState& s = strings[i];
            if (!s.alive || s.frozen) continue;
            base[i] = static_cast<std::uint32_t>(grid_positions.size());
            for (std::size_t p = 0; p < s.particles(); ++p) {
                grid_positions.push_back(s.x_prev[p]);  // pairs from the start of the step (speculative)
                grid_owner.emplace_back(static_cast<std::uint32_t>(i), static_cast<std::uint32_t>(p));
                travel = std::max(travel, (s.x[p] - s.x_prev[p]).norm());
            }
            for (std::size_t j = 0; j < s.segments(); ++j) {
                detail::CollisionSegment seg;
                seg.a = base[i] + static_cast<std::uint32_t>(j);
                seg.b = seg.a + 1;
                seg.chain = static_cast<std::uint32_t>(i);
                seg.index_in_chain = static_cast<std::uint32_t>(j);
                seg.radius = s.radius[j];
                seg.skip = s.broken[j] != 0;
                grid_segments.push_back(seg);
            }
        }
        if (grid_segments.size() < 2) return;
        double shortest_radius = 1e300, thickest = 0.0, shortest_segment = 1e300;
        for (const auto& seg : grid_segments) {
            shortest_radius = std::min(shortest_radius, seg.radius);
            thickest = std::max(thickest, seg.radius);
        }
        for (const StringState& s : strings)
            if (s.alive && !s.frozen) shortest_segment = std::min(shortest_segment, s.shortest_rest);
        // Pairs that can meet during the step: found at the start positions within what
        // both can travel (speculative, like the rigid contacts), judged at the predicted.
        const double margin = 0.5 * shortest_radius + 2.0 * travel;
        // Segments of one string closer along it than the capsules are thick always touch
        // their neighbours: those pairs are not collisions (a straight rope of short, thick
        // segments would push itself apart along its axis).
        const auto skip = static_cast<std::uint32_t>(1.0 + std::ceil((2.0 * thickest + margin) / shortest_segment));
        const double cell = detail::requiredCellSize(grid_positions.data(), grid_positions.size(), grid_segments, margin);
        grid.findPairs(grid_positions.data(), grid_positions.size(), grid_segments, cell, margin,
                       detail::NeighbourSearch::TwentySeven, grid_pairs, skip);
        for (const detail::SegmentPair& pair : grid_pairs) {
            const detail::CollisionSegment& a = grid_segments[pair.first];
            const detail::CollisionSegment& b = grid_segments[pair.second];
            StringState& sa = strings[a.chain];
            StringState& sb = strings[b.chain];
            const std::size_t ja = a.index_in_chain, jb = b.index_in_chain;
            auto point_inverse_mass = [](const StringState& s, std::size_t j, double t) {
                const double w0 = s.hold[j].kind == ParticleHold::Kind::Free ? s.inv_mass[j] : 0.0;
                const double w1 = s.hold[j + 1].kind == ParticleHold::Kind::Free ? s.inv_mass[j + 1] : 0.0;
                return (1.0 - t) * (1.0 - t) * w0 + t * t * w1;
            };
            const double wa = point_inverse_mass(sa, ja, pair.s);
            const double wb = point_inverse_mass(sb, jb, pair.t);
            if (!(wa + wb > 0.0)) continue;
            // The normal from the start of the step; the overlap along it at the prediction.
            const Vec3 pa = (1.0 - pair.s) * sa.x[ja] + pair.s * sa.x[ja + 1];
            const Vec3 pb = (1.0 - pair.t) * sb.x[jb] + pair.t * sb.x[jb + 1];
            // Deep overlaps already there at the start (strings created through each
            // other, a pin that jumped) are undone over several steps, at most half the
            // capsules' thickness per step; an approach is stopped at once.
            const double thickness = a.radius + b.radius;
            const double residual = std::max(0.0, (thickness - pair.distance) - 0.5 * thickness);
            const double overlap = thickness - pair.normal.dot(pa - pb) - residual;
            auto add = [&](StringState& s, std::size_t j, double t, const Vec3& point, const Vec3& normal, double share) {
                detail::SegmentContact c;
                c.segment = static_cast<std::uint32_t>(j);
                c.s = t;
                c.normal = normal;
                c.local = point;  // a fixed point: the body stays invalid
                c.gap = share * overlap;
                c.friction = kStringFriction;
                c.depth = std::max(0.0, overlap * share);
                s.contacts.push_back(c);
                s.colliding[j] = s.colliding[j + 1] = 1;
            };
            add(sa, ja, pair.s, pa, pair.normal, wa / (wa + wb));
            add(sb, jb, pair.t, pb, -pair.normal, wb / (wa + wb));
        }
    }

    void freeze(StringState& s, StringId id, const StepContext& ctx) {
        for (std::size_t p = 0; p < s.particles(); ++p) {
            if (!finite(s.x_prev[p])) s.x_prev[p].setZero();
            s.x[p] = s.x_prev[p];
            s.v[p].setZero();
        }
        std::fill(s.tension.begin(), s.tension.end(), 0.0);
        s.frozen = true;
        Event e;
        e.type = EventType::Freeze;
        e.cause = EventCause::NonFinite;
        e.string = id;
        e.object = s.desc.name;
        e.time = ctx.time;
        e.step = ctx.step;
        events.push_back(e);
    }
};

World::World(const WorldSettings& settings) : impl_(std::make_unique<Impl>()) {
    validate(settings);
    impl_->settings = settings;
}

World::~World() = default;

StringId World::addString(const StringDesc& desc) {
    validate(desc);
    StringState s;
    s.desc = desc;
    const std::size_t n = desc.points.size();
    const std::size_t m = n - 1;
    s.x = desc.points;
    s.v.assign(n, Vec3::Zero());
    s.x_prev = s.x;
    s.x_pred = s.x;
    s.force.assign(n, Vec3::Zero());
    s.mass.assign(n, 0.0);
    s.hold.assign(n, ParticleHold{});
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
        detail::SegmentMaterial& sm = s.material[j];
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
    s.dir.resize(m);
    for (std::size_t j = 0; j < m; ++j) s.dir[j] = (s.x[j + 1] - s.x[j]) / s.rest_length[j];
    s.diag.assign(m, 0.0);
    s.off.assign(m, 0.0);
    s.rhs.assign(m, 0.0);
    s.scratch.assign(m, 0.0);
    s.violation.assign(m, 0.0);
    s.impulse.assign(m, 0.0);
    s.active.assign(m, 0);
    s.blk_diag.assign(n, Mat3::Zero());
    s.blk_off.assign(n, Mat3::Zero());
    s.blk_rhs.assign(n, Vec3::Zero());
    s.blk_factor_gain.assign(n, Mat3::Zero());
    s.blk_factor.resize(n);
    s.row_projector.assign(n, Mat3::Identity());
    s.colliding.assign(n, 0);
    s.spring_force.assign(m, 0.0);
    s.prev_stretch.assign(m, 0.0);
    s.rest_direction.resize(m);
    for (std::size_t j = 0; j < m; ++j) s.rest_direction[j] = (desc.points[j + 1] - desc.points[j]) / s.rest_length[j];
    s.rest_shape.assign(n, Vec3::Zero());
    s.csm_goal.assign(n, Vec3::Zero());
    s.csm_mass = s.mass;
    detail::updateRestShape(s);
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
    detail::updateTwistStiffness(s);
    s.shortest_rest = *std::min_element(s.rest_length.begin(), s.rest_length.end());

    // Reuse a free slot so ids stay small; the order of strings is the slot order.
    for (std::size_t i = 0; i < impl_->strings.size(); ++i)
        if (!impl_->strings[i].alive) {
            impl_->strings[i] = std::move(s);
            return StringId{static_cast<std::uint32_t>(i)};
        }
    impl_->strings.push_back(std::move(s));
    return StringId{static_cast<std::uint32_t>(impl_->strings.size() - 1)};
}

void World::removeString(StringId id) {
    StringState& s = impl_->get(id);
    s = StringState{};
    s.alive = false;
}

std::vector<StringId> World::strings() const {
    std::vector<StringId> ids;
    for (std::size_t i = 0; i < impl_->strings.size(); ++i)
        if (impl_->strings[i].alive) ids.push_back(StringId{static_cast<std::uint32_t>(i)});
    return ids;
}

bool World::contains(StringId id) const { return id.index < impl_->strings.size() && impl_->strings[id.index].alive; }

int World::resolveParticle(StringId id, int particle) const {
    return resolveIndex(particle, impl_->get(id).particles(), "particle");
}

void World::attachToPoint(StringId id, int particle, const Vec3& point) {
    StringState& s = impl_->get(id);
    const int p = resolveIndex(particle, s.particles(), "particle");
    if (!finite(point)) throw InvalidInput("point", "must be finite");
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
    StringState& s = impl_->get(id);
    const int p = resolveIndex(particle, s.particles(), "particle");
    const RigidState& b = impl_->body(body);
    if (!finite(local_point)) throw InvalidInput("local", "must be finite");
    s.hold[p].kind = ParticleHold::Kind::Glue;
    s.hold[p].point = local_point;
    s.hold[p].body = body;
    s.x[p] = detail::gluePoint(b, local_point);
}

void World::movePin(StringId id, int particle, const Vec3& point) {
    StringState& s = impl_->get(id);
    const int p = resolveIndex(particle, s.particles(), "particle");
    if (s.hold[p].kind != ParticleHold::Kind::Pin) throw InvalidInput("particle", "is not pinned to a world point");
    if (!finite(point)) throw InvalidInput("point", "must be finite");
    s.hold[p].point = point;
}

void World::detach(StringId id, int particle) {
    StringState& s = impl_->get(id);
    const int p = resolveIndex(particle, s.particles(), "particle");
    impl_->release(s, id, static_cast<std::size_t>(p), EventCause::Request);
}

bool World::isAttached(StringId id, int particle) const {
    const StringState& s = impl_->get(id);
    return s.hold[resolveIndex(particle, s.particles(), "particle")].kind != ParticleHold::Kind::Free;
}

bool World::pinTarget(StringId id, int particle, Vec3* point) const {
    const StringState& s = impl_->get(id);
    const ParticleHold& hold = s.hold[resolveIndex(particle, s.particles(), "particle")];
    if (hold.kind != ParticleHold::Kind::Pin) return false;
    if (point) *point = hold.point;
    return true;
}

void World::turnEnd(StringId id, int end, double angle) {
    StringState& s = impl_->get(id);
    if (end != 0 && end != -1) throw InvalidInput("end", "must be 0 (first) or -1 (last), got " + std::to_string(end));
    const std::size_t p = end == 0 ? 0 : s.particles() - 1;
    if (s.hold[p].kind != ParticleHold::Kind::Pin)
        throw InvalidInput("end", "is not clamped: pin its particle to a point before turning it");
    if (!std::isfinite(angle)) throw InvalidInput("angle", "must be finite");
    s.end_twist[end == 0 ? 0 : 1] += angle;
}

double World::endTwist(StringId id, int end) const {
    const StringState& s = impl_->get(id);
    if (end != 0 && end != -1) throw InvalidInput("end", "must be 0 (first) or -1 (last), got " + std::to_string(end));
    return s.end_twist[end == 0 ? 0 : 1];
}

void World::applyForce(StringId id, int particle, const Vec3& force) {
    StringState& s = impl_->get(id);
    const int p = resolveIndex(particle, s.particles(), "particle");
    if (!finite(force)) throw InvalidInput("force", "must be finite");
    s.force[p] += force;
}

RigidId World::addRigid(const RigidState& state) {
    if (!finite(state.position) || !std::isfinite(state.inverse_mass) || state.inverse_mass < 0.0 ||
        !state.inverse_inertia_local.allFinite() || !state.orientation.coeffs().allFinite())
        throw InvalidInput("body", "rigid state must be finite with a non-negative inverse mass");
    RigidTable& t = impl_->rigids;
    for (std::size_t i = 0; i < t.bodies.size(); ++i)
        if (!t.used[i]) {
            t.bodies[i] = state;
            t.used[i] = 1;
            return RigidId{static_cast<std::uint32_t>(i)};
        }
    t.bodies.push_back(state);
    t.used.push_back(1);
    t.start_position.emplace_back(Vec3::Zero());
    t.start_orientation.emplace_back(Quat::Identity());
    return RigidId{static_cast<std::uint32_t>(t.bodies.size() - 1)};
}

RigidState& World::rigid(RigidId id) { return impl_->body(id); }
const RigidState& World::rigid(RigidId id) const { return const_cast<Impl&>(*impl_).body(id); }

void World::removeRigid(RigidId id) {
    impl_->body(id);
    for (std::size_t i = 0; i < impl_->strings.size(); ++i) {
        StringState& s = impl_->strings[i];
        if (!s.alive) continue;
        for (std::size_t p = 0; p < s.particles(); ++p)
            if (s.hold[p].kind == ParticleHold::Kind::Glue && s.hold[p].body == id)
                impl_->release(s, StringId{static_cast<std::uint32_t>(i)}, p, EventCause::BodyRemoved);
    }
    impl_->rigids.used[id.index] = 0;
    impl_->rigids.bodies[id.index].present = false;
}

bool World::rigidInUse(RigidId id) const {
    for (const StringState& s : impl_->strings) {
        if (!s.alive) continue;
        for (const ParticleHold& hold : s.hold)
            if (hold.kind == ParticleHold::Kind::Glue && hold.body == id) return true;
    }
    return false;
}

void World::step(double h) {
    Impl& w = *impl_;
    w.events.clear();
    w.events.swap(w.pending);
    if (!(h > 0.0) || !std::isfinite(h)) return;  // refused: nothing changes

    StepContext ctx;
    ctx.h = h;
    ctx.inv_h = 1.0 / h;
    ctx.gravity = w.settings.gravity;
    ctx.settings = &w.settings;
    ctx.time = w.time + h;
    ctx.step = w.steps + 1;

    RigidTable& rigids = w.rigids;
    for (std::size_t i = 0; i < rigids.bodies.size(); ++i) {
        rigids.bodies[i].impulse.setZero();
        rigids.start_position[i] = rigids.bodies[i].position;
        rigids.start_orientation[i] = rigids.bodies[i].orientation;
    }

    StageTimes& t = w.last;
    t = StageTimes{};
    auto live = [](const StringState& s) { return s.alive && !s.frozen; };

    auto t0 = Clock::now();
    for (StringState& s : w.strings)
        if (live(s)) detail::shapeMatch(s);
    auto t0b = Clock::now();
    t.shape_matching = seconds(t0, t0b);

    for (StringState& s : w.strings)
        if (live(s)) detail::predict(s, rigids, ctx);
    auto t1 = Clock::now();
    t.predict = seconds(t0b, t1);

    // Collision with rigid bodies: the host's narrow phase on the predicted positions.
    for (StringState& s : w.strings) {
        s.contacts.clear();
        s.body_nodes.clear();
        std::fill(s.row_projector.begin(), s.row_projector.end(), Mat3::Identity());
        std::fill(s.colliding.begin(), s.colliding.end(), 0);
    }
    w.contacts.clear();
    if (w.contact_provider && w.settings.rigid_contacts) w.collectContacts(ctx);
    if (w.settings.string_collisions) w.collectStringContacts();
    auto t1c = Clock::now();
    t.collision = seconds(t1, t1c);
    t1 = t1c;

    // Strain limiting. Strings that pull or touch a movable body are coupled through it
    // and are swept Gauss-Seidel style; the others are solved once (their solve is exact).
    bool coupled = false;
    for (StringState& s : w.strings) {
        if (!live(s)) continue;
        detail::prepareStrainLimit(s, rigids, ctx);
        coupled = coupled || touchesMovableBody(s);
    }
    const int sweeps = coupled ? w.settings.coupling_iterations : 1;
    for (int sweep = 0; sweep < sweeps; ++sweep)
        for (StringState& s : w.strings) {
            if (!live(s)) continue;
            if (sweep == 0 || touchesMovableBody(s)) detail::limitStrain(s, rigids, ctx);
        }
    auto t2 = Clock::now();
    t.strain_limit = seconds(t1, t2);

    for (StringState& s : w.strings)
        if (live(s)) detail::solveTwist(s, rigids, ctx);
    auto t2b = Clock::now();
    t.twist = seconds(t2, t2b);
    t2 = t2b;

    for (StringState& s : w.strings)
        if (live(s)) detail::estimateTension(s, ctx);
    // Friction after the tension solve: its tangential corrections are not tension.
    for (StringState& s : w.strings)
        if (live(s) && !s.contacts.empty()) detail::applyFriction(s, rigids, ctx);
    auto t3 = Clock::now();
    t.tension = seconds(t2, t3);

    for (std::size_t i = 0; i < w.strings.size(); ++i)
        if (live(w.strings[i])) detail::respondMaterial(w.strings[i], StringId{static_cast<std::uint32_t>(i)}, ctx, w.events);
    auto t4 = Clock::now();
    t.material = seconds(t3, t4);

    for (std::size_t i = 0; i < w.strings.size(); ++i) {
        StringState& s = w.strings[i];
        if (!live(s)) continue;
        detail::computeTwistForces(s);
        detail::updateVelocities(s, ctx);
        bool ok = true;
        for (std::size_t p = 0; p < s.particles() && ok; ++p) ok = finite(s.x[p]) && finite(s.v[p]);
        if (!ok) w.freeze(s, StringId{static_cast<std::uint32_t>(i)}, ctx);
        std::fill(s.force.begin(), s.force.end(), Vec3::Zero());
    }
    // Bodies moved by the strings get the matching velocity change (position-based
    // coupling: dv = dx / h, dw = dtheta / h), so Bullet carries the reaction on.
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
    auto t5 = Clock::now();
    t.velocities = seconds(t4, t5);

    w.time = ctx.time;
    w.steps = ctx.step;
}

StringView World::view(StringId id) const {
    const StringState& s = impl_->get(id);
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
    return v;
}

const StringDesc& World::desc(StringId id) const { return impl_->get(id).desc; }
const std::vector<Event>& World::events() const { return impl_->events; }
void World::setContactProvider(ContactProvider* provider) { impl_->contact_provider = provider; }
const std::vector<RigidContact>& World::lastContacts() const { return impl_->contacts; }
const StageTimes& World::lastStageTimes() const { return impl_->last; }
double World::time() const { return impl_->time; }
std::int64_t World::stepCount() const { return impl_->steps; }
WorldSettings& World::settings() { return impl_->settings; }
const WorldSettings& World::settings() const { return impl_->settings; }

}  // namespace tearables
