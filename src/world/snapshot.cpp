// Snapshots of the whole core state (include/tearables/snapshot.hpp has the format).
//
// One function per state type lists its fields once (`io`), for writing and reading
// alike, so that the two can never disagree. Everything is written little-endian as
// 64-bit words (integers) and IEEE bit patterns (doubles): restoring gives back the same
// bits, which is what a bit-identical continuation needs. A reader checks the magic, the
// version and the checksum first, then the sizes of everything it reads and the
// consistency of every string, cloth and sheet (per-particle, per-edge and per-spring
// arrays, indices into the mesh, attachments to rigid slots that exist, a valid
// descriptor), so that a damaged file is refused rather than stepped.
#include "tearables/snapshot.hpp"

#include "world/world_access.hpp"
#include "string/string_state.hpp"

#include <array>
#include <cmath>
#include <cstring>
#include <istream>
#include <iterator>
#include <limits>
#include <optional>
#include <ostream>
#include <sstream>
#include <type_traits>

namespace tearables {

namespace {

constexpr char kMagic[8] = {'T', 'E', 'A', 'R', 'S', 'N', 'A', 'P'};
constexpr const char* kCoreTags[] = {"WRLD", "RIGD", "STRG", "CLTH", "PAPR", "SCOL", "EVNT", "END "};
/// A header (magic, version, reserved) and the checksum: the least a file can have.
constexpr std::size_t kHeaderBytes = 8 + 4 + 4;
constexpr std::size_t kChecksumBytes = 8;

std::uint64_t fnv1a(const char* data, std::size_t size) {
    std::uint64_t h = 1469598103934665603ull;
    for (std::size_t i = 0; i < size; ++i) {
        h ^= static_cast<unsigned char>(data[i]);
        h *= 1099511628211ull;
    }
    return h;
}

bool isCoreTag(const std::string& tag) {
    for (const char* t : kCoreTags)
        if (tag == t) return true;
    return false;
}

// --- archives ------------------------------------------------------------------------------

class Writer {
public:
    static constexpr bool kReading = false;
    std::string bytes;

    void word(std::uint64_t& v) {
        for (int i = 0; i < 8; ++i) bytes.push_back(static_cast<char>((v >> (8 * i)) & 0xffu));
    }
    void raw(const char* data, std::size_t n) { bytes.append(data, n); }
    /// Elements of a vector about to be read: nothing to check when writing.
    void expectElements(std::uint64_t) {}
    [[noreturn]] void fail(const std::string& problem) { throw SnapshotError("snapshot", problem); }
};

class Reader {
public:
    static constexpr bool kReading = true;
    Reader(const char* begin, const char* end, std::string where) : p_(begin), end_(end), where_(std::move(where)) {}

    void word(std::uint64_t& v) {
        need(8);
        v = 0;
        for (int i = 0; i < 8; ++i) v |= static_cast<std::uint64_t>(static_cast<unsigned char>(p_[i])) << (8 * i);
        p_ += 8;
    }
    void raw(char* data, std::size_t n) {
        need(n);
        std::memcpy(data, p_, n);
        p_ += n;
    }
    /// A vector of `count` elements of at least 8 bytes each must fit in what is left
    /// (a damaged length never allocates gigabytes).
    void expectElements(std::uint64_t count) {
        if (count > remaining() / 8) fail("a length of " + std::to_string(count) + " elements does not fit in the section");
    }
    std::size_t remaining() const { return static_cast<std::size_t>(end_ - p_); }
    [[noreturn]] void fail(const std::string& problem) const { throw SnapshotError(where_, problem); }
    const std::string& where() const { return where_; }

private:
    void need(std::size_t n) const {
        if (remaining() < n) fail("truncated section");
    }
    const char* p_;
    const char* end_;
    std::string where_;
};

// --- primitives ---------------------------------------------------------------------------

template <class A>
void io(A& a, std::uint64_t& v) {
    a.word(v);
}
template <class A>
void io(A& a, double& v) {
    std::uint64_t bits = 0;
    std::memcpy(&bits, &v, sizeof bits);
    a.word(bits);
    std::memcpy(&v, &bits, sizeof bits);
}
template <class A>
void io(A& a, bool& v) {
    std::uint64_t w = v ? 1 : 0;
    a.word(w);
    if (w > 1) a.fail("a flag is neither 0 nor 1");
    v = w == 1;
}
/// Signed and unsigned integers other than u64: as a 64-bit two's complement word,
/// checked to fit the type when read.
template <class A, class T>
std::enable_if_t<std::is_integral_v<T> && !std::is_same_v<T, bool> && !std::is_same_v<T, std::uint64_t>> io(A& a, T& v) {
    std::uint64_t w = static_cast<std::uint64_t>(static_cast<std::int64_t>(v));
    if constexpr (std::is_unsigned_v<T>) w = static_cast<std::uint64_t>(v);
    a.word(w);
    if constexpr (A::kReading) {
        if constexpr (std::is_unsigned_v<T>) {
            if (w > static_cast<std::uint64_t>(std::numeric_limits<T>::max())) a.fail("an integer out of range");
            v = static_cast<T>(w);
        } else {
            const auto s = static_cast<std::int64_t>(w);
            if (s < std::numeric_limits<T>::min() || s > std::numeric_limits<T>::max()) a.fail("an integer out of range");
            v = static_cast<T>(s);
        }
    }
}
/// An enum with values 0..max.
template <class A, class E>
void ioEnum(A& a, E& e, int max, const char* what) {
    auto v = static_cast<std::int64_t>(e);
    io(a, v);
    if (v < 0 || v > max) a.fail(std::string("unknown ") + what + " " + std::to_string(v));
    e = static_cast<E>(v);
}
template <class A, int R, int C>
void io(A& a, Eigen::Matrix<double, R, C>& m) {
    for (Eigen::Index i = 0; i < m.size(); ++i) io(a, m.data()[i]);
}
template <class A>
void io(A& a, Quat& q) {
    io(a, q.coeffs());
}
template <class A>
void io(A& a, std::string& s) {
    std::uint64_t n = s.size();
    io(a, n);
    if constexpr (A::kReading) {
        if (n > a.remaining()) a.fail("a string longer than the section");
        s.resize(static_cast<std::size_t>(n));
        a.raw(s.data(), s.size());
    } else {
        a.raw(s.data(), s.size());
    }
}
template <class A, class T>
void io(A& a, std::vector<T>& v);
template <class A, class T, std::size_t N>
void io(A& a, std::array<T, N>& v) {
    for (T& e : v) io(a, e);
}
/// A fixed C array (the descriptors' `double size[2]`, a spring's `hinge[2]`).
template <class A, class T, std::size_t N>
void ioArray(A& a, T (&v)[N]) {
    for (T& e : v) io(a, e);
}
template <class A>
void io(A& a, std::optional<Vec3>& o) {
    bool has = o.has_value();
    io(a, has);
    if (!has) {
        o.reset();
        return;
    }
    if (!o) o.emplace(Vec3::Zero());
    io(a, *o);
}
template <class A, class T, class U>
void io(A& a, std::pair<T, U>& p) {
    io(a, p.first);
    io(a, p.second);
}
template <class A>
void io(A& a, detail::PairKey& k) {
    io(a, k.string);
    io(a, k.segment);
    io(a, k.partner);
    io(a, k.partner_segment);
}
template <class A>
void io(A& a, StringId& id) {
    io(a, id.index);
    io(a, id.generation);
}
template <class A>
void io(A& a, RigidId& id) {
    io(a, id.index);
}
/// The generator's full state in the standard's text form (exact by definition).
template <class A>
void io(A& a, std::mt19937_64& rng) {
    std::string text;
    if constexpr (!A::kReading) {
        std::ostringstream s;
        s << rng;
        text = s.str();
    }
    io(a, text);
    if constexpr (A::kReading) {
        std::istringstream s(text);
        s >> rng;
        if (s.fail()) a.fail("the random generator's state is damaged");
    }
}

// --- state types --------------------------------------------------------------------------

template <class A>
void io(A& a, Material& m) {
    io(a, m.tensile.young);
    io(a, m.tensile.yield);
    io(a, m.tensile.plastic_modulus);
    io(a, m.tensile.rupture);
    io(a, m.torsion.modulus);
    io(a, m.torsion.yield);
    io(a, m.torsion.plastic_modulus);
    io(a, m.torsion.rupture);
    io(a, m.variation);
}
template <class A>
void io(A& a, StringDesc& d) {
    io(a, d.name);
    io(a, d.points);
    io(a, d.radius);
    io(a, d.density);
    io(a, d.particle_masses);
    io(a, d.material);
    io(a, d.csm_half_width);
    io(a, d.bending);
    io(a, d.twist_half_width);
    ioEnum(a, d.tension, 1, "tension estimator");
    ioEnum(a, d.integrator, 1, "string integrator");
    io(a, d.tearable);
    io(a, d.yield_in_solve);
    io(a, d.damping);
    io(a, d.axial_damping);
    io(a, d.seed);
}
template <class A>
void io(A& a, WorldSettings& s) {
    io(a, s.gravity);
    io(a, s.strain_iterations);
    io(a, s.coupling_iterations);
    io(a, s.strain_tolerance);
    io(a, s.max_speed);
    io(a, s.rigid_contacts);
    io(a, s.string_collisions);
    io(a, s.island_string_contacts);
}
template <class A>
void io(A& a, detail::ParticleHold& h) {
    ioEnum(a, h.kind, 2, "attachment kind");
    io(a, h.point);
    io(a, h.body);
}
template <class A>
void io(A& a, detail::SegmentMaterial& m) {
    io(a, m.young);
    io(a, m.yield);
    io(a, m.plastic_modulus);
    io(a, m.rupture);
    io(a, m.shear_modulus);
    io(a, m.torsion_yield);
    io(a, m.torsion_plastic);
    io(a, m.torsion_rupture);
}
template <class A>
void io(A& a, detail::StringPairContact& c) {
    io(a, c.segment);
    io(a, c.s);
    io(a, c.normal);
    io(a, c.gap);
    io(a, c.friction);
    io(a, c.stiffness);
    io(a, c.active);
    io(a, c.string);
    io(a, c.partner);
    io(a, c.partner_segment);
    io(a, c.partner_s);
    io(a, c.start_normal);
    io(a, c.start_distance);
    io(a, c.force);
}
template <class A>
void io(A& a, detail::ContactMemory& c) {
    io(a, c.segment);
    io(a, c.s);
    io(a, c.body);
    io(a, c.normal);
    io(a, c.force);
}
template <class A>
void io(A& a, RigidState& b) {
    io(a, b.position);
    io(a, b.orientation);
    io(a, b.linear_velocity);
    io(a, b.angular_velocity);
    io(a, b.inverse_mass);
    io(a, b.inverse_inertia_local);
    io(a, b.awake);
    io(a, b.present);
    io(a, b.impulse);
}
template <class A>
void io(A& a, Event& e) {
    ioEnum(a, e.type, static_cast<int>(EventType::Overlap), "event type");
    ioEnum(a, e.cause, static_cast<int>(EventCause::NonFinite), "event cause");
    io(a, e.string);
    io(a, e.object);
    io(a, e.segment);
    io(a, e.particle);
    io(a, e.stress);
    io(a, e.time);
    io(a, e.step);
    io(a, e.rigid);
    io(a, e.depth);
}
// Cloths (src/cloth/cloth_state.hpp).
// The attachments a cloth or a sheet is created with (tearables/sheet_attachment.hpp).
template <class A>
void io(A& a, SheetAttachment& t) {
    io(a, t.vertex);
    io(a, t.body);
    io(a, t.local);
    io(a, t.world);
}
template <class A>
void io(A& a, YarnKind& k) {
    ioEnum(a, k, static_cast<int>(YarnKind::Weft), "yarn kind");
}
template <class A>
void io(A& a, ClothWeakYarn& w) {
    io(a, w.i);
    io(a, w.j);
    io(a, w.kind);
    io(a, w.strength);
}
template <class A>
void io(A& a, detail::SoftSpring& s) {
    io(a, s.a);
    io(a, s.b);
    io(a, s.rest);
    io(a, s.stiffness);
    io(a, s.alive);
}
// Paper sheets (src/paper/sheet.hpp).
template <class A>
void io(A& a, PaperSpring& sp) {
    io(a, sp.a);
    io(a, sp.b);
    io(a, sp.rest);
    io(a, sp.stiffness);
    ioEnum(a, sp.kind, static_cast<int>(PaperSpringKind::Hinge), "spring kind");
    io(a, sp.broken);
    ioArray(a, sp.hinge);
}
template <class A, class T>
void io(A& a, std::vector<T>& v) {
    std::uint64_t n = v.size();
    io(a, n);
    if constexpr (A::kReading) {
        a.expectElements(n);
        v.clear();
        v.resize(static_cast<std::size_t>(n));
    }
    for (T& e : v) io(a, e);
}
// std::vector<std::uint8_t> and friends go through the integral overload per element.

/// Every field of a string that lives from one step to the next, and the solver scratch
/// that a step may read before writing (kept so that the continuation is bit-identical).
/// Not kept, rebuilt by every step: contacts, body nodes and their columns, the block
/// factorisation, the shape-matching scratch.
template <class A>
void io(A& a, detail::StringState& s) {
    io(a, s.alive);
    io(a, s.generation);
    if (!s.alive) return;  // a free slot: only its place and generation are kept
    io(a, s.desc);
    io(a, s.frozen);
    io(a, s.x);
    io(a, s.v);
    io(a, s.x_prev);
    io(a, s.x_pred);
    io(a, s.v_prev);
    io(a, s.x_older);
    io(a, s.inertia_gain);
    io(a, s.force);
    io(a, s.mass);
    io(a, s.inv_mass);
    io(a, s.hold);
    io(a, s.glue_impulse);
    io(a, s.glue_movable);
    io(a, s.rest_length);
    io(a, s.max_length);
    io(a, s.compliance);
    io(a, s.tension);
    io(a, s.twist);
    io(a, s.radius);
    io(a, s.broken);
    io(a, s.yielded);
    io(a, s.original_length);
    io(a, s.peak_stress);
    io(a, s.material);
    io(a, s.scratch.dir);
    io(a, s.scratch.diag);
    io(a, s.scratch.off);
    io(a, s.scratch.rhs);
    io(a, s.scratch.segment_work);
    io(a, s.scratch.active);
    io(a, s.scratch.blk_diag);
    io(a, s.scratch.blk_off);
    io(a, s.scratch.blk_rhs);
    io(a, s.scratch.blk_factor_gain);
    io(a, s.spring_force);
    io(a, s.scratch.row_projector);
    io(a, s.colliding);
    io(a, s.made_inside);
    io(a, s.overlap_reported);
    io(a, s.contact_memory);
    io(a, s.prev_stretch);
    io(a, s.rest_direction);
    io(a, s.rest_shape);
    io(a, s.scratch.csm_goal);
    io(a, s.csm_mass);
    io(a, s.twist_velocity);
    io(a, s.twist_old);
    io(a, s.twist_inertia);
    io(a, s.twist_width);
    io(a, s.rest_twist);
    io(a, s.joint_stiffness);
    io(a, s.torsion_peak);
    io(a, s.joint_strain);
    io(a, s.torsion_yielded);
    io(a, s.twist_force);
    for (double& v : s.end_twist) io(a, v);
    io(a, s.twist_frame);
    for (double& v : s.twist_glued_pred) io(a, v);
    for (double& v : s.twist_glued_axis_inertia) io(a, v);
    io(a, s.shortest_rest);
    io(a, s.rng);
}

template <class A>
void io(A& a, ClothDesc& d) {
    io(a, d.name);
    io(a, d.center);
    io(a, d.corner);
    io(a, d.size);
    io(a, d.resolution);
    io(a, d.orientation);
    io(a, d.areal_density);
    io(a, d.density);
    io(a, d.yarn_radius);
    io(a, d.material);
    io(a, d.lambda);
    io(a, d.shear_stiffness);
    io(a, d.bending_stiffness);
    io(a, d.damping);
    io(a, d.plastic_time);
    io(a, d.tearable);
    io(a, d.attachments);
    io(a, d.weak_yarns);
    io(a, d.seed);
}

/// Every field of a cloth that lives from one step to the next. Not kept, rebuilt by
/// every step before it is read: contacts, body nodes, penalty rows, the Newton solve's
/// unknowns, Hessian and factorisation, the tension solve's rows and right-hand sides.
/// The two sparse factorisations keep a symbolic analysis between steps; a restored cloth
/// analyses its pattern afresh (the analysis is a function of the pattern alone, so the
/// factors, and the run, are the same bits: tests/reliability/test_snapshot.cpp).
/// `dir` is kept: an edge shorter than 1e-15 m keeps the last step's direction.
template <class A>
void io(A& a, detail::ClothState& c) {
    io(a, c.alive);
    io(a, c.generation);
    io(a, c.desc);
    io(a, c.frozen);
    io(a, c.nu);
    io(a, c.nv);
    io(a, c.x);
    io(a, c.v);
    io(a, c.x_prev);
    io(a, c.x_pred);
    io(a, c.force);
    io(a, c.mass);
    io(a, c.hold);
    io(a, c.edges);
    io(a, c.kinds);
    io(a, c.rest_length);
    io(a, c.original_length);
    io(a, c.max_length);
    io(a, c.tension);
    io(a, c.stiffness);
    io(a, c.peak_stress);
    io(a, c.broken);
    io(a, c.yielded);
    io(a, c.material);
    io(a, c.edge_springs);
    io(a, c.vertex_edges);
    io(a, c.springs);
    io(a, c.shortest_rest);
    io(a, c.dir);
    io(a, c.topology);
    io(a, c.tension_residual);
    io(a, c.tension_iterations);
    io(a, c.rng);
}

template <class A>
void io(A& a, PaperDesc& d) {
    io(a, d.name);
    io(a, d.center);
    io(a, d.corner);
    io(a, d.orientation);
    ioArray(a, d.size);
    ioArray(a, d.resolution);
    io(a, d.vertices);
    io(a, d.triangles);
    io(a, d.areal_density);
    io(a, d.stiffness);
    io(a, d.bending);
    io(a, d.damping);
    ioEnum(a, d.solver, static_cast<int>(PaperSolver::Multigrid), "solver");
    io(a, d.tolerance);
    io(a, d.jacobi_iterations);
    ioEnum(a, d.integrator, static_cast<int>(PaperIntegrator::Explicit), "integrator");
    io(a, d.phi);
    io(a, d.psi);
    io(a, d.hinge_threshold);
    io(a, d.breakable);
    io(a, d.tearable);
    io(a, d.rupture_stretch);
    ioEnum(a, d.tension, static_cast<int>(PaperTension::Momentum), "tension estimator");
    io(a, d.thickness);
    io(a, d.friction);
    io(a, d.seed);
    io(a, d.attachments);
}

/// Every field of a sheet that lives from one step to the next: the mesh as it is now
/// (vertices inserted by creases and tears, triangles, springs with their kinds, hinges
/// and broken flags), the adjacency lists in their order (topology changes search them in
/// that order), the compression each spring survived, the crack tips, the counters and the
/// random generator, and the conjugate gradient's warm start (the last step's dv). Not kept, rebuilt by every step before it is read: the implicit
/// solve's blocks and right-hand sides, the bodies' lent masses, the start velocities.
template <class A>
void io(A& a, detail::PaperSheet& s) {
    io(a, s.alive);
    io(a, s.generation);
    io(a, s.desc);
    io(a, s.frozen);
    io(a, s.x);
    io(a, s.x_pred);
    io(a, s.v);
    io(a, s.force);
    io(a, s.mass);
    io(a, s.hold);
    io(a, s.crack_tip);
    io(a, s.triangles);
    io(a, s.springs);
    io(a, s.vertex_triangles);
    io(a, s.vertex_springs);
    io(a, s.survived);
    io(a, s.counters.creases);
    io(a, s.counters.hinges);
    io(a, s.counters.tears);
    io(a, s.rng);
    io(a, s.total_mass);
    io(a, s.tension);
    io(a, s.cg_warm);
}

// --- consistency of what was read ----------------------------------------------------------

/// A glue (or a remembered contact) names a rigid slot that exists.
bool bodyExists(const detail::RigidTable& rigids, RigidId body) {
    return body.index < rigids.bodies.size() && rigids.used[body.index];
}

/// The arrays of a string agree with its particle count, its descriptor is valid and its
/// attachments name rigid slots that exist: what the step assumes without checking.
void checkString(const detail::StringState& s, const detail::RigidTable& rigids, const std::string& where) {
    auto fail = [&](const std::string& problem) { throw SnapshotError(where, problem); };
    try {
        validate(s.desc);
    } catch (const InvalidInput& e) {
        fail("the string's descriptor is invalid: " + std::string(e.what()));
    }
    const std::size_t n = s.x.size();
    if (n < 2 || n != s.desc.points.size()) fail("the particle count does not match the descriptor");
    const std::size_t m = n - 1, joints = m - 1;
    auto size = [&](std::size_t actual, std::size_t expected, const char* name) {
        if (actual != expected)
            fail(std::string(name) + " has " + std::to_string(actual) + " entries, expected " + std::to_string(expected));
    };
    size(s.v.size(), n, "v");
    size(s.x_prev.size(), n, "x_prev");
    size(s.x_pred.size(), n, "x_pred");
    size(s.v_prev.size(), n, "v_prev");
    size(s.x_older.size(), n, "x_older");
    size(s.force.size(), n, "force");
    size(s.mass.size(), n, "mass");
    size(s.inv_mass.size(), n, "inv_mass");
    size(s.hold.size(), n, "hold");
    size(s.glue_impulse.size(), n, "glue_impulse");
    size(s.glue_movable.size(), n, "glue_movable");
    size(s.scratch.blk_diag.size(), n, "blk_diag");
    size(s.scratch.blk_off.size(), n, "blk_off");
    size(s.scratch.blk_rhs.size(), n, "blk_rhs");
    size(s.scratch.blk_factor_gain.size(), n, "blk_factor_gain");
    size(s.scratch.row_projector.size(), n, "row_projector");
    size(s.colliding.size(), n, "colliding");
    size(s.rest_shape.size(), n, "rest_shape");
    size(s.scratch.csm_goal.size(), n, "csm_goal");
    size(s.csm_mass.size(), n, "csm_mass");
    size(s.twist_force.size(), n, "twist_force");
    for (const auto* v : {&s.rest_length, &s.max_length, &s.compliance, &s.tension, &s.twist, &s.radius,
                          &s.original_length, &s.peak_stress, &s.scratch.diag, &s.scratch.off, &s.scratch.rhs,
                          &s.scratch.segment_work, &s.spring_force, &s.prev_stretch, &s.twist_velocity, &s.twist_old, &s.twist_inertia, &s.twist_width})
        size(v->size(), m, "a per-segment array");
    size(s.broken.size(), m, "broken");
    size(s.yielded.size(), m, "yielded");
    size(s.made_inside.size(), m, "made_inside");
    size(s.scratch.active.size(), m, "active");
    size(s.material.size(), m, "material");
    size(s.scratch.dir.size(), m, "dir");
    size(s.rest_direction.size(), m, "rest_direction");
    for (const auto* v : {&s.rest_twist, &s.joint_stiffness, &s.torsion_peak, &s.joint_strain})
        size(v->size(), joints, "a per-joint array");
    size(s.torsion_yielded.size(), joints, "torsion_yielded");
    if (!s.twist_frame.empty()) size(s.twist_frame.size(), m, "twist_frame");
    for (std::size_t p = 0; p < n; ++p) {
        const detail::ParticleHold& h = s.hold[p];
        if (h.kind == detail::ParticleHold::Kind::Glue && !bodyExists(rigids, h.body))
            fail("particle " + std::to_string(p) + " is glued to rigid slot " + std::to_string(h.body.index) +
                 ", which the snapshot does not have");
        if (!(s.mass[p] > 0.0) || !std::isfinite(s.inv_mass[p])) fail("particle " + std::to_string(p) + " has no valid mass");
    }
    for (std::size_t j = 0; j < m; ++j)
        if (!(s.rest_length[j] > 0.0) || !(s.material[j].young > 0.0))
            fail("segment " + std::to_string(j) + " has no valid rest length or material");
    // The contact memory is looked up by (segment, body) with a binary search.
    for (const detail::ContactMemory& c : s.contact_memory)
        if (c.segment >= m || !(c.s >= 0.0 && c.s <= 1.0) || !bodyExists(rigids, c.body) ||
            !c.normal.allFinite() || std::abs(c.normal.norm() - 1.0) > 1e-6 || !std::isfinite(c.force) || c.force < 0.0)
            fail("contact_memory names a segment, point or body that does not exist, or has no valid normal or force");
    if (!std::is_sorted(s.contact_memory.begin(), s.contact_memory.end())) fail("contact_memory is not sorted");
}

/// The arrays of a cloth agree with its weave (vertex and edge counts of its resolution),
/// every index names a vertex, edge or spring that exists, glues name rigid slots that
/// exist, masses and rest lengths are positive: what the step assumes without checking.
void checkCloth(const detail::ClothState& c, const detail::RigidTable& rigids, const std::string& where) {
    auto fail = [&](const std::string& problem) { throw SnapshotError(where, problem); };
    try {
        validate(c.desc);
    } catch (const InvalidInput& e) {
        fail("the cloth's descriptor is invalid: " + std::string(e.what()));
    }
    if (c.nu != c.desc.resolution[0] || c.nv != c.desc.resolution[1]) fail("the weave does not match the descriptor's resolution");
    const std::size_t n = static_cast<std::size_t>(c.nu) * static_cast<std::size_t>(c.nv);
    const std::size_t m = static_cast<std::size_t>(c.nu - 1) * static_cast<std::size_t>(c.nv) +
                          static_cast<std::size_t>(c.nu) * static_cast<std::size_t>(c.nv - 1);
    auto size = [&](std::size_t actual, std::size_t expected, const char* name) {
        if (actual != expected)
            fail(std::string(name) + " has " + std::to_string(actual) + " entries, expected " + std::to_string(expected));
    };
    for (const auto* v : {&c.x, &c.v, &c.x_prev, &c.x_pred, &c.force}) size(v->size(), n, "a per-vertex array");
    size(c.mass.size(), n, "mass");
    size(c.hold.size(), n, "hold");
    size(c.vertex_edges.size(), n, "vertex_edges");
    size(c.edges.size(), m, "edges");
    size(c.kinds.size(), m, "kinds");
    for (const auto* v : {&c.rest_length, &c.original_length, &c.max_length, &c.tension, &c.stiffness, &c.peak_stress})
        size(v->size(), m, "a per-edge array");
    size(c.broken.size(), m, "broken");
    size(c.yielded.size(), m, "yielded");
    size(c.material.size(), m, "material");
    size(c.edge_springs.size(), m, "edge_springs");
    size(c.dir.size(), m, "dir");
    if (c.topology < 1) fail("the topology counter is 0");
    for (std::size_t p = 0; p < n; ++p) {
        const detail::ParticleHold& h = c.hold[p];
        if (h.kind == detail::ParticleHold::Kind::Glue && !bodyExists(rigids, h.body))
            fail("vertex " + std::to_string(p) + " is glued to rigid slot " + std::to_string(h.body.index) +
                 ", which the snapshot does not have");
        if (!(c.mass[p] > 0.0) || !std::isfinite(c.mass[p])) fail("vertex " + std::to_string(p) + " has no valid mass");
        for (std::uint32_t e : c.vertex_edges[p])
            if (e >= m || (c.edges[e][0] != p && c.edges[e][1] != p))
                fail("vertex " + std::to_string(p) + " lists edge " + std::to_string(e) + ", which does not end at it");
    }
    for (std::size_t e = 0; e < m; ++e) {
        if (c.edges[e][0] >= n || c.edges[e][1] >= n || c.edges[e][0] == c.edges[e][1])
            fail("edge " + std::to_string(e) + " names a vertex the cloth does not have");
        if (!(c.rest_length[e] > 0.0) || !(c.stiffness[e] > 0.0) || !(c.material[e].young > 0.0))
            fail("edge " + std::to_string(e) + " has no valid rest length, stiffness or material");
        for (std::uint32_t k : c.edge_springs[e])
            if (k >= c.springs.size()) fail("edge " + std::to_string(e) + " names soft spring " + std::to_string(k) + ", which does not exist");
    }
    for (std::size_t k = 0; k < c.springs.size(); ++k)
        if (c.springs[k].a >= n || c.springs[k].b >= n || !(c.springs[k].rest > 0.0))
            fail("soft spring " + std::to_string(k) + " names a vertex the cloth does not have or has no rest length");
    if (!(c.shortest_rest > 0.0)) fail("the shortest rest length is not positive");
}

/// Sizes the solver scratch of a cloth read from a snapshot as makeCloth does, and makes
/// both factorisations analyse their patterns afresh at the next step.
void prepareCloth(detail::ClothState& c) {
    const std::size_t n = c.vertices(), m = c.edgeCount();
    c.x_trial = c.x;
    c.dof.assign(n, -1);
    c.projector.assign(n, Mat3::Identity());
    c.has_row.assign(n, 0);
    c.row_rhs.assign(n, Vec3::Zero());
    c.unknown.assign(m, -1);
    c.tension_topology = 0;  // never a topology (they start at 1): the tension pattern is rebuilt
    c.newton_analysed = false;
}

/// Reads one CLTH payload (checked when alive; a dead slot comes back empty).
detail::ClothState readCloth(const std::string& payload, const detail::RigidTable& rigids, const std::string& where) {
    Reader s(payload.data(), payload.data() + payload.size(), where);
    detail::ClothState c;
    io(s, c);
    if (s.remaining() != 0) s.fail(std::to_string(s.remaining()) + " bytes left over at the end of the section");
    if (!c.alive) {
        const std::uint32_t generation = c.generation;
        c = detail::ClothState{};
        c.alive = false;
        c.generation = generation;
        return c;
    }
    checkCloth(c, rigids, where);
    prepareCloth(c);
    return c;
}

/// The mesh of a sheet names only vertices, triangles and springs it has, its per-vertex
/// and per-spring arrays agree, every adjacency entry is true of the mesh, glues name
/// rigid slots that exist and masses are positive: what the step assumes without checking.
void checkPaper(const detail::PaperSheet& s, const detail::RigidTable& rigids, const std::string& where) {
    auto fail = [&](const std::string& problem) { throw SnapshotError(where, problem); };
    try {
        validate(s.desc);
    } catch (const InvalidInput& e) {
        fail("the sheet's descriptor is invalid: " + std::string(e.what()));
    }
    const std::size_t n = s.x.size(), t = s.triangles.size(), k = s.springs.size();
    if (n < 3 || t == 0) fail("the sheet has no mesh");
    auto size = [&](std::size_t actual, std::size_t expected, const char* name) {
        if (actual != expected)
            fail(std::string(name) + " has " + std::to_string(actual) + " entries, expected " + std::to_string(expected));
    };
    for (const auto* v : {&s.x_pred, &s.v, &s.force}) size(v->size(), n, "a per-vertex array");
    size(s.mass.size(), n, "mass");
    size(s.hold.size(), n, "hold");
    size(s.crack_tip.size(), n, "crack_tip");
    size(s.vertex_triangles.size(), n, "vertex_triangles");
    size(s.vertex_springs.size(), n, "vertex_springs");
    size(s.survived.size(), k, "survived");
    // Tensions are of the springs the last tension stage saw: creases add springs after it.
    if (s.tension.size() > k) fail("tension has " + std::to_string(s.tension.size()) + " entries for " + std::to_string(k) + " springs");
    // The warm start is of the vertices the last solve saw: creases and tears add vertices after it.
    if (s.cg_warm.size() > n) fail("cg_warm has " + std::to_string(s.cg_warm.size()) + " entries for " + std::to_string(n) + " vertices");
    for (std::size_t i = 0; i < t; ++i)
        for (std::uint32_t v : s.triangles[i])
            if (v >= n) fail("triangle " + std::to_string(i) + " names vertex " + std::to_string(v) + ", which the sheet does not have");
    auto names = [](const PaperSpring& sp, std::uint32_t v) {
        return sp.a == v || sp.b == v || sp.hinge[0] == v || sp.hinge[1] == v;
    };
    for (std::size_t i = 0; i < k; ++i) {
        const PaperSpring& sp = s.springs[i];
        if (sp.a >= n || sp.b >= n || sp.a == sp.b || (sp.hinge[0] >= n && sp.hinge[0] != UINT32_MAX) ||
            (sp.hinge[1] >= n && sp.hinge[1] != UINT32_MAX))
            fail("spring " + std::to_string(i) + " names a vertex the sheet does not have");
        if (!(sp.rest >= 0.0) || !(sp.stiffness >= 0.0)) fail("spring " + std::to_string(i) + " has no valid rest length or stiffness");
    }
    double total = 0.0;
    for (std::uint32_t v = 0; v < n; ++v) {
        const detail::ParticleHold& h = s.hold[v];
        if (h.kind == detail::ParticleHold::Kind::Glue && !bodyExists(rigids, h.body))
            fail("vertex " + std::to_string(v) + " is glued to rigid slot " + std::to_string(h.body.index) +
                 ", which the snapshot does not have");
        if (!(s.mass[v] > 0.0) || !std::isfinite(s.mass[v])) fail("vertex " + std::to_string(v) + " has no valid mass");
        total += s.mass[v];
        for (std::uint32_t i : s.vertex_triangles[v])
            if (i >= t || (s.triangles[i][0] != v && s.triangles[i][1] != v && s.triangles[i][2] != v))
                fail("vertex " + std::to_string(v) + " lists triangle " + std::to_string(i) + ", which does not use it");
        for (std::uint32_t i : s.vertex_springs[v])
            if (i >= k || !names(s.springs[i], v))
                fail("vertex " + std::to_string(v) + " lists spring " + std::to_string(i) + ", which does not name it");
    }
    if (!(s.total_mass > 0.0) || std::abs(total - s.total_mass) > 1e-9 * s.total_mass)
        fail("the vertices' masses do not sum to the sheet's mass");
}

}  // namespace

// --- Snapshot -------------------------------------------------------------------------------

struct Snapshot::Data {
    WorldSettings settings;
    std::vector<detail::StringState> strings;
    /// A cloth holds its solvers (not copyable): its checked section is kept and read
    /// again by restore(); its descriptor is kept to compare with the world's.
    struct Cloth {
        std::string payload;
        bool alive = false;
        ClothDesc desc;
    };
    std::vector<Cloth> cloths;
    std::vector<detail::PaperSheet> papers;
    detail::RigidTable rigids;
    std::vector<Event> pending;
    std::vector<detail::StringPairContact> previous_pairs;
    std::vector<detail::PairKey> deep_pairs;
    double time = 0.0;
    std::int64_t steps = 0;
    std::vector<SnapshotSection> host;
};

Snapshot::Snapshot(std::unique_ptr<Data> data) : data_(std::move(data)) {}
Snapshot::Snapshot(Snapshot&&) noexcept = default;
Snapshot& Snapshot::operator=(Snapshot&&) noexcept = default;
Snapshot::~Snapshot() = default;
const std::vector<SnapshotSection>& Snapshot::hostSections() const { return data_->host; }
bool Snapshot::hasRigid(RigidId id) const {
    return id.index < data_->rigids.bodies.size() && data_->rigids.used[id.index];
}

void saveSnapshot(const World& world, std::ostream& out, const std::vector<SnapshotSection>& host) {
    for (const SnapshotSection& s : host)
        if (s.tag.size() != 4 || isCoreTag(s.tag))
            throw InvalidInput("host", "a host section needs a 4-character tag that is not a core tag (got \"" + s.tag + "\")");
    const detail::WorldParts w = detail::WorldAccess::parts(const_cast<World&>(world));
    Writer file;
    file.raw(kMagic, sizeof kMagic);
    std::uint64_t header = kSnapshotVersion;  // u32 version, u32 reserved
    file.word(header);
    auto section = [&](const char* tag, const std::string& payload) {
        file.raw(tag, 4);
        std::uint64_t length = payload.size();
        file.word(length);
        file.raw(payload.data(), payload.size());
    };
    {
        Writer s;
        io(s, *w.settings);
        io(s, *w.time);
        io(s, *w.steps);
        std::uint64_t slots = w.strings->size(), bodies = w.rigids->bodies.size();
        std::uint64_t cloth_slots = w.cloths->size(), paper_slots = w.papers->size();
        io(s, slots);
        io(s, bodies);
        io(s, cloth_slots);
        io(s, paper_slots);
        section("WRLD", s.bytes);
    }
    {
        Writer s;
        io(s, w.rigids->bodies);
        io(s, w.rigids->used);
        io(s, w.rigids->start_position);
        std::vector<Quat> orientations = w.rigids->start_orientation;
        io(s, orientations);
        io(s, w.rigids->fresh);
        section("RIGD", s.bytes);
    }
    for (detail::StringState& string : *w.strings) {
        Writer s;
        io(s, string);
        section("STRG", s.bytes);
    }
    for (detail::ClothState& cloth : *w.cloths) {
        Writer s;
        io(s, cloth);
        section("CLTH", s.bytes);
    }
    for (detail::PaperSheet& sheet : *w.papers) {
        Writer s;
        io(s, sheet);
        section("PAPR", s.bytes);
    }
    {
        Writer s;
        io(s, *w.previous_pairs);
        io(s, *w.deep_pairs);
        section("SCOL", s.bytes);
    }
    {
        Writer s;
        io(s, *w.pending);
        section("EVNT", s.bytes);
    }
    for (const SnapshotSection& h : host) section(h.tag.c_str(), h.payload);
    section("END ", std::string());
    std::uint64_t checksum = fnv1a(file.bytes.data(), file.bytes.size());
    file.word(checksum);
    out.write(file.bytes.data(), static_cast<std::streamsize>(file.bytes.size()));
    if (!out) throw std::runtime_error("writing the snapshot failed");
}

Snapshot Snapshot::read(std::istream& in) {
    const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    if (bytes.size() < sizeof kMagic || std::memcmp(bytes.data(), kMagic, sizeof kMagic) != 0)
        throw SnapshotError("snapshot", "not a tearables snapshot (no TEARSNAP header)");
    if (bytes.size() < kHeaderBytes + kChecksumBytes)
        throw SnapshotError("snapshot", "truncated (" + std::to_string(bytes.size()) + " bytes)");
    Reader header(bytes.data() + sizeof kMagic, bytes.data() + kHeaderBytes, "snapshot");
    std::uint64_t word = 0;
    header.word(word);
    const auto version = static_cast<std::uint32_t>(word & 0xffffffffu);
    if (version != kSnapshotVersion)
        throw SnapshotError("snapshot.version", "version " + std::to_string(version) + " (this build reads version " +
                                                    std::to_string(kSnapshotVersion) + ")");
    if ((word >> 32) != 0) throw SnapshotError("snapshot", "reserved header bits are set");
    const std::size_t body_end = bytes.size() - kChecksumBytes;
    Reader tail(bytes.data() + body_end, bytes.data() + bytes.size(), "snapshot");
    std::uint64_t checksum = 0;
    tail.word(checksum);
    if (checksum != fnv1a(bytes.data(), body_end))
        throw SnapshotError("snapshot", "checksum mismatch: the file is truncated or corrupt");

    auto data = std::make_unique<Data>();
    Data& d = *data;
    Reader file(bytes.data() + kHeaderBytes, bytes.data() + body_end, "snapshot");
    bool have_world = false, have_rigids = false, ended = false;
    std::uint64_t slots = 0, bodies = 0, cloth_slots = 0, paper_slots = 0;
    while (!ended) {
        if (file.remaining() == 0) file.fail("truncated: no END section");
        std::string tag(4, ' ');
        file.raw(tag.data(), 4);
        std::uint64_t length = 0;
        file.word(length);
        if (length > file.remaining()) file.fail("section \"" + tag + "\" is longer than the file");
        std::string payload(static_cast<std::size_t>(length), '\0');
        file.raw(payload.data(), payload.size());
        Reader s(payload.data(), payload.data() + payload.size(), "snapshot." + tag);
        if (tag == "WRLD") {
            if (have_world) s.fail("appears twice");
            io(s, d.settings);
            io(s, d.time);
            io(s, d.steps);
            io(s, slots);
            io(s, bodies);
            io(s, cloth_slots);
            io(s, paper_slots);
            try {
                validate(d.settings);
            } catch (const InvalidInput& e) {
                s.fail(std::string("invalid settings: ") + e.what());
            }
            if (!std::isfinite(d.time) || d.time < 0.0 || d.steps < 0) s.fail("invalid time or step count");
            have_world = true;
        } else if (tag == "RIGD") {
            if (!have_world || have_rigids) s.fail("out of order (expected once, after WRLD)");
            io(s, d.rigids.bodies);
            io(s, d.rigids.used);
            io(s, d.rigids.start_position);
            io(s, d.rigids.start_orientation);
            io(s, d.rigids.fresh);
            const std::size_t n = d.rigids.bodies.size();
            if (n != bodies || d.rigids.used.size() != n || d.rigids.start_position.size() != n ||
                d.rigids.start_orientation.size() != n || d.rigids.fresh.size() != n)
                s.fail("the rigid table's arrays disagree");
            for (std::size_t i = 0; i < n; ++i) {
                const RigidState& b = d.rigids.bodies[i];
                if (!b.position.allFinite() || !b.orientation.coeffs().allFinite() || !b.linear_velocity.allFinite() ||
                    !b.angular_velocity.allFinite() || !std::isfinite(b.inverse_mass) || b.inverse_mass < 0.0 ||
                    !b.inverse_inertia_local.allFinite())
                    s.fail("rigid slot " + std::to_string(i) + " has a non-finite state");
            }
            have_rigids = true;
        } else if (tag == "STRG") {
            if (!have_rigids) s.fail("out of order (expected after RIGD)");
            if (d.strings.size() >= slots) s.fail("more string sections than the world has slots");
            d.strings.emplace_back();
            detail::StringState& string = d.strings.back();
            io(s, string);
            if (string.alive) {
                checkString(string, d.rigids, "snapshot.STRG[" + std::to_string(d.strings.size() - 1) + "]");
            } else {
                const std::uint32_t generation = string.generation;
                string = detail::StringState{};
                string.alive = false;
                string.generation = generation;
            }
        } else if (tag == "CLTH") {
            if (!have_rigids) s.fail("out of order (expected after RIGD)");
            if (d.cloths.size() >= cloth_slots) s.fail("more cloth sections than the world has cloth slots");
            const std::string where = "snapshot.CLTH[" + std::to_string(d.cloths.size()) + "]";
            const detail::ClothState cloth = readCloth(payload, d.rigids, where);
            d.cloths.push_back({std::move(payload), cloth.alive, cloth.desc});
            continue;  // readCloth checked that nothing is left over
        } else if (tag == "PAPR") {
            if (!have_rigids) s.fail("out of order (expected after RIGD)");
            if (d.papers.size() >= paper_slots) s.fail("more paper sections than the world has paper slots");
            d.papers.emplace_back();
            detail::PaperSheet& sheet = d.papers.back();
            io(s, sheet);
            if (sheet.alive) {
                checkPaper(sheet, d.rigids, "snapshot.PAPR[" + std::to_string(d.papers.size() - 1) + "]");
            } else {
                const std::uint32_t generation = sheet.generation;
                sheet = detail::PaperSheet{};
                sheet.alive = false;
                sheet.generation = generation;
            }
        } else if (tag == "SCOL") {
            io(s, d.previous_pairs);
            io(s, d.deep_pairs);
        } else if (tag == "EVNT") {
            io(s, d.pending);
        } else if (tag == "END ") {
            ended = true;
        } else {
            bool printable = true;
            for (char c : tag) printable = printable && c >= 0x20 && c < 0x7f;
            if (!printable) s.fail("a section with an unreadable tag (the file is corrupt)");
            d.host.push_back({tag, std::move(payload)});
            continue;
        }
        if (s.remaining() != 0) s.fail(std::to_string(s.remaining()) + " bytes left over at the end of the section");
    }
    if (file.remaining() != 0) file.fail("data after the END section");
    if (!have_world || !have_rigids) file.fail("the WRLD or RIGD section is missing");
    if (d.strings.size() != slots)
        file.fail("has " + std::to_string(d.strings.size()) + " string sections for " + std::to_string(slots) + " slots");
    if (d.cloths.size() != cloth_slots)
        file.fail("has " + std::to_string(d.cloths.size()) + " cloth sections for " + std::to_string(cloth_slots) + " cloth slots");
    if (d.papers.size() != paper_slots)
        file.fail("has " + std::to_string(d.papers.size()) + " paper sections for " + std::to_string(paper_slots) + " paper slots");
    for (const detail::StringPairContact& c : d.previous_pairs) {
        auto ok = [&](std::uint32_t string, std::uint32_t segment) {
            return string < d.strings.size() && d.strings[string].alive && segment < d.strings[string].segments();
        };
        if (!ok(c.string, c.segment) || !ok(c.partner, c.partner_segment))
            throw SnapshotError("snapshot.SCOL", "a contact names a segment the snapshot does not have");
    }
    for (const Event& e : d.pending)
        if (!std::isfinite(e.stress) || !std::isfinite(e.time)) throw SnapshotError("snapshot.EVNT", "a non-finite event");
    return Snapshot(std::move(data));
}

namespace {

/// The bytes of a descriptor as a snapshot writes them: two descriptors are the same when
/// these are.
template <class Desc>
std::string descBytes(Desc desc) {
    Writer w;
    io(w, desc);
    return w.bytes;
}

/// A world that has cloths (or sheets) takes a snapshot only when they are the snapshot's:
/// the same slots, created from the same descriptors (the ids a user holds keep naming
/// the same objects). A world without any takes the snapshot's. `kind` is "cloth" or
/// "paper sheet", `tag` the section's.
template <class Desc>
void checkSameObjects(const std::vector<std::pair<bool, const Desc*>>& world, const std::vector<std::pair<bool, const Desc*>>& snapshot,
                      const char* kind, const char* tag, const std::string& plural) {
    bool any = false;
    for (const auto& slot : world) any = any || slot.first;
    if (!any) return;
    const std::string where = std::string("snapshot.") + tag;
    const std::string remedy = ": restore into a world with the snapshot's " + plural + " or none";
    for (std::size_t i = 0; i < std::max(world.size(), snapshot.size()); ++i) {
        const bool in_world = i < world.size() && world[i].first, in_snapshot = i < snapshot.size() && snapshot[i].first;
        const std::string id = std::string(kind) + " " + std::to_string(i);
        if (in_world && !in_snapshot)
            throw SnapshotError(where, "the world has " + id + " (\"" + world[i].second->name + "\"), which the snapshot does not have" + remedy);
        if (!in_world && in_snapshot)
            throw SnapshotError(where, "the snapshot has " + id + " (\"" + snapshot[i].second->name + "\"), which the world does not have" + remedy);
        if (!in_world) continue;
        const Desc& a = *world[i].second;
        const Desc& b = *snapshot[i].second;
        if (a.name != b.name)
            throw SnapshotError(where, id + " is \"" + a.name + "\" in the world and \"" + b.name + "\" in the snapshot" + remedy);
        if (a.resolution[0] != b.resolution[0] || a.resolution[1] != b.resolution[1])
            throw SnapshotError(where, id + " (\"" + a.name + "\") has resolution " + std::to_string(a.resolution[0]) + " x " +
                                           std::to_string(a.resolution[1]) + " in the world and " + std::to_string(b.resolution[0]) +
                                           " x " + std::to_string(b.resolution[1]) + " in the snapshot" + remedy);
        if (descBytes(a) != descBytes(b))
            throw SnapshotError(where, id + " (\"" + a.name + "\") was created from another descriptor than the snapshot's" + remedy);
    }
}

}  // namespace

void Snapshot::restore(World& world) const {
    const detail::WorldParts w = detail::WorldAccess::parts(world);
    // Refused before anything changes: cloths and sheets that are not the snapshot's.
    {
        std::vector<std::pair<bool, const ClothDesc*>> mine, theirs;
        for (const detail::ClothState& c : *w.cloths) mine.emplace_back(c.alive, &c.desc);
        for (const Data::Cloth& c : data_->cloths) theirs.emplace_back(c.alive, &c.desc);
        checkSameObjects(mine, theirs, "cloth", "CLTH", "cloths");
        std::vector<std::pair<bool, const PaperDesc*>> sheets, saved;
        for (const detail::PaperSheet& s : *w.papers) sheets.emplace_back(s.alive, &s.desc);
        for (const detail::PaperSheet& s : data_->papers) saved.emplace_back(s.alive, &s.desc);
        checkSameObjects(sheets, saved, "paper sheet", "PAPR", "paper sheets");
    }
    // Read again from their checked sections (cannot fail).
    std::vector<detail::ClothState> cloths;
    for (std::size_t i = 0; i < data_->cloths.size(); ++i)
        cloths.push_back(readCloth(data_->cloths[i].payload, data_->rigids, "snapshot.CLTH[" + std::to_string(i) + "]"));
    *w.cloths = std::move(cloths);
    *w.papers = data_->papers;
    *w.settings = data_->settings;
    *w.strings = data_->strings;
    // The block factorisation is rebuilt by every step; it is sized here, not copied (a
    // default-constructed Eigen::LLT has an uninitialised status, which UBSan flags when
    // copied). So are the chain solve's tension estimate (filled from spring_force at every
    // solve) and its pivots' inverses (written by a solve before a chord iteration reads them).
    for (detail::StringState& s : *w.strings)
        if (s.alive) {
            s.scratch.blk_factor.resize(s.particles());
            s.scratch.chain_inverse.assign(6 * s.particles() + 12, 0.0);
            s.scratch.chain_coupled.assign(s.particles(), 0);
            s.scratch.twist_skipped = s.scratch.twist_force_zero = false;  // scratch: the next step computes them
            s.scratch.geometric_tension.assign(s.segments(), 0.0);
            // Not in the snapshot's bytes: whether a row projector differs from I.
            s.scratch.rows_pressed = std::any_of(s.scratch.row_projector.begin(), s.scratch.row_projector.end(),
                                         [](const Mat3& r) { return r != Mat3::Identity(); });
        }
    *w.rigids = data_->rigids;
    *w.pending = data_->pending;
    w.events->clear();
    *w.previous_pairs = data_->previous_pairs;
    *w.deep_pairs = data_->deep_pairs;
    *w.time = data_->time;
    *w.steps = data_->steps;
}

void loadSnapshot(World& world, std::istream& in) {
    const Snapshot snapshot = Snapshot::read(in);
    if (!snapshot.hostSections().empty())
        throw SnapshotError("snapshot." + snapshot.hostSections().front().tag,
                            "a host's section (written by BulletWorld::saveSnapshot? load it through BulletWorld)");
    snapshot.restore(world);
}

}  // namespace tearables
