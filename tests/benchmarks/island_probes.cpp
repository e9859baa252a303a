// tearables_island_probes: issue 30's physics targets (items 2-5), each measured on a
// scene built as a Bullet user builds it, printed beside its target, one line each.
// Not a test: it prints today's values (docs/island-baseline.md) so that the island
// solver's effect on each can be read. Every step is 1/100 s (one internal Bullet step)
// unless a probe says otherwise.
// Run: build/tests/benchmarks/tearables_island_probes [crate|statics|capstan|momentum|overlap]
// or `closing V` (two island boxes thrown at each other at +-V m/s, step by step)
// or `momentum-trace` (not in the default run): item 3's scene step by step; with
// tools/momentum_stage_trace.patch applied and TEARABLES_MTRACE set, each stage's share.
#include "island_scenes.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>

namespace {

using namespace tearables;
using island::Rig;

constexpr double kPi = 3.14159265358979323846;
constexpr double kG = 9.81;

void line(const char* probe, const std::string& value, const char* target, bool met) {
    std::printf("%-44s %-58s target %-26s %s\n", probe, value.c_str(), target, met ? "met" : "NOT MET");
}
std::string fmt(const char* f, double a, double b = 0, double c = 0, double d = 0) {
    char buf[256];
    std::snprintf(buf, sizeof buf, f, a, b, c, d);
    return buf;
}

// Item 2: a crate set down at rest on the middle board of a 7-board bridge (3 kg boards,
// 3 cm thick, the scene), after the bridge settled for `settle` s; 2 s after.
// Penetration: how far the crate's centre is below where it would rest, in the board's
// frame (board half thickness + crate half size - local y), until it goes through, and,
// independently, the deepest Bullet contact point between the two (-getDistance()).
// Through: the penetration passes the board's thickness (the crate's bottom face below
// the board's).
void heavyCrate(double crate_mass, double settle) {
    const double board_half = 0.015, crate_half = 0.1;
    const int boards = 7, middle = 3, steps = 200;
    Rig rig;
    const auto bridge = island::buildBridge(rig, {boards, 3.0, board_half, 0.8, false});
    for (auto* b : bridge.boards) b->setActivationState(DISABLE_DEACTIVATION);
    for (int i = 0; i < static_cast<int>(std::lround(settle / 0.01)); ++i) rig.step();
    btRigidBody& board = *bridge.boards[middle];
    const btTransform at = board.getWorldTransform();
    const btVector3 up = at.getBasis().getColumn(1);
    btRigidBody& crate = rig.phys.box(btVector3(0.1f, 0.1f, 0.1f), crate_mass,
                                      at.getOrigin() + up * static_cast<btScalar>(board_half + crate_half + 0.0005));
    crate.setWorldTransform(btTransform(at.getRotation(), crate.getWorldTransform().getOrigin()));
    crate.setFriction(0.8f);
    crate.setActivationState(DISABLE_DEACTIVATION);
    double worst_geometric = 0, worst_manifold = 0, at_01 = 0, through_at = -1, last = 0;
    for (int i = 1; i <= steps; ++i) {
        rig.step();
        const btTransform b = board.getWorldTransform();
        const btVector3 local = b.invXform(crate.getCenterOfMassPosition());
        const double sink = (board_half + crate_half) - local.y();
        if (sink > 2 * board_half && through_at < 0) through_at = 0.01 * i;
        if (through_at < 0) worst_geometric = std::max(worst_geometric, sink);
        if (i == 10) at_01 = sink;
        last = sink;
        auto* dispatcher = rig.phys.world->getDispatcher();
        for (int m = 0; m < dispatcher->getNumManifolds(); ++m) {
            const auto* manifold = dispatcher->getManifoldByIndexInternal(m);
            const bool pair = (manifold->getBody0() == &crate && manifold->getBody1() == &board) ||
                              (manifold->getBody1() == &crate && manifold->getBody0() == &board);
            if (!pair) continue;
            for (int c = 0; c < manifold->getNumContacts(); ++c)
                worst_manifold = std::max(worst_manifold, -static_cast<double>(manifold->getContactPoint(c).getDistance()));
        }
    }
    const std::string name =
        fmt("crate %.0f kg (%.1fx) on a 3 kg board, after %.0f s", crate_mass, crate_mass / 3.0, settle);
    std::string value = fmt("penetration up to %.1f mm (contacts %.1f), at 0.1 s %.1f", 1e3 * worst_geometric,
                            1e3 * worst_manifold, 1e3 * at_01);
    value += through_at >= 0 ? fmt("; through at %.2f s", through_at) : fmt("; stays, %.1f mm at 2 s", 1e3 * last);
    line(name.c_str(), value, "< 2 mm, stays", worst_geometric < 0.002 && through_at < 0);
}

// Item 3: the bridge's statics. The `bridge` scene's bridge (island_scenes.hpp: 8 boards of
// 4 kg, 18 ropes, 746 segments) settles for 1 s; then `crates` 10 kg crates (0.2 m cubes)
// are set down at rest on boards 3 and 4 (the scene's first two), 0.5 mm above contact in
// the board's frame; 5 s more. Over the last second, every step: the anchors' vertical
// pull against the weight of every rope particle, board and crate. At each of the four
// pinned ends the end segment pulls its pinned particle toward the next one with T u,
// u = (x_next - x_pin)/|...|; the pin holds that and the particle's weight, so its upward
// reaction is -T u_y + m_pin g. T is the library's momentum-balance tension (the API
// gives no pin reaction force). "Mean" is the target's "on average while it swings";
// min and max show how far from rest it still is.
void bridgeStatics(int crates) {
    const int settle = 100, steps = 500, window = 100;
    Rig rig;
    const auto bridge = island::buildBridge(rig, {});
    for (auto* b : bridge.boards) b->setActivationState(DISABLE_DEACTIVATION);
    for (int i = 0; i < settle; ++i) rig.step();
    double weight = kG * bridge.board_mass * static_cast<double>(bridge.boards.size());
    for (StringId id : bridge.ropes) weight += kG * island::ropeMass(rig.ropes->core(), id);
    std::vector<btRigidBody*> placed;
    for (int k = 0; k < crates; ++k) {
        btRigidBody& board = *bridge.boards[k == 0 ? 3 : 4];
        const btTransform at = board.getWorldTransform();
        btRigidBody& crate = rig.phys.box(btVector3(0.1f, 0.1f, 0.1f), 10.0,
                                          at.getOrigin() + at.getBasis().getColumn(1) * (0.04f + 0.1f + 0.0005f));
        crate.setWorldTransform(btTransform(at.getRotation(), crate.getWorldTransform().getOrigin()));
        crate.setFriction(0.8f);
        crate.setActivationState(DISABLE_DEACTIVATION);
        placed.push_back(&crate);
        weight += kG * 10.0;
    }
    double sum = 0, lo = 1e9, hi = -1e9;
    for (int i = 1; i <= steps; ++i) {
        rig.step();
        if (i <= steps - window) continue;
        const double pull = tearables::island::anchorPull(rig.ropes->core(), bridge, kG);
        const double ratio = pull / weight;
        sum += ratio;
        lo = std::min(lo, ratio);
        hi = std::max(hi, ratio);
    }
    int tears = 0;
    for (const auto& e : rig.ropes->events()) tears += e.type == EventType::Tear;
    bool fell = false;
    for (auto* c : placed) fell = fell || c->getCenterOfMassPosition().y() < 1.5f;
    const double mean = sum / window;
    const std::string name = fmt("bridge statics, %.0f crates (10 kg) on it", crates);
    std::string value = fmt("pull / weight over the last 1 s: mean %.4f (min %.4f, max %.4f)", mean, lo, hi);
    if (tears) value += fmt(", %.0f tears", tears);
    if (fell) value += ", a crate fell";
    line(name.c_str(), value, "within 0.5% (mean)", std::abs(mean - 1) < 0.005);
}

// Item 4: the capstan. A rope (radius 3 mm, 1 cm segments) wraps a fixed horizontal capsule
// (radius 5 cm, along z, friction 0.25; the plugin's rope-body friction is the body's)
// by `theta`, with straight 0.3 m tails leaving it on its tangents; wraps past half a turn
// advance 12 mm in z a turn so the rope clears itself. Zero gravity: the tails' end
// particles carry 1 kg and M kg and are pulled outward along their tails by 1 g and M g
// (9.81 N/kg), as hanging weights would. With `hanging` (theta = pi only) there are no
// forces: gravity pulls the end masses down both vertical tails, as in the issue.
// Holds: the light end moves less than 1 cm in 2 s from rest; runs off: more than its
// 0.3 m tail (the rope leaves the drum); between the two the rope creeps. The largest M
// that holds and the largest that stays on are each found by bisection over
// [1, 2 e^(mu theta)] (12 halvings), assuming monotonicity in M (a sweep of M in steps of
// 0.1 kg at a half and a full turn found it so).
struct CapstanRun {
    bool holds;
    double light_travel;  // m in 2 s
};
CapstanRun capstanRun(double theta, double heavy, bool hanging) {
    const double R = 0.05, r = 0.003, mu = 0.25, tail = 0.3, seg = 0.01, pitch = 4 * r;
    const double a = R + r + 0.0002;  // axis to rope axis, a hair off contact
    Rig rig(hanging ? -kG : 0.0);
    btRigidBody& drum = rig.phys.add(std::make_unique<btCapsuleShapeZ>(static_cast<btScalar>(R), 1.0f), 0.0,
                                     btVector3(0, 0, 0));
    drum.setFriction(static_cast<btScalar>(mu));
    // Arc from phi1 = pi/2 + theta/2 to phi2 = pi/2 - theta/2 (clockwise over the top).
    const double phi1 = kPi / 2 + theta / 2, phi2 = kPi / 2 - theta / 2;
    const double z_end = pitch * theta / (2 * kPi);
    const Vec3 p1(a * std::cos(phi1), a * std::sin(phi1), 0), p2(a * std::cos(phi2), a * std::sin(phi2), z_end);
    const Vec3 t1(-std::sin(phi1), std::cos(phi1), 0), t2(std::sin(phi2), -std::cos(phi2), 0);  // outward tails
    std::vector<Vec3> pts;
    const int nt = static_cast<int>(std::lround(tail / seg));
    for (int i = nt; i > 0; --i) pts.push_back(p1 + t1 * (tail * i / nt));
    const int na = std::max(2, static_cast<int>(std::lround(a * theta / seg)));
    for (int i = 0; i <= na; ++i) {
        const double s = static_cast<double>(i) / na;
        const double phi = phi1 + (phi2 - phi1) * s;
        pts.emplace_back(a * std::cos(phi), a * std::sin(phi), z_end * s);
    }
    for (int i = 1; i <= nt; ++i) pts.push_back(p2 + t2 * (tail * i / nt));
    StringDesc d;
    d.points = pts;
    d.radius = r;
    d.tearable = false;
    d.material.variation = 0.0;
    d.particle_masses = {{0, 1.0}, {-1, heavy}};
    const StringId id = rig.ropes->addString(d);
    const Vec3 start = pts.front();
    for (int i = 0; i < 200; ++i) {
        if (!hanging) {
            rig.ropes->core().applyForce(id, 0, t1 * (1.0 * kG));
            rig.ropes->core().applyForce(id, -1, t2 * (heavy * kG));
        }
        rig.step();
    }
    const double travel = ((*rig.ropes->core().view(id).positions)[0] - start).norm();
    return {travel < 0.01, travel};
}
// Bisection, 12 halvings over [lo, hi], for the largest mass at which `pred` still holds
// (pred(lo) true, pred(hi) false; assumed monotonic).
template <class Pred>
double largestWhere(double lo, double hi, Pred pred) {
    for (int k = 0; k < 12; ++k) {
        const double mid = 0.5 * (lo + hi);
        (pred(mid) ? lo : hi) = mid;
    }
    return lo;
}
void capstan(double theta, const char* label, bool hanging) {
    const double mu = 0.25, closed = std::exp(mu * theta), tail = 0.3;
    const double lo = 1.0, hi = 2 * closed;
    if (!capstanRun(theta, lo, hanging).holds) {
        line(label, "1 kg against 1 kg already slides", "within 5% of e^(mu theta)", false);
        return;
    }
    if (capstanRun(theta, hi, hanging).holds) {
        line(label, fmt("holds even %.2f kg (2 e^(mu theta))", hi), "within 5% of e^(mu theta)", false);
        return;
    }
    // Holds: under 1 cm in 2 s. Runs off: the light end travels more than its tail (0.3 m),
    // so the rope leaves the drum; between the two it creeps.
    const double holds = largestWhere(lo, hi, [&](double m) { return capstanRun(theta, m, hanging).holds; });
    const double stays_on =
        largestWhere(lo, hi, [&](double m) { return capstanRun(theta, m, hanging).light_travel < tail; });
    const auto below = capstanRun(theta, 0.95 * closed, hanging);
    const std::string value = fmt("holds to %.3f kg = %.3f e^(mu theta) (%.3f kg); creeps to %.3f kg", holds,
                                  holds / closed, closed, stays_on) +
                              fmt(" = %.3f, runs off above; at 0.95 e^(mu theta) travels %.0f mm", stays_on / closed,
                                  1e3 * below.light_travel);
    line(label, value, "within 5% of e^(mu theta)", std::abs(holds / closed - 1) < 0.05);
        if (hanging)
        for (double m : {1.3, 1.6, 1.95})
            std::printf("    %.2f kg on the other end: the light end travels %.1f mm in 2 s\n", m,
                        1e3 * capstanRun(theta, m, hanging).light_travel);
}

// Item 3: momentum. Zero gravity. A rope (1 m, 40 segments, radius 5 mm) along x held at
// its ends by two free 1 kg boxes (glued); a 2 kg box (0.2 m cube) thrown at its middle at
// 4 m/s. `crossing`: a second such rope along z, 12 mm below the first (2 mm gap), held
// the same way, so the box presses a rope that touches another. `heavy_density`: the
// ropes' density (1150 nylon: 0.09 kg a rope; 20000: 1.6 kg). Nothing tears. Drift: the
// largest |P(t) - P(0)| / |P(0)| over 1 s (P: every rope particle and body); energy: the
// largest E(t) / E(0) (kinetic; no potential in zero gravity, the ropes do not stretch
// measurably). `island_contacts`: WorldSettings::island_string_contacts (the strings'
// contacts solved with the bodies; off: held still in the strings' joint solve).
void momentum(bool crossing, double density, bool island_contacts = true) {
    WorldSettings settings;
    settings.island_string_contacts = island_contacts;
    Rig rig(0.0, settings);
    std::vector<btRigidBody*> bodies;
    std::vector<StringId> ropes;
    auto holdRope = [&](const Vec3& from, const Vec3& to) {
        ropes.push_back(island::ropeHeldByBoxes(rig.phys, *rig.ropes, from, to, density, bodies));
    };
    holdRope({-0.5, 0, 0}, {0.5, 0, 0});
    if (crossing) holdRope({0, -0.012, -0.5}, {0, -0.012, 0.5});
    btRigidBody& thrown = rig.phys.box(btVector3(0.1f, 0.1f, 0.1f), 2.0, btVector3(0.02f, 0.3f, 0));
    thrown.setLinearVelocity(btVector3(0, -4, 0));
    thrown.setActivationState(DISABLE_DEACTIVATION);
    bodies.push_back(&thrown);
    auto total = [&](Vec3* p, double* e) {
        *p = Vec3::Zero();
        *e = 0;
        for (auto* b : bodies) {
            *p += toCore(b->getLinearVelocity()) / static_cast<double>(b->getInvMass());
            *e += testing::kineticEnergy(*b);
        }
        for (StringId id : ropes) {
            *p += island::ropeMomentum(rig.ropes->core(), id);
            *e += island::ropeKinetic(rig.ropes->core(), id);
        }
    };
    Vec3 p0;
    double e0;
    total(&p0, &e0);
    double drift = 0, gain = 0, rope_mass = 0;
    for (StringId id : ropes) rope_mass += island::ropeMass(rig.ropes->core(), id);
    for (int i = 0; i < 100; ++i) {
        rig.step();
        Vec3 p;
        double e;
        total(&p, &e);
        drift = std::max(drift, (p - p0).norm() / p0.norm());
        gain = std::max(gain, e / e0);
    }
    const std::string name = fmt(crossing ? (island_contacts ? "box thrown at a rope on a crossing rope, ropes %.2f kg"
                                                             : "box thrown at a rope on a crossing rope, ropes %.2f kg, bodies held (island_string_contacts off)")
                                          : "box thrown at a rope held by 2 bodies, rope %.2f kg",
                                 rope_mass / static_cast<double>(ropes.size()));
    line(name.c_str(), fmt("momentum drift %.3f%%, largest E/E0 %.4f", 100 * drift, gain), "drift < 0.1%, E/E0 <= 1",
         drift < 0.001 && gain <= 1.0 + 1e-9);
}

// Item 3's trace: the scene of `momentum` (one rope), stepped 40 times (the box meets the
// rope at t = 0.05 s), printing per step the linear momentum (kg m/s, y component: the
// throw is along -y, x and z stay ~0) of the rope, the two end bodies and the box, and
// the change of the total. `kick`: no box; the left end body is given 1 m/s along y
// instead, so only the glue couples (no contact rows).
void momentumTrace(double density, bool kick) {
    Rig rig(0.0);
    StringDesc d = StringDesc::straight({-0.5, 0, 0}, {0.5, 0, 0}, 40);
    d.radius = 0.005;
    d.density = density;
    d.tearable = false;
    d.material.variation = 0.0;
    const StringId id = rig.ropes->addString(d);
    btRigidBody* ends[2];
    for (int end : {0, 1}) {
        const double sx = end == 0 ? -1.0 : 1.0;
        btRigidBody& b = rig.phys.box(btVector3(0.05f, 0.05f, 0.05f), 1.0, btVector3(static_cast<float>(0.56 * sx), 0, 0));
        b.setActivationState(DISABLE_DEACTIVATION);
        rig.ropes->attach(id, end == 0 ? 0 : -1, b, btVector3(static_cast<float>(-0.06 * sx), 0, 0));
        ends[end] = &b;
    }
    btRigidBody* thrown = nullptr;
    if (kick) {
        ends[0]->setLinearVelocity(btVector3(0, 1, 0));
    } else {
        thrown = &rig.phys.box(btVector3(0.1f, 0.1f, 0.1f), 2.0, btVector3(0.02f, 0.3f, 0));
        thrown->setLinearVelocity(btVector3(0, -4, 0));
        thrown->setActivationState(DISABLE_DEACTIVATION);
    }
    auto py = [](const btRigidBody* b) { return b ? static_cast<double>(b->getLinearVelocity().y()) / b->getInvMass() : 0.0; };
    std::printf("  %s, rope %.3f kg\n", kick ? "left end kicked 1 m/s" : "box thrown", island::ropeMass(rig.ropes->core(), id));
    std::printf("    step   rope Py   ends Py    box Py   total Py  dTotal\n");
    double last = island::ropeMomentum(rig.ropes->core(), id).y() + py(ends[0]) + py(ends[1]) + py(thrown);
    for (int i = 1; i <= 40; ++i) {
        rig.step();
        const double rope = island::ropeMomentum(rig.ropes->core(), id).y();
        const double e = py(ends[0]) + py(ends[1]);
        const double total = rope + e + py(thrown);
        std::printf("    %4d %9.5f %9.5f %9.5f %9.5f %+.2e\n", i, rope, e, py(thrown), total, total - last);
        last = total;
    }
}

// Item 5: a rope (1 m, 50 segments, radius 2 mm, default nylon) hanging from the centre of
// a static 0.2 m cube, so its first 5 segments start inside the cube; held there by a glue
// to the cube or by a pin. The control (`inside` false): the cube raised so that its
// bottom face is 3 mm above the held end (rope radius 2 mm), so only the overlap
// differs. Reported: tears in the first step and in the first second, and
// the first step's peak stress (the largest tear event's stress, or the largest tension
// over the section) over the material's rupture stress.
// Two island boxes meeting face to face (docs/island-plan.md, "Boxes that pass through
// each other"): two 1 kg, 0.1 m boxes joined by a slack rope arched over them (so both are
// island bodies), no gravity, thrown at each other at +-v along x, 1/60 s steps. Per
// step: the boxes' centres and speeds, the gap between their faces (negative: inside each
// other), and the island's body-body contacts where the step started (points on A, the
// gap there) with the force the solve left on each.
void closing(double v) {
    Rig rig(0.0);
    const island::ClosingBoxes boxes = island::buildClosingBoxes(rig.phys, *rig.ropes, v);
    const btRigidBody &a = *boxes.a, &b = *boxes.b;
    std::printf("two 0.1 m boxes closing at %g m/s\n", 2 * v);
    for (int i = 1; i <= 12; ++i) {
        rig.phys.world->stepSimulation(1.0f / 60.0f, 1, 1.0f / 60.0f);
        const double xa = a.getCenterOfMassPosition().x(), xb = b.getCenterOfMassPosition().x();
        std::printf("step %2d: A at %.4f (%.3f m/s), B at %.4f (%.3f m/s), faces %.4f m apart\n", i, xa, a.getLinearVelocity().x(), xb,
                    b.getLinearVelocity().x(), xb - xa - 0.1);
        for (const BodyContact& c : rig.ropes->core().lastBodyContacts())
            std::printf("    contact at (%.4f, %.4f, %.4f) on A, gap %.4f, force %.1f N\n", c.point_a.x(), c.point_a.y(), c.point_a.z(),
                        c.normal.dot(c.point_a - c.point_b), c.force);
    }
}

void overlapStart(bool glued, bool inside = true) {
    Rig rig;
    const btScalar lift = inside ? 0.0f : 0.103f;
    btRigidBody& cube = rig.phys.box(btVector3(0.1f, 0.1f, 0.1f), 0.0, btVector3(0, 2 + lift, 0));
    StringDesc d = StringDesc::straight({0, 2, 0}, {0, 1, 0}, 50);
    const StringId id = rig.ropes->addString(d);
    if (glued)
        rig.ropes->attach(id, 0, cube, btVector3(0, -lift, 0));
    else
        rig.ropes->attach(id, 0, btVector3(0, 2, 0));
    const double area = kPi * d.radius * d.radius;
    rig.step();
    int first_tears = 0;
    double peak = 0;
    for (const auto& e : rig.ropes->events())
        if (e.type == EventType::Tear) {
            ++first_tears;
            peak = std::max(peak, e.stress);
        }
    for (double t : *rig.ropes->core().view(id).tension) peak = std::max(peak, t / area);
    for (int i = 1; i < 100; ++i) rig.step();
    int tears = 0;
    for (const auto& e : rig.ropes->events()) tears += e.type == EventType::Tear;
    std::string name = glued ? "rope starting inside the cube it is glued to" : "rope starting inside a cube, pinned";
    if (!inside) name = glued ? "control: glued 3 mm below the cube" : "control: pinned 3 mm below the cube";
    line(name.c_str(),
         fmt("tears in step 1: %.0f (in 1 s: %.0f); step 1 peak stress %.1fx rupture", first_tears, tears,
             peak / d.material.tensile.rupture),
         "no tear, pushed out gently", first_tears == 0 && tears == 0);
}

}  // namespace

// With an argument, only the probes of that group: crate, statics, capstan, momentum, overlap.
int main(int argc, char** argv) {
    const std::string only = argc > 1 ? argv[1] : "";
    auto want = [&](const char* group) { return only.empty() || only == group; };
    std::printf("issue 30, items 2-5: today's values against the targets\n");
    if (want("crate"))
        for (double settle : {1.0, 3.0})
            for (double m : {5.0, 10.0, 60.0}) heavyCrate(m, settle);
    if (want("statics"))
        for (int c : {0, 1, 2}) bridgeStatics(c);
    if (want("capstan")) {
        capstan(kPi, "capstan, half turn, hanging 1 kg (gravity)", true);
        capstan(kPi / 2, "capstan, quarter turn (end forces)", false);
        capstan(kPi, "capstan, half turn (end forces)", false);
        capstan(2 * kPi, "capstan, full turn (end forces)", false);
    }
    // `capstan-at THETA_OVER_PI MASS_OVER_E HANGING`: one capstan run, the light end's travel.
    if (only == "capstan-at" && argc > 4) {
        const double theta = std::atof(argv[2]) * kPi, m = std::atof(argv[3]) * std::exp(0.25 * theta);
        std::printf("theta %.2f pi, M %.4f kg (%.3f e^(mu theta)), %s: light end travels %.2f mm in 2 s\n",
                    std::atof(argv[2]), m, std::atof(argv[3]), std::atoi(argv[4]) ? "hanging" : "end forces",
                    1e3 * capstanRun(theta, m, std::atoi(argv[4]) != 0).light_travel);
    }
    if (only == "momentum-trace") {
        for (double density : {1150.0, 20000.0}) {
            momentumTrace(density, false);
            momentumTrace(density, true);
        }
    }
    if (want("momentum")) {
        momentum(false, 1150);
        momentum(false, 20000);
        momentum(true, 1150);
        momentum(true, 1150, false);
    }
    // `rest`: the bridge at rest (BM_IslandRopesVsPinned/1's island), the Newton iterations
    // and final residual of its solve in 10 steps after 100 of settling; `rest-swing [crate]`
    // the same for the swing; `rest-pinned` the bridge's ropes pinned, each rope's Newton
    // iterations a step (chords not counted).
    if (only == "rest-pinned") {
        island::Rig rig;
        const auto ids = island::buildBridge(rig, {8, 4.0, 0.04, 0.8, true}).ropes;
        for (int i = 0; i < 100; ++i) rig.step();
        for (int i = 0; i < 5; ++i) {
            rig.step();
            std::printf("step %d:", 100 + i);
            for (StringId id : ids) std::printf(" %d", rig.ropes->core().view(id).newton_iterations);
            std::printf("\n");
        }
    }
    if (only == "rest" || only == "rest-swing") {
        island::Rig rig;
        if (only == "rest") {
            for (auto* b : island::buildBridge(rig, {}).boards) b->setActivationState(DISABLE_DEACTIVATION);
        } else {
            island::buildSwing(rig, false, argc > 2);
        }
        for (int i = 0; i < 100; ++i) rig.step();
        for (int i = 0; i < 10; ++i) {
            rig.step();
            std::printf("step %d:", 100 + i);
            for (const IslandSummary& s : rig.ropes->core().lastIslands())
                std::printf(" [%zu strings, %zu bodies: %d iterations, residual %.3g]", s.strings, s.bodies, s.iterations, s.residual);
            std::printf("\n");
        }
    }
    // `closing V`: two island boxes thrown at each other at +-V m/s, step by step.
    if (only == "closing") closing(argc > 2 ? std::atof(argv[2]) : 3.0);
    if (want("overlap")) {
        overlapStart(true);
        overlapStart(false);
        overlapStart(true, false);
        overlapStart(false, false);
    }
    return 0;
}
