// The core world: owns the strings, runs the stages of a step in a fixed order
// (DESIGN.md, "How a step flows"), times them and collects events.
#include "tearables/world.hpp"

#include "cloth/cloth_state.hpp"
#include "collision/capsule.hpp"
#include "collision/grid.hpp"
#include "paper/system.hpp"
#include "base/float_mode.hpp"
#include "base/thread_pool.hpp"
#include "world/world_access.hpp"
#include "string/string_state.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <tuple>

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
/// The clean-up projection after the tension stage (finishStringContacts): at most this
/// many Gauss-Seidel sweeps, stopped once no pair overlaps by more than the tolerance
/// (fraction of its thickness).
constexpr int kStringCleanupSweeps = 8;
constexpr double kStringCleanupTolerance = 1e-3;
/// A pair whose axes are closer than this fraction of the thickness at the start of a
/// step is no contact this step: no step of the solver ends that deep, so something else
/// put it there (strings created through each other, a pin moved through a string, a
/// string pinned back onto itself), and it has no side to be pushed to (the axes may
/// even be collinear). It is left to come apart by itself and is a contact again once its
/// axes are apart by the thickness at the start of a step.
constexpr double kStringDeepStart = 0.5;
/// Axes closer than this fraction of the thickness have no reliable direction of their
/// own: the direction at the start of the step is used.
constexpr double kStringAxisContact = 1e-3;
/// Pairs are searched for with each capsule grown by its ends' travel in the step and by
/// this fraction of its radius (slack for what the joint solve changes): every pair that
/// can meet during the step is found, and no pair that cannot (one fast segment does not
/// widen the search for all, as one margin of twice the largest travel did).
constexpr double kStringReach = 1.0;
/// A pair of the swept search whose axes are farther apart after the strings' own solves
/// than (1 + this) times the thickness plus twice the relative travel of its ends in the
/// step, on their starting side, is not solved: the joint solve moves a string by about
/// that (a fast arm meeting another is deflected by a step's motion); the pairs of a
/// swinging or resting straight rope (every third segment) are dropped. Found by the tests: with no
/// travel term, 0.75 let a whipping arm through its own rope.
constexpr double kStringNear = 0.25;
/// Pairs within this fraction of the thickness of touching count as colliding.
constexpr double kStringTouchSlop = 0.1;

/// Segments of one string closer along it than the capsules are thick touch their
/// neighbours when the string is straight: segments k apart have (k - 1) L of axis
/// between them, so pairs with k <= 1 + ceil(2 r / L) are not collisions. (A property
/// of the string, not of the search margin: only true overlaps act.)
std::uint32_t stringContactSkip(double thickest_radius, double shortest_segment) {
    return static_cast<std::uint32_t>(1.0 + std::ceil(2.0 * thickest_radius / shortest_segment));
}

/// The time steps World::step takes, s: shorter ones make 1/h and the penalties overflow,
/// longer ones are no simulation.
constexpr double kMinStep = 1e-7;
constexpr double kMaxStep = 1.0;

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
    detail::ChainTree tree;
    detail::ThreadPool pool;          // independent strings' stages (WorldSettings::threads)
    std::vector<std::uint32_t> live_strings, own_strings;  // this step's live strings; those sharing no body
    std::vector<std::uint8_t> string_own;  // per string slot: in own_strings this step
    std::vector<std::uint8_t> bad_state;  // per live string: non-finite after the step
    std::vector<std::vector<Event>> string_events;  // per live string: its material events of this step
    std::vector<Vec3> grid_positions;
    std::vector<Vec3> grid_travel;  // per particle of grid_positions: x - x_prev after the strings' own solves
    std::vector<double> grid_thickness;  // per segment of grid_segments: its string's radius there
    double grid_rounding = 0.0;  // nodesSeparationNeeded's rounding margin (from the largest |x|_1)
    bool sparse_joint_steps = false;  // ClusterScratch::always_sparse (tests compare)
    bool cold_strain_starts = false;  // StepContext::cold_strain_starts (tests compare)
    bool newton_strain_only = false;  // StepContext::newton_strain_only (tests compare)
    bool node_pruning = true;    // nodesSeparationNeeded in the search (off: tests compare)
    bool straight_strings_skip = true;  // selfPairFree in the search (off: tests compare)
    bool tree_searched = false;  // the last findStringPairs ran the tree (its counters are this step's)
    std::vector<std::uint8_t> self_free;  // per live string of pair_strings: selfPairFree held
    std::vector<detail::CollisionSegment> grid_segments;
    std::vector<detail::SegmentPair> grid_pairs;
    // findStringPairs' scratch: per live string where its particles and segments start in
    // grid_positions / grid_segments (and its thickest radius, finite radii); per pair of
    // the swept search its verdict and contact.
    struct PairString {
        std::uint32_t string;
        std::size_t particle_base, segment_base;
        double thickest;
        double extent;  // largest |x|_1 and |x_prev|_1 of its particles
        bool finite;
        // selfPairFree's sums: the least advance of a segment along the string's chord at
        // the start of the step (less a rounding margin; -1 where the chord has no
        // direction), and the largest change of travel from one particle to the next.
        double advance = -1.0;
        double shear = 0.0;
    };
    std::vector<PairString> pair_strings;
    std::vector<std::uint8_t> pair_verdict;  // per pair
    std::vector<detail::SegmentContact> pair_contact;
    // String-string collision (coupleStrings): this step's pairs (global string indices,
    // sorted by string and segment), the last step's touching ones (warm start), and the
    // scratch of the clusters.
    std::vector<detail::SegmentContact> string_pairs, previous_pairs;
    struct Cluster {  // strings that touch, their pairs (cluster-local string numbers) and the pairs' indices
        std::vector<StringState*> strings;
        std::vector<detail::SegmentContact> contacts;
        std::vector<std::size_t> index;
        detail::ClusterScratch scratch;  // solveStringCluster's, kept so that a running step does not allocate
    };
    std::vector<Cluster> clusters;  // reused; the first `count` of a step are in use
    std::vector<std::uint32_t> cluster_root, cluster_local, pair_root;
    std::vector<std::size_t> cluster_first, cluster_fill, cluster_order;
    // Pairs that started a step deeper than kStringDeepStart (sorted) and have not come
    // apart since: no contacts until they have.
    using PairKey = std::tuple<std::uint32_t, std::uint32_t, std::uint32_t, std::uint32_t>;
    std::vector<PairKey> deep_pairs, deep_next;
    std::vector<std::pair<PairKey, std::uint32_t>> contact_order;  // findStringPairs' sort: key, index into pair_contact
    std::vector<RigidContact> contacts;
    CollisionQuery query;
    detail::ClothSystem cloths;  // cloth state and solvers (src/cloth/), stepped after the strings
    detail::PaperSystem papers;  // paper sheets (src/paper/), stepped after the strings
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
            // A string glued to a MOVABLE body does not collide with it: the glue already
            // moves that body in the string's solve, and a second coupling through
            // contacts would count the same body twice (a limitation: a rope cannot yet
            // wrap around the crate it holds). A static or kinematic body is no unknown,
            // so a string glued to it (a winch drum) collides with it (glue it on the
            // surface: the contacts push the rest of the string out of the body).
            bool glued = false;
            if (rigids.bodies[c.body.index].inverse_mass > 0.0)
                for (const ParticleHold& hold : s.hold)
                    glued = glued || (hold.kind == ParticleHold::Kind::Glue && hold.body == c.body);
            if (glued) continue;
            detail::SegmentContact sc;
            sc.segment = c.segment;
            sc.s = std::clamp(c.s, 0.0, 1.0);
            sc.normal = c.normal / len;
            const RigidState& body = rigids.bodies[c.body.index];
            sc.local = body.orientation.conjugate() * (c.point - body.position);
            sc.local_normal = body.orientation.conjugate() * sc.normal;
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

    /// String-string and self collision (Strings Sec. 6: every segment is a capsule, two
    /// capsules overlap when their axes come closer than the sum of the radii).
    ///
    /// Root cause of the interpenetration of the first design: each string's own solve
    /// held its contacts against the OTHER string's point FIXED at its PREDICTED position.
    /// A rope resting on a clamped rope predicts a fall of g h^2 per step; the clamped
    /// rope's solve could not rise above that point, its penalty (100x the segment
    /// stiffness) beat the rope's springs, and both fell together: the clamped rope was
    /// dragged down and stretched (tens of percent, yielding) while the free rope, which
    /// never felt the clamped rope's tension, kept its speed and finally slipped through.
    /// Sharing the predicted overlap by masses cannot fix that (in resting contact there
    /// is no predicted overlap to share), and friction against the fixed point held each
    /// rope still relative to the WORLD rather than to the other rope, shifting the
    /// contact points by millimetres per step (the largest single loss of separation).
    /// Separating the pairs after the solves instead, by a mass-weighted projection of
    /// the four ends, treats a taut rope as two free particles (a rope on a clamped rope
    /// pushed it down by half the overlap every step, 17% stretch), and a linearised
    /// coupling (the strings' Delassus operators) fails where the strings are floppy (a
    /// particle between two pins swings about their chord, to first order freely).
    ///
    /// So the strings that touch are solved together (detail::solveStringCluster): one
    /// Newton method on the sum of their energies, the contact penalties and Coulomb
    /// friction on the contact points' motion RELATIVE to each other, both sides of every
    /// contact moving with their masses, springs and tensions; momentum is exchanged, the
    /// strain limit stays exact and the step ends without overlaps. The strings' own
    /// solves run first (unchanged) and give the starting point; a cluster whose pairs
    /// they already keep apart is left as it is.
    ///
    /// Pairs come from the START positions of the step within 2x the largest travel of
    /// the step plus half a radius, so every pair that came within reach during the step
    /// (also one that passed through) is found (27-cell grid, exact); the start direction
    /// of each pair says which side is which when the axes touch or have crossed. A pair
    /// that starts the step deeper than half the thickness is not one the solver let
    /// happen (kStringDeepStart) and is left to come apart by itself. A string that hangs
    /// or swings nearly straight is proved free of self pairs from its shape (selfPairFree,
    /// one pass over its particles) and its self search is skipped: the same pairs, none.
    ///
    /// Momentum-balance tension: the particles a string contact presses lose the contact
    /// force's directions (normal, friction) from their tension equations (row_projector,
    /// as for rigid contacts); everything else the joint solve moved (a clamped rope
    /// sagging under the rope on it) is the springs' doing and counts as tension. The
    /// clean-up projection (finishStringContacts) runs after the tension stage.
    void findStringPairs() {
        string_pairs.clear();
        deep_next.clear();
        // The segments of the live strings, string after string, each string's run filled
        // on the pool (where it starts is known beforehand).
        pair_strings.clear();
        std::size_t particle_count = 0, segment_count = 0;
        for (std::size_t i = 0; i < strings.size(); ++i) {
            const StringState& s = strings[i];
            if (!s.alive || s.frozen) continue;
            pair_strings.push_back({static_cast<std::uint32_t>(i), particle_count, segment_count, 0.0, 0.0, true, -1.0, 0.0});
            particle_count += s.particles();
            segment_count += s.segments();
        }
        grid_positions.resize(particle_count);
        grid_travel.resize(particle_count);
        grid_thickness.resize(segment_count);
        grid_segments.resize(segment_count);
        // A single string is scanned for selfPairFree alone first: proved free of self
        // pairs, it needs nothing more (the search would keep none). Otherwise each
        // string's scan fills its run of the search's arrays as well.
        const bool alone = pair_strings.size() == 1;
        pool.forEach(pair_strings.size(), [&](std::size_t k) {
            if (alone)
                scanString<false>(pair_strings[k]);
            else
                scanString<true>(pair_strings[k]);
        });
        double thickest = 0.0, shortest_segment = 1e300, extent = 0.0;
        for (const PairString& ps : pair_strings) {
            thickest = std::max(thickest, ps.thickest);
            extent = std::max(extent, ps.extent);
            shortest_segment = std::min(shortest_segment, strings[ps.string].shortest_rest);
        }
        tree_searched = false;
        grid_pairs.clear();
        grid_rounding = 1e-15 * (2.0 * extent + 1.0);
        const std::uint32_t skip = stringContactSkip(thickest, shortest_segment);
        self_free.assign(pair_strings.size(), 0);
        if (straight_strings_skip)
            for (std::size_t k = 0; k < pair_strings.size(); ++k) self_free[k] = selfPairFree(pair_strings[k], skip);
        if (alone && self_free[0]) {
            deep_pairs.clear();
            return;
        }
        if (alone) scanString<true>(pair_strings[0]);
        bool finite_state = true;
        for (const PairString& ps : pair_strings) finite_state = finite_state && ps.finite;
        if (grid_segments.size() < 2 || !finite_state) {
            deep_pairs.clear();
            return;
        }
        // The swept capsules' overlaps through a box tree per string (collision/grid.hpp,
        // ChainTree): the same pairs as the exact 27-cell grid, whose cells all grow to the
        // fastest segment's swept capsule (a swinging rope's tip), at a fraction of its cost.
        // Most pairs are dropped (judgePair, on the pool in chunks; the verdicts are then
        // collected in the pairs' order); the kept ones are sorted.
        // The tree asks judgePair about each pair as it finds it and keeps only those that
        // are not dropped (a swinging rope's swept search finds thousands, nearly all of them
        // dropped: stored, they were most of the search's memory traffic).
        auto keep = [](const void* self, const detail::SegmentPair& pair) {
            // judgePair writes what it reads of the contact first: a scratch per thread,
            // not a SegmentContact (~330 bytes of defaults) built for every candidate.
            thread_local detail::SegmentContact scratch;
            return static_cast<const Impl*>(self)->judgePair(pair, scratch) != kPairDropped;
        };
        auto reject = [](const void* self, std::uint32_t i, std::uint32_t j) {
            return static_cast<const Impl*>(self)->surelyDropped(i, j);
        };
        // Whole node pairs of the tree dropped at once (nodesSeparationNeeded): a rope
        // swinging as a whole has its swept boxes overlap far along it, their relative
        // travel small.
        auto separation_needed = [](const void* self, const detail::ChainTree::NodeBounds& a,
                                    const detail::ChainTree::NodeBounds& b) {
            return static_cast<const Impl*>(self)->nodesSeparationNeeded(a, b);
        };
        const detail::ChainTree::Sweep sweep{grid_travel.data(), grid_thickness.data(), separation_needed};
        tree.findPairs(grid_positions.data(), grid_segments, 0.0, grid_pairs, skip, &pool, keep, this, reject,
                       node_pruning ? &sweep : nullptr, self_free.data());
        tree_searched = true;
        pair_verdict.resize(grid_pairs.size());
        pair_contact.resize(grid_pairs.size());
        const std::size_t chunks = std::min<std::size_t>(grid_pairs.size(), 64);
        pool.forEach(chunks, [&](std::size_t chunk) {
            const std::size_t lo = grid_pairs.size() * chunk / chunks, hi = grid_pairs.size() * (chunk + 1) / chunks;
            for (std::size_t i = lo; i < hi; ++i) pair_verdict[i] = judgePair(grid_pairs[i], pair_contact[i]);
        });
        // The contacts sorted by key (string, segment, partner, partner segment): the warm
        // start merges with the last step's pairs, and the deep pairs are binary-searched.
        // The keys are sorted with the contacts' indices and the contacts copied once, in
        // that order: sorting the ~330-byte contacts themselves, and growing string_pairs
        // by push_back, were a fifth of the step in which a 5000-segment rope tears (10^5
        // pairs). A key names one pair of segments, which the search reports once, so the
        // order is the one sorting the contacts gave.
        contact_order.clear();
        for (std::size_t i = 0; i < grid_pairs.size(); ++i) {
            const detail::SegmentContact& c = pair_contact[i];
            const PairKey key = std::make_tuple(c.string, c.segment, c.partner, c.partner_segment);
            if (pair_verdict[i] == kPairDeep) deep_next.push_back(key);
            if (pair_verdict[i] == kPairContact) contact_order.emplace_back(key, static_cast<std::uint32_t>(i));
        }
        std::sort(contact_order.begin(), contact_order.end());
        string_pairs.reserve(contact_order.size());
        for (const auto& [key, i] : contact_order) string_pairs.push_back(pair_contact[i]);
        std::sort(deep_next.begin(), deep_next.end());
        deep_pairs.swap(deep_next);
    }

    /// Scans a live string for the search: its largest |x|_1 and |x_prev|_1 (ps.extent),
    /// thickest radius, and selfPairFree's sums: the least advance of a segment along the
    /// unit chord u of the start positions, d . u - 1e-14 |d|_1 (d = x_prev[j+1] - x_prev[j];
    /// -1 where the chord has no direction or a segment does not advance), and the largest
    /// |t_{j+1} - t_j| of the travels t = x - x_prev, times 1 + 1e-12. With `fill`, also its
    /// run of grid_positions (the start positions), grid_travel (t), grid_segments (each
    /// capsule at the start, grown by its ends' travel) and grid_thickness, and ps.finite.
    /// A long string's particles in ranges on the pool (each writes its own entries; the
    /// least, largest and finiteness do not depend on the cut). A NaN makes the sums fail
    /// the test, not vanish from it.
    template <bool fill>
    void scanString(PairString& ps) {
        const StringState& s = strings[ps.string];
        const std::size_t n = s.particles();
        const Vec3 chord = s.x_prev.back() - s.x_prev.front();
        const double chord_length = chord.norm();
        const bool along_chord = chord_length > 0.0 && std::isfinite(chord_length);
        const Vec3 u = along_chord ? Vec3(chord / chord_length) : Vec3::Zero();
        struct Sums {
            double extent = 0.0, thickest = 0.0;
            double advance = std::numeric_limits<double>::infinity(), shear2 = 0.0;
            bool finite = true;
            void least(double v) { if (!(v >= advance)) advance = v; }
            void most(double v) { if (!(v <= shear2)) shear2 = v; }
        };
        Vec3* positions = grid_positions.data() + ps.particle_base;
        Vec3* moved = grid_travel.data() + ps.particle_base;
        detail::CollisionSegment* segments = grid_segments.data() + ps.segment_base;
        double* thickness = grid_thickness.data() + ps.segment_base;
        const auto base = static_cast<std::uint32_t>(ps.particle_base);
        // How far particle p travelled this step (t = x - x_prev given), to its prediction or
        // in its string's own solve (sqrt is monotone and correctly rounded: the larger of
        // the two norms, bit for bit, with one square root).
        auto travel = [&s](std::size_t p, const Vec3& t) {
            return std::sqrt(std::max(t.squaredNorm(), (s.x_pred[p] - s.x_prev[p]).squaredNorm()));
        };
        Sums range_sums[detail::kMaxRanges];
        detail::forRanges(&pool, n, detail::kParallelItems, [&](std::size_t p0, std::size_t p1, std::size_t part) {
            Sums sums;
            // The particle before's travel vector and (with `fill`) travel, carried: each
            // particle's found once, both its segments use them.
            Vec3 before = p0 > 0 ? Vec3(s.x[p0 - 1] - s.x_prev[p0 - 1]) : Vec3::Zero();
            double previous = 0.0;
            if constexpr (fill) previous = p0 > 0 ? travel(p0 - 1, before) : 0.0;
            for (std::size_t p = p0; p < p1; ++p) {
                sums.extent = std::max(sums.extent, std::max(s.x[p].cwiseAbs().sum(), s.x_prev[p].cwiseAbs().sum()));
                const Vec3 t = s.x[p] - s.x_prev[p];
                double now = 0.0;
                if constexpr (fill) {
                    now = travel(p, t);
                    positions[p] = s.x_prev[p];  // pairs from the start of the step (swept)
                    moved[p] = t;
                }
                if (p > 0) {
                    const std::size_t j = p - 1;
                    sums.thickest = std::max(sums.thickest, s.radius[j]);
                    const Vec3 d = s.x_prev[p] - s.x_prev[j];
                    sums.least(d.dot(u) - 1e-14 * d.cwiseAbs().sum());
                    sums.most((t - before).squaredNorm());
                    if constexpr (fill) {
                        detail::CollisionSegment& seg = segments[j];
                        seg.a = base + static_cast<std::uint32_t>(j);
                        seg.b = seg.a + 1;
                        seg.chain = ps.string;
                        seg.index_in_chain = static_cast<std::uint32_t>(j);
                        // The capsule at the start of the step, swept: grown by the travel
                        // of its ends, and by kStringReach of its radius for what the joint
                        // solve changes.
                        seg.radius = s.radius[j] * (1.0 + kStringReach) + std::max(previous, now);
                        seg.skip = s.broken[j] != 0;
                        thickness[j] = s.radius[j];
                        sums.finite = sums.finite && std::isfinite(seg.radius);
                    }
                }
                previous = now;
                before = t;
            }
            range_sums[part] = sums;
        });
        Sums total;
        for (const Sums& sums : range_sums) {  // (ranges not run hold the identities)
            total.extent = std::max(total.extent, sums.extent);
            total.thickest = std::max(total.thickest, sums.thickest);
            total.least(sums.advance);
            total.most(sums.shear2);
            total.finite = total.finite && sums.finite;
        }
        ps.extent = total.extent;
        ps.thickest = total.thickest;
        ps.advance = along_chord && total.advance > 0.0 ? total.advance : -1.0;
        ps.shear = std::sqrt(total.shear2) * (1.0 + 1e-12);
        ps.finite = total.finite;
    }

    /// True when judgePair would drop every pair of a string's own segments this step, by
    /// the string's shape alone (ps's sums, scanString): a rope that
    /// swings or hangs nearly straight, whose self search otherwise descends its whole
    /// tree along the diagonal (its neighbouring nodes' boxes overlap) to drop every pair.
    ///
    /// With u the unit chord of the string's start positions, every segment advancing along
    /// u by at least `advance` > 0 (less a rounding margin of 1e-14 |d|_1 per segment, far
    /// above the dot product's), segments i < j with g = j - i are separated along u, at
    /// the start, by at least (g - 1) advance (the segments between them, each forward);
    /// and the relative travel of any end of one and any end of the other is at most
    /// (g + 1) `shear` (shear: the largest |t_{k+1} - t_k| of the travels t = x - x_prev
    /// judgePair reads, with a relative 1e-12 for the norms' rounding). surelyDropped's
    /// argument (any unit direction will do) drops a pair separated by sep along u when
    /// sep > c + k r (k = 1 + 2 (1 + 1e-6)); this takes 4 for k, and for c the string's
    /// largest gap, 2 (1 + kStringNear) (1 + 1e-6) times its thickest radius, plus
    /// grid_rounding. The pairs that exist have g > skip (closer ones are never pairs), and
    /// (g - 1) advance - 4 (g + 1) shear grows with g where advance > 4 shear: so the
    /// pairs with g = skip + 1 decide for all. Such a pair is not deep either: its start
    /// distance exceeds c > the gap.
    bool selfPairFree(const PairString& ps, std::uint32_t skip) const {
        const double c = 2.0 * (1.0 + kStringNear) * ps.thickest * (1.0 + 1e-6) + grid_rounding;
        const double travel = 4.0 * ps.shear;
        const double g = static_cast<double>(skip) + 1.0;
        return ps.advance > travel && (g - 1.0) * ps.advance - (g + 1.0) * travel > c;
    }

    /// What findStringPairs makes of a pair of the swept search: no contact, a pair that
    /// is (still) deep (c's key is remembered), or a contact (c). Reads only.
    static constexpr std::uint8_t kPairDropped = 0, kPairDeep = 1, kPairContact = 2;
    std::uint8_t judgePair(const detail::SegmentPair& pair, detail::SegmentContact& c) const {
        const detail::CollisionSegment& a = grid_segments[pair.first];
        const detail::CollisionSegment& b = grid_segments[pair.second];
        // Only the key and the gap until the pair is kept (most are not).
        c.string = a.chain;
        c.segment = a.index_in_chain;
        c.partner = b.chain;
        c.partner_segment = b.index_in_chain;
        c.gap = strings[c.string].radius[c.segment] + strings[c.partner].radius[c.partner_segment];
        // Deep at the start, or still coming apart from being deep: no contact (see
        // kStringDeepStart), and remembered for the next step.
        const auto key = std::make_tuple(c.string, c.segment, c.partner, c.partner_segment);
        const bool was_deep = std::binary_search(deep_pairs.begin(), deep_pairs.end(), key);
        if (pair.distance < (was_deep ? 1.0 : kStringDeepStart) * c.gap) {
            return kPairDeep;
        }
        // Apart after the strings' own solves, by more than kStringNear of the
        // thickness and on the side they started on: no contact this step (most pairs
        // of the swept search, e.g. every third segment of a straight rope).
        const StringState& sa = strings[c.string];
        const StringState& sb = strings[c.partner];
        // Relative travel of the pair's ends over the step: the axes' distance at any
        // time of the step differs from the end's by at most this.
        double relative = 0.0;
        for (std::size_t i = c.segment; i <= c.segment + 1u; ++i)
            for (std::size_t k = c.partner_segment; k <= c.partner_segment + 1u; ++k)
                relative = std::max(relative, ((sa.x[i] - sa.x_prev[i]) - (sb.x[k] - sb.x_prev[k])).squaredNorm());
        relative = std::sqrt(relative);
        const double apart = (1.0 + kStringNear) * c.gap + 2.0 * relative;
        // Most pairs of the swept search are dropped here without their closest points:
        // when the segments are separated along the start normal n by more than
        // `apart` (every point of this side beyond every point of the other), the
        // closest points p, q have (p - q).n >= that > 0 and |p - q| >= (p - q).n, so
        // the test below would drop the pair too. A margin of 1e-6 and of the
        // positions' rounding keeps that true in floating point.
        {
            const Vec3& a0 = sa.x[c.segment];
            const Vec3& a1 = sa.x[c.segment + 1];
            const Vec3& b0 = sb.x[c.partner_segment];
            const Vec3& b1 = sb.x[c.partner_segment + 1];
            const Vec3& n = pair.normal;
            const double separation = std::min(n.dot(a0), n.dot(a1)) - std::max(n.dot(b0), n.dot(b1));
            const double rounding = 1e-15 * (a0.cwiseAbs().sum() + b0.cwiseAbs().sum() + 1.0);
            if (separation > apart * (1.0 + 1e-6) + rounding) return kPairDropped;
        }
        const detail::SegmentClosest now = detail::closestPointsOfSegments(
            sa.x[c.segment], sa.x[c.segment + 1], sb.x[c.partner_segment], sb.x[c.partner_segment + 1]);
        if (now.distance > apart && (now.p - now.q).dot(pair.normal) > 0.0) return kPairDropped;
        const double gap = c.gap;
        c = detail::SegmentContact{};
        c.string = a.chain;
        c.segment = a.index_in_chain;
        c.partner = b.chain;
        c.partner_segment = b.index_in_chain;
        c.s = pair.s;
        c.partner_s = pair.t;
        c.start_normal = pair.normal;
        c.start_distance = pair.distance;
        c.normal = pair.normal;
        c.gap = gap;
        c.friction = kStringFriction;
        return kPairContact;
    }

    /// True when judgePair would drop the pair of segments i < j (of grid_segments) for
    /// sure, decided before their closest points at the start of the step: when at the
    /// start they are separated along some unit u (here the direction between their
    /// midpoints) by sep > the relative travel r of their ends, then for every point a of
    /// one and b of the other, now, (a - b).n0 >= d0 - r > 0 (n0, d0: the start closest
    /// points' direction and distance; d0 >= sep, and the motion of a - b is a convex
    /// combination of the ends' relative motions), so the pair is on its starting side, not
    /// deep, and its axes are now at least sep - r apart. Dropped when that is beyond
    /// judgePair's distance, with a margin for rounding: judgePair would drop it too.
    ///
    /// In the arithmetic (most of a swinging rope's candidates, ~3 a segment, meet this
    /// test): with w = (a0 + a1) - (b0 + b1) (twice the midpoints' difference), L = |w|,
    /// the separation along u = w / L is (L^2 - |w.(a1 - a0)| - |w.(b1 - b0)|) / (2 L);
    /// the test sep - r > k r + c (k = 1 + 2 (1 + 1e-6), c = (1 + kStringNear) gap (1 + 1e-6)
    /// + rounding) is multiplied by 2 L and squared (both sides positive) so that it needs
    /// one square root (for L) and none for r (r^2 is the max of the squared relative
    /// travels, computed as judgePair does; a relative 1e-12 on it for the square root's
    /// rounding). The errors of the rearranged expression are of the order of
    /// 1e-16 |x|, far below the rounding term (grid_rounding >= judgePair's own).
    bool surelyDropped(std::uint32_t i, std::uint32_t j) const {
        const detail::CollisionSegment& a = grid_segments[i];
        const detail::CollisionSegment& b = grid_segments[j];
        const Vec3& a0 = grid_positions[a.a];
        const Vec3& a1 = grid_positions[a.b];
        const Vec3& b0 = grid_positions[b.a];
        const Vec3& b1 = grid_positions[b.b];
        const Vec3 w = (a0 + a1) - (b0 + b1);
        const double length2 = w.squaredNorm();
        const double length = std::sqrt(length2);
        const double c = (1.0 + kStringNear) * (grid_thickness[i] + grid_thickness[j]) * (1.0 + 1e-6) + grid_rounding;
        // 2 L (sep - c), when the pair is separated along u by more than c.
        const double room = length2 - std::abs(w.dot(a1 - a0)) - std::abs(w.dot(b1 - b0)) - 2.0 * c * length;
        if (!(room > 0.0)) return false;
        // The relative travel (squared) as judgePair computes it, from the set-up's
        // x - x_prev (the same values).
        double relative2 = 0.0;
        for (std::uint32_t pa : {a.a, a.b})
            for (std::uint32_t pb : {b.a, b.b}) relative2 = std::max(relative2, (grid_travel[pa] - grid_travel[pb]).squaredNorm());
        constexpr double k = 1.0 + 2.0 * (1.0 + 1e-6);
        return room * room > 4.0 * length2 * (k * k * (1.0 + 1e-12)) * relative2;
    }

    /// The separation along any unit direction u beyond which judgePair drops every pair of
    /// node a's segments with node b's (the tree tests it along the coordinate axes and
    /// along directions it finds, ChainTree::NodeSeparation). surelyDropped's argument for
    /// all the pairs at once: a separation sep of the nodes' start boxes (of the axes' ends,
    /// grid_positions) along u bounds every pair's separation along u from below; the
    /// travel boxes bound every end pair's relative travel: |t_a - t_b| <= |max(ta_hi -
    /// tb_lo, tb_hi - ta_lo)| (per coordinate), >= each pair's `relative`; the thicknesses
    /// bound each pair's gap. So when sep - R > (1 + kStringNear) (g_a + g_b) + 2 R, every
    /// pair meets surelyDropped's condition with its own (smaller) gap and travel, on u.
    /// The relative margins: 1e-12 on R for the order of the sums in judgePair's norms (a
    /// few ulps), 1e-6 and grid_rounding (from the largest |x|_1 of the strings' particles,
    /// start or now, >= judgePair's) as in surelyDropped; the rounding of a separation
    /// along a direction the tree finds (a dot product of positions, along a direction
    /// unit to 1e-16) is within the second grid_rounding.
    double nodesSeparationNeeded(const detail::ChainTree::NodeBounds& a, const detail::ChainTree::NodeBounds& b) const {
        const Vec3 d = (a.travel_hi - b.travel_lo).cwiseMax(b.travel_hi - a.travel_lo);
        const double relative = std::sqrt(d.x() * d.x() + d.y() * d.y() + d.z() * d.z()) * (1.0 + 1e-12);
        const double apart = (1.0 + kStringNear) * (a.thickness + b.thickness) + 2.0 * relative;
        return relative + apart * (1.0 + 1e-6) + 2.0 * grid_rounding;
    }

    /// After every string's own strain limit, before the tension stage: finds the pairs
    /// and solves each cluster of touching strings jointly (see above).
    void coupleStrings(const StepContext& ctx) {
        findStringPairs();
        if (string_pairs.empty()) return;
        // Warm start: the force a pair pressed with at the end of the last step bounds
        // its friction in the first pass.
        auto key = [](const detail::SegmentContact& c) { return std::make_tuple(c.string, c.segment, c.partner, c.partner_segment); };
        std::size_t k = 0;
        for (detail::SegmentContact& c : string_pairs) {
            while (k < previous_pairs.size() && key(previous_pairs[k]) < key(c)) ++k;
            if (k < previous_pairs.size() && key(previous_pairs[k]) == key(c)) c.force = previous_pairs[k].force;
        }
        // Clusters: strings connected through pairs (union-find over string slots).
        cluster_root.resize(strings.size());
        for (std::size_t i = 0; i < strings.size(); ++i) cluster_root[i] = static_cast<std::uint32_t>(i);
        auto root = [&](std::uint32_t i) {
            while (cluster_root[i] != i) i = cluster_root[i] = cluster_root[cluster_root[i]];
            return i;
        };
        for (const detail::SegmentContact& c : string_pairs) cluster_root[root(c.string)] = root(c.partner);
        // The pairs grouped by cluster (clusters in the order of their root slot, pairs in
        // their order within each: a counting sort by root), each cluster's strings in the
        // order its pairs name them first.
        cluster_first.assign(strings.size() + 1, 0);
        pair_root.resize(string_pairs.size());
        for (std::size_t i = 0; i < string_pairs.size(); ++i) {
            pair_root[i] = root(string_pairs[i].string);
            ++cluster_first[pair_root[i] + 1];
        }
        for (std::size_t r = 0; r < strings.size(); ++r) cluster_first[r + 1] += cluster_first[r];
        cluster_order.resize(string_pairs.size());
        cluster_fill.assign(cluster_first.begin(), cluster_first.end() - 1);
        for (std::size_t i = 0; i < string_pairs.size(); ++i) cluster_order[cluster_fill[pair_root[i]]++] = i;
        cluster_local.assign(strings.size(), ~std::uint32_t{0});
        std::size_t count = 0;
        for (std::size_t r = 0; r < strings.size(); ++r) {
            if (cluster_first[r] == cluster_first[r + 1]) continue;
            if (clusters.size() <= count) clusters.emplace_back();
            Cluster& cl = clusters[count++];
            cl.strings.clear();
            cl.contacts.clear();
            cl.index.clear();
            cl.contacts.reserve(cluster_first[r + 1] - cluster_first[r]);  // not grown copy by copy
            cl.index.reserve(cluster_first[r + 1] - cluster_first[r]);
            for (std::size_t q = cluster_first[r]; q < cluster_first[r + 1]; ++q) {
                const std::size_t i = cluster_order[q];
                const detail::SegmentContact& c = string_pairs[i];
                for (std::uint32_t sidx : {c.string, c.partner})
                    if (cluster_local[sidx] == ~std::uint32_t{0}) {
                        cluster_local[sidx] = static_cast<std::uint32_t>(cl.strings.size());
                        cl.strings.push_back(&strings[sidx]);
                    }
                detail::SegmentContact local = c;
                local.string = cluster_local[c.string];
                local.partner = cluster_local[c.partner];
                cl.contacts.push_back(local);
                cl.index.push_back(i);
            }
        }
        // Clusters share no string (and the joint solve moves no body), so they are solved
        // on the pool; each writes only its own strings and its own pairs.
        pool.forEach(count, [&](std::size_t q) {
            Cluster& cl = clusters[q];
            cl.scratch.always_sparse = sparse_joint_steps;
            detail::solveStringCluster(cl.strings, cl.contacts, rigids, ctx, cl.scratch);
            for (std::size_t i = 0; i < cl.contacts.size(); ++i) {
                detail::SegmentContact& c = string_pairs[cl.index[i]];
                c.force = cl.contacts[i].force;
                c.normal = cl.contacts[i].normal;
            }
        });
    }

    /// After the tension stage: a mass-weighted projection of whatever overlap the joint
    /// solve left (its penalty gives way by F / k_c, and the closest points move while s
    /// and t are held within a pass; usually nothing), moving the four ends by the
    /// fractions s and t as the Strings paper does (the least mass-weighted motion that
    /// moves the closest points apart by the overlap d: impulse d / (w_a + w_b),
    /// w_a = (1-s)^2 w_j + s^2 w_{j+1}); then the colliding flags of the next shape
    /// matching and the warm start of the next step.
    void finishStringContacts() {
        previous_pairs.clear();
        if (string_pairs.empty()) return;
        auto weight = [](const StringState& s, std::size_t p) {
            return s.hold[p].kind == ParticleHold::Kind::Free ? s.inv_mass[p] : 0.0;
        };
        // The gap at the closest points now. The joint solve kept every pair on its side,
        // so the closest-point direction is the normal (the solve's where the axes touch).
        auto measure = [&](detail::SegmentContact& c) {
            const StringState& sa = strings[c.string];
            const StringState& sb = strings[c.partner];
            const detail::SegmentClosest cp = detail::closestPointsOfSegments(
                sa.x[c.segment], sa.x[c.segment + 1], sb.x[c.partner_segment], sb.x[c.partner_segment + 1]);
            c.s = cp.s;
            c.partner_s = cp.t;
            const Vec3 d = cp.p - cp.q;
            if (cp.distance > kStringAxisContact * c.gap) c.normal = d / cp.distance;
            return d.dot(c.normal) - c.gap;
        };
        for (int sweep = 0; sweep < kStringCleanupSweeps; ++sweep) {
            double worst = 0.0;
            for (detail::SegmentContact& c : string_pairs) {
                if (strings[c.string].broken[c.segment] || strings[c.partner].broken[c.partner_segment]) continue;
                const double gap = measure(c);
                if (gap >= 0.0) continue;
                worst = std::max(worst, -gap / c.gap);
                StringState& sa = strings[c.string];
                StringState& sb = strings[c.partner];
                const double s = c.s, t = c.partner_s;
                const double a0 = (1.0 - s) * weight(sa, c.segment), a1 = s * weight(sa, c.segment + 1);
                const double b0 = (1.0 - t) * weight(sb, c.partner_segment), b1 = t * weight(sb, c.partner_segment + 1);
                const double w = (1.0 - s) * a0 + s * a1 + (1.0 - t) * b0 + t * b1;
                if (!(w > 0.0)) continue;
                const Vec3 step = (-gap / w) * c.normal;
                sa.x[c.segment] += a0 * step;
                sa.x[c.segment + 1] += a1 * step;
                sb.x[c.partner_segment] -= b0 * step;
                sb.x[c.partner_segment + 1] -= b1 * step;
            }
            if (worst <= kStringCleanupTolerance) break;
        }
        // Colliding particles weigh 3x in the next step's shape matching (Sec. 6).
        for (detail::SegmentContact& c : string_pairs) {
            if (c.force > 0.0) previous_pairs.push_back(c);
            if (measure(c) > kStringTouchSlop * c.gap) continue;
            strings[c.string].colliding[c.segment] = strings[c.string].colliding[c.segment + 1] = 1;
            strings[c.partner].colliding[c.partner_segment] = strings[c.partner].colliding[c.partner_segment + 1] = 1;
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
    s.chain_inverse.assign(6 * n + 12, 0.0);
    s.chain_coupled.assign(n, 0);
    s.row_projector.assign(n, Mat3::Identity());
    s.colliding.assign(n, 0);
    s.spring_force.assign(m, 0.0);
    s.geometric_tension.assign(m, 0.0);
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
    // The step's per-string index lists get their room here, not in a step: own_strings is
    // empty while every string touches a movable body, and grew (allocated) in the step in
    // which one stopped touching it (StepAllocations' rope leaving a ball).
    impl_->live_strings.reserve(impl_->strings.size());
    impl_->own_strings.reserve(impl_->strings.size());
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

std::vector<std::pair<Vec3, Vec3>> World::meshBounds(double h) const {
    std::vector<std::pair<Vec3, Vec3>> out;  // sheets and cloths add their swept bounds here
    impl_->cloths.bounds(h, impl_->settings.gravity, out);
    impl_->papers.bounds(h, impl_->settings.gravity, out);
    return out;
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
    impl_->cloths.releaseBody(id, impl_->time, impl_->steps, impl_->pending);
    impl_->papers.forgetBody(id, impl_->time, impl_->steps, impl_->pending);
    impl_->rigids.used[id.index] = 0;
    impl_->rigids.bodies[id.index].present = false;
}

bool World::rigidInUse(RigidId id) const {
    if (impl_->papers.usesBody(id)) return true;
    for (const StringState& s : impl_->strings) {
        if (!s.alive) continue;
        for (const ParticleHold& hold : s.hold)
            if (hold.kind == ParticleHold::Kind::Glue && hold.body == id) return true;
    }
    return impl_->cloths.usesBody(id);
}

void World::step(double h) {
    Impl& w = *impl_;
    // Refused before anything changes (issue 8): a step the solver can take, and settings
    // that are valid (settings() hands out a reference).
    if (!(h >= kMinStep && h <= kMaxStep))
        throw InvalidInput("h", "the time step must be a finite number in [1e-07, 1] s (got " + std::to_string(h) + ")");
    validate(w.settings);
    const detail::FlushSubnormals mode;  // subnormals cost ~100 cycles an operation (float_mode.hpp)
    w.events.clear();
    w.events.swap(w.pending);

    StepContext ctx;
    ctx.h = h;
    ctx.inv_h = 1.0 / h;
    ctx.gravity = w.settings.gravity;
    ctx.settings = &w.settings;
    ctx.time = w.time + h;
    ctx.step = w.steps + 1;
    ctx.pool = &w.pool;
    ctx.cold_strain_starts = w.cold_strain_starts;
    ctx.newton_strain_only = w.newton_strain_only;

    RigidTable& rigids = w.rigids;
    for (std::size_t i = 0; i < rigids.bodies.size(); ++i) {
        rigids.bodies[i].impulse.setZero();
        rigids.start_position[i] = rigids.bodies[i].position;
        rigids.start_orientation[i] = rigids.bodies[i].orientation;
    }

    StageTimes& t = w.last;
    t = StageTimes{};
    auto live = [](const StringState& s) { return s.alive && !s.frozen; };

    // Independent strings run their own stages on the pool (WorldSettings::threads): each
    // call touches only its string (and reads the bodies); whatever strings share (bodies
    // they pull or touch, string-string contacts, events) stays on this thread, in order.
    w.pool.setThreads(w.settings.threads);
    w.live_strings.clear();
    for (std::size_t i = 0; i < w.strings.size(); ++i)
        if (live(w.strings[i])) w.live_strings.push_back(static_cast<std::uint32_t>(i));
    auto eachLive = [&w](auto&& fn) { w.pool.forEach(w.live_strings.size(), [&](std::size_t k) { fn(w.strings[w.live_strings[k]]); }); };
    // A string that holds a body (glue) writes to it in several stages: it stays serial.
    auto ownsNothing = [](const StringState& s) {
        for (const ParticleHold& hold : s.hold)
            if (hold.kind == ParticleHold::Kind::Glue) return false;
        return true;
    };

    auto t0 = Clock::now();
    eachLive([&w](StringState& s) { detail::shapeMatch(s, &w.pool); });
    auto t0b = Clock::now();
    t.shape_matching = seconds(t0, t0b);

    eachLive([&](StringState& s) { detail::predict(s, rigids, ctx); });
    auto t1 = Clock::now();
    t.predict = seconds(t0b, t1);

    // Collision with rigid bodies: the host's narrow phase on the predicted positions.
    w.pool.forEach(w.strings.size(), [&w](std::size_t i) {
        StringState& s = w.strings[i];
        s.contacts.clear();
        s.body_nodes.clear();
        if (s.rows_pressed) std::fill(s.row_projector.begin(), s.row_projector.end(), Mat3::Identity());
        s.rows_pressed = false;
        std::fill(s.colliding.begin(), s.colliding.end(), 0);
    });
    w.contacts.clear();
    if (w.contact_provider && w.settings.rigid_contacts) w.collectContacts(ctx);
    auto t1c = Clock::now();
    t.collision = seconds(t1, t1c);
    t1 = t1c;

    // Strain limiting. Strings that pull or touch a movable body are coupled through it
    // and are swept Gauss-Seidel style; the others are solved once (their solve is exact).
    // Strings that neither hold nor touch a movable body are solved once, in parallel; the
    // others in order on this thread (they move bodies other strings see).
    // prepareStrainLimit touches bodies only for particles glued to them: strings that
    // hold none are prepared in parallel, the others in order on this thread.
    eachLive([&](StringState& s) {
        if (ownsNothing(s)) detail::prepareStrainLimit(s, rigids, ctx);
    });
    bool coupled = false;
    w.own_strings.clear();
    w.string_own.assign(w.strings.size(), 0);
    for (std::size_t i = 0; i < w.strings.size(); ++i) {
        StringState& s = w.strings[i];
        if (!live(s)) continue;
        const bool owns_nothing = ownsNothing(s);
        if (!owns_nothing) detail::prepareStrainLimit(s, rigids, ctx);
        coupled = coupled || touchesMovableBody(s);
        if (!touchesMovableBody(s) && owns_nothing) {
            w.own_strings.push_back(static_cast<std::uint32_t>(i));
            w.string_own[i] = 1;
        }
    }
    w.pool.forEach(w.own_strings.size(), [&](std::size_t k) { detail::limitStrain(w.strings[w.own_strings[k]], rigids, ctx); });
    // The sweeps end early once a sweep finds every string at its solution already (its
    // first Newton step within the strain tolerance): the bodies no longer move.
    const int sweeps = coupled ? w.settings.coupling_iterations : 1;
    for (int sweep = 0; sweep < sweeps; ++sweep) {
        double moved = 0.0;
        for (std::size_t i = 0; i < w.strings.size(); ++i) {
            StringState& s = w.strings[i];
            if (!live(s) || w.string_own[i]) continue;
            if (sweep == 0 || touchesMovableBody(s))
                moved = std::max(moved, detail::limitStrain(s, rigids, ctx) / s.shortest_rest);
        }
        if (sweep > 0 && moved < w.settings.strain_tolerance) break;
    }
    eachLive([&](StringState& s) { detail::clampTravel(s, ctx); });
    auto t2 = Clock::now();
    t.strain_limit = seconds(t1, t2);
    // String-string and self collision: the strings that touch are solved again, together
    // (coupleStrings), before the tension stage reads their motion.
    if (w.settings.string_collisions) {
        w.coupleStrings(ctx);
        const auto t2c = Clock::now();
        t.collision += seconds(t2, t2c);
        t2 = t2c;
    }

    w.pool.forEach(w.own_strings.size(), [&](std::size_t k) { detail::solveTwist(w.strings[w.own_strings[k]], rigids, ctx); });
    for (std::size_t i = 0; i < w.strings.size(); ++i)
        if (live(w.strings[i]) && !w.string_own[i]) detail::solveTwist(w.strings[i], rigids, ctx);
    auto t2b = Clock::now();
    t.twist = seconds(t2, t2b);
    t2 = t2b;

    eachLive([&](StringState& s) { detail::estimateTension(s, ctx); });
    auto t3 = Clock::now();
    t.tension = seconds(t2, t3);
    // What overlap the joint solve left is projected away after the tension stage (so it
    // never counts as tension), and the next step's warm start is kept.
    if (w.settings.string_collisions) {
        w.finishStringContacts();
        const auto t3c = Clock::now();
        t.collision += seconds(t3, t3c);
        t3 = t3c;
    }

    // Each string's response is its own; its events are collected per string and appended
    // in string order (the order of a serial loop).
    if (w.string_events.size() < w.live_strings.size()) w.string_events.resize(w.live_strings.size());
    w.pool.forEach(w.live_strings.size(), [&](std::size_t k) {
        w.string_events[k].clear();
        detail::respondMaterial(w.strings[w.live_strings[k]], StringId{w.live_strings[k]}, ctx, w.string_events[k]);
    });
    for (std::size_t k = 0; k < w.live_strings.size(); ++k)
        w.events.insert(w.events.end(), w.string_events[k].begin(), w.string_events[k].end());
    auto t4 = Clock::now();
    t.material = seconds(t3, t4);

    w.bad_state.assign(w.live_strings.size(), 0);
    w.pool.forEach(w.live_strings.size(), [&](std::size_t k) {
        StringState& s = w.strings[w.live_strings[k]];
        detail::computeTwistForces(s);
        detail::updateVelocities(s, ctx);
        // A long string alone checks and clears its particles on the pool (forRanges).
        w.bad_state[k] = detail::forRangesAny(&w.pool, s.particles(), detail::kParallelItems, [&](std::size_t p0, std::size_t p1) {
            bool ok = true;
            for (std::size_t p = p0; p < p1 && ok; ++p) ok = finite(s.x[p]) && finite(s.v[p]);
            std::fill(s.force.begin() + static_cast<std::ptrdiff_t>(p0), s.force.begin() + static_cast<std::ptrdiff_t>(p1), Vec3::Zero());
            return !ok;
        });
    });
    for (std::size_t k = 0; k < w.live_strings.size(); ++k)
        if (w.bad_state[k]) w.freeze(w.strings[w.live_strings[k]], StringId{w.live_strings[k]}, ctx);
    // Cloths (src/cloth/): their own stages, after the strings, before the bodies' velocities.
    StageTimes cloth_times;
    if (!w.cloths.empty())
        w.cloths.step(rigids, ctx, [&w](const PointQuery& q, std::vector<PointContact>& out) { w.findPointContacts(q, out); },
                      w.events, cloth_times);

    // Paper sheets: their own stages (src/paper/system.cpp); contacts through the host.
    {
        detail::PaperStep pctx;
        pctx.h = h;
        pctx.inv_h = ctx.inv_h;
        pctx.gravity = ctx.gravity;
        pctx.max_speed = w.settings.max_speed;
        pctx.time = ctx.time;
        pctx.step = ctx.step;
        w.papers.step(pctx, rigids, [&w](const PointQuery& q, std::vector<PointContact>& out) { w.findPointContacts(q, out); }, w.events);
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
    // The cloths' stages are counted as theirs; the sheets' are in lastPaperTimes().
    t.velocities = seconds(t4, t5) - cloth_times.total() - w.papers.lastTimes().total();
    t += cloth_times;

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

// Paper sheets: forwarded to the paper system (src/paper/system.cpp).
PaperId World::addPaper(const PaperDesc& desc) { return impl_->papers.add(desc, impl_->rigids); }
void World::removePaper(PaperId id) { impl_->papers.remove(id); }
std::vector<PaperId> World::papers() const { return impl_->papers.ids(); }
bool World::contains(PaperId id) const { return impl_->papers.contains(id); }
PaperView World::viewPaper(PaperId id) const { return impl_->papers.view(id); }
const PaperDesc& World::paperDesc(PaperId id) const { return impl_->papers.get(id).desc; }
void World::attachPaperToPoint(PaperId id, std::uint32_t vertex, const Vec3& point) { impl_->papers.attachToPoint(id, vertex, point); }
void World::attachPaperToRigid(PaperId id, std::uint32_t vertex, RigidId body, const Vec3& local_point) {
    impl_->papers.attachToRigid(id, vertex, body, local_point, impl_->rigids);
}
void World::movePaperPin(PaperId id, std::uint32_t vertex, const Vec3& point) { impl_->papers.movePin(id, vertex, point); }
void World::detachPaper(PaperId id, std::uint32_t vertex) {
    impl_->papers.detach(id, vertex, EventCause::Request, impl_->time, impl_->steps, impl_->pending);
}
void World::applyPaperForce(PaperId id, std::uint32_t vertex, const Vec3& force) { impl_->papers.applyForce(id, vertex, force); }
const PaperTimes& World::lastPaperTimes() const { return impl_->papers.lastTimes(); }
void World::setContactProvider(ContactProvider* provider) { impl_->contact_provider = provider; }
const std::vector<RigidContact>& World::lastContacts() const { return impl_->contacts; }
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
    return {&w.settings, &w.strings, &w.cloths.cloths_, &w.papers.sheets_, &w.rigids, &w.pending,
            &w.events, &w.previous_pairs, &w.deep_pairs, &w.time, &w.steps};
}
void detail::WorldAccess::setStringNodePruning(World& world, bool on) { world.impl_->node_pruning = on; }
void detail::WorldAccess::setSparseJointSteps(World& world, bool on) { world.impl_->sparse_joint_steps = on; }
void detail::WorldAccess::setColdStrainStarts(World& world, bool on) { world.impl_->cold_strain_starts = on; }
void detail::WorldAccess::setNewtonStrainOnly(World& world, bool on) { world.impl_->newton_strain_only = on; }
std::size_t detail::WorldAccess::lastStringNodeRejects(const World& world) {
    return world.impl_->tree_searched ? world.impl_->tree.lastNodeRejects() : 0;
}
void detail::WorldAccess::setStraightStringsSkip(World& world, bool on) { world.impl_->straight_strings_skip = on; }
std::size_t detail::WorldAccess::lastSelfFreeStrings(const World& world) {
    const std::vector<std::uint8_t>& flags = world.impl_->self_free;
    return static_cast<std::size_t>(std::count(flags.begin(), flags.end(), std::uint8_t{1}));
}
const std::vector<detail::SegmentPair>& detail::WorldAccess::lastStringSearchPairs(const World& world) {
    return world.impl_->grid_pairs;
}

}  // namespace tearables
