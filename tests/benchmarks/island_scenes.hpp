// Scenes of issue 30 ("coupling that holds") built as a Bullet user builds them: a
// btDiscreteDynamicsWorld, a tearables::BulletWorld inside it, ropes pinned or glued to
// Bullet bodies. Shared by bench_island.cpp (times) and island_probes.cpp (physics).
#pragma once

#include "plugin/bullet_fixture.hpp"
#include "tearables/bullet_core.hpp"

#include <btBulletDynamicsCommon.h>

#include <cmath>
#include <memory>
#include <vector>

namespace tearables::island {

/// A Bullet world with a tearables world inside it.
struct Rig {
    testing::Physics phys;
    std::unique_ptr<BulletWorld> ropes;
    explicit Rig(double gravity = -9.81, const WorldSettings& settings = {}) : phys(gravity) {
        ropes = std::make_unique<BulletWorld>(*phys.world, settings);
    }
    ~Rig() { ropes.reset(); }
    /// One 1/100 s step, as the scene runner steps.
    void step() { phys.world->stepSimulation(0.01f, 1, 0.01f); }
};

/// A free rope from `from` to `to` (40 segments, radius 5 mm, untearable, no material
/// scatter) of fibre `density`, glued at each end to a free 1 kg box (a 0.1 m cube) just
/// beyond it, as the momentum rigs of issue 30 (item 3) hold their ropes. The boxes are
/// appended to `bodies`.
inline StringId ropeHeldByBoxes(testing::Physics& phys, BulletWorld& ropes, const Vec3& from, const Vec3& to, double density,
                                std::vector<btRigidBody*>& bodies) {
    StringDesc d = StringDesc::straight(from, to, 40);
    d.radius = 0.005;
    d.density = density;
    d.tearable = false;
    d.material.variation = 0.0;
    const StringId id = ropes.addString(d);
    const Vec3 dir = (to - from).normalized();
    for (int end : {0, -1}) {
        const Vec3 out = end == 0 ? Vec3(-dir) : dir;
        btRigidBody& b = phys.box(btVector3(0.05f, 0.05f, 0.05f), 1.0, toBullet((end == 0 ? from : to) + 0.06 * out));
        b.setActivationState(DISABLE_DEACTIVATION);
        ropes.attach(id, end, b, toBullet(-0.06 * out));
        bodies.push_back(&b);
    }
    return id;
}

/// Sum over a string's particles of m v (kg m/s).
inline Vec3 ropeMomentum(const World& w, StringId id) {
    const auto v = w.view(id);
    Vec3 p = Vec3::Zero();
    for (std::size_t i = 0; i < v.particleCount(); ++i) p += (*v.masses)[i] * (*v.velocities)[i];
    return p;
}
inline double ropeKinetic(const World& w, StringId id) {
    const auto v = w.view(id);
    double e = 0.0;
    for (std::size_t i = 0; i < v.particleCount(); ++i) e += 0.5 * (*v.masses)[i] * (*v.velocities)[i].squaredNorm();
    return e;
}
inline double ropeMass(const World& w, StringId id) {
    const auto v = w.view(id);
    double m = 0.0;
    for (double mi : *v.masses) m += mi;
    return m;
}

/// The swing (the built-in `swing` scene without its crate): a 10 kg board, 1 x 0.05 x
/// 0.3 m, hung from two 60-segment ropes of 1.475 m. `pinned`: the same ropes with the
/// lower ends pinned where the board would hold them, and no board. `crate`: a 20 kg
/// crate (0.24 m cube, as the scene drops) set at rest on the board 0.15 m off centre, so
/// that the island holds a body-body contact.
inline std::vector<StringId> buildSwing(Rig& rig, bool pinned, bool crate = false) {
    btRigidBody* board = nullptr;
    if (!pinned) board = &rig.phys.box(btVector3(0.5f, 0.025f, 0.15f), 10.0, btVector3(0, 1.0f, 0));
    if (!pinned && crate) {
        btRigidBody& c = rig.phys.box(btVector3(0.12f, 0.12f, 0.12f), 20.0, btVector3(0.15f, 1.0f + 0.025f + 0.12f + 0.0005f, 0));
        c.setFriction(0.8f);
        board->setFriction(0.8f);
    }
    std::vector<StringId> ids;
    for (double x : {-0.4, 0.4}) {
        StringDesc d = StringDesc::straight({x, 2.5, 0}, {x, 1.025, 0}, 60);
        d.radius = 0.006;
        const StringId id = rig.ropes->addString(d);
        rig.ropes->attach(id, 0, btVector3(static_cast<btScalar>(x), 2.5f, 0));
        if (pinned)
            rig.ropes->attach(id, -1, btVector3(static_cast<btScalar>(x), 1.025f, 0));
        else
            rig.ropes->attach(id, -1, *board, btVector3(static_cast<btScalar>(x), 0.025f, 0));
        ids.push_back(id);
    }
    return ids;
}

/// A hanging bridge as demos/scenes/make_bridge.py writes the `bridge` scene (Strings
/// Fig. 10): `boards` boards of half extents (0.12, half_thickness, 0.35) m in a row at
/// y = 2 m, tied by two rows (z = +-0.3 m) of ropes 0.16 m long (45 segments for the first,
/// 41 for the others), the outer ends pinned. `pinned`: every rope end that a board would
/// hold is pinned at that point instead, and there are no boards.
struct BridgeDesc {
    int boards = 8;
    double board_mass = 4.0;        ///< kg
    double half_thickness = 0.04;   ///< m
    double friction = 0.8;
    bool pinned = false;
};
struct Bridge {
    std::vector<btRigidBody*> boards;
    std::vector<StringId> ropes;
    std::vector<std::pair<StringId, int>> anchors;  ///< (rope, particle) pinned at the bridge's two ends
    double board_mass = 0.0;
};
inline Bridge buildBridge(Rig& rig, const BridgeDesc& b) {
    const double bw = 0.12, bd = 0.35, gap = 0.16, y0 = 2.0;
    const double span = b.boards * 2 * bw + (b.boards + 1) * gap;
    const double x0 = -span / 2;
    Bridge out;
    out.board_mass = b.board_mass;
    std::vector<double> xs;
    double x = x0 + gap;
    for (int i = 0; i < b.boards; ++i) {
        xs.push_back(x + bw);
        if (!b.pinned) {
            btRigidBody& board = rig.phys.box(btVector3(static_cast<btScalar>(bw), static_cast<btScalar>(b.half_thickness),
                                                        static_cast<btScalar>(bd)),
                                              b.board_mass, btVector3(static_cast<btScalar>(x + bw), static_cast<btScalar>(y0), 0));
            board.setFriction(static_cast<btScalar>(b.friction));
            out.boards.push_back(&board);
        }
        x += 2 * bw + gap;
    }
    Material mat;
    mat.tensile.young = 1e9;
    mat.tensile.yield = 1.4e7;
    mat.tensile.plastic_modulus = 1e8;
    mat.tensile.rupture = 1.7e7;
    mat.variation = 0.05;
    auto bt = [](double v) { return static_cast<btScalar>(v); };
    for (double z : {-0.3, 0.3})
        for (int g = 0; g <= b.boards; ++g) {
            const double a = g == 0 ? x0 : xs[g - 1] + bw;
            const double e = g == b.boards ? x0 + span : xs[g] - bw;
            StringDesc d = StringDesc::straight({a, y0, z}, {e, y0, z}, g == 0 ? 45 : 41);
            d.radius = 0.004;
            d.density = 1150;
            d.material = mat;
            d.seed = 1 + out.ropes.size();
            const StringId id = rig.ropes->addString(d);
            if (g == 0 || b.pinned)
                rig.ropes->attach(id, 0, btVector3(bt(a), bt(y0), bt(z)));
            else
                rig.ropes->attach(id, 0, *out.boards[g - 1], btVector3(bt(bw), 0, bt(z)));
            if (g == b.boards || b.pinned)
                rig.ropes->attach(id, -1, btVector3(bt(e), bt(y0), bt(z)));
            else
                rig.ropes->attach(id, -1, *out.boards[g], btVector3(bt(-bw), 0, bt(z)));
            if (g == 0) out.anchors.emplace_back(id, 0);
            if (g == b.boards) out.anchors.emplace_back(id, -1);
            out.ropes.push_back(id);
        }
    return out;
}

/// The bridge's pinned ends' upward pull, N, for gravity g (m/s^2, downward): at each the
/// end segment pulls its pinned particle toward the next with T u, u = (x_next - x_pin) /
/// |...|, and the pin holds that and the particle's weight, an upward reaction -T u_y + m g
/// (T the library's momentum-balance tension: the API gives no pin reaction force).
inline double anchorPull(const World& w, const Bridge& bridge, double g) {
    double pull = 0.0;
    for (const auto& [id, particle] : bridge.anchors) {
        const auto v = w.view(id);
        const auto& x = *v.positions;
        const std::size_t n = x.size();
        if (particle == 0)
            pull += -v.tension->front() * (x[1] - x[0]).normalized().y() + (*v.masses)[0] * g;
        else
            pull += -v.tension->back() * (x[n - 2] - x[n - 1]).normalized().y() + (*v.masses)[n - 1] * g;
    }
    return pull;
}

/// A 64-segment rope, 1 m long, radius 6 mm (nylon), lying straight along x on a static
/// ground plane y = 0 (its axis at y = radius + 1 mm).
inline StringId buildFloorRope(Rig& rig, int segments = 64) {
    rig.phys.add(std::make_unique<btStaticPlaneShape>(btVector3(0, 1, 0), 0.0f), 0.0, btVector3(0, 0, 0));
    StringDesc d = StringDesc::straight({-0.5, 0.007, 0}, {0.5, 0.007, 0}, segments);
    d.radius = 0.006;
    return rig.ropes->addString(d);
}

/// Two 1 kg, 0.1 m boxes 1.1 m apart along x (centres at -+0.6 m), joined by a slack rope
/// arched over them from top to top (so both are island bodies), thrown at each other at
/// +-v. At up to 20 m/s each they meet after the first step, which Bullet solves (the
/// island takes bodies from the step after a rope holds them).
struct ClosingBoxes {
    btRigidBody* a = nullptr;
    btRigidBody* b = nullptr;
    StringId rope;
};
inline ClosingBoxes buildClosingBoxes(testing::Physics& phys, BulletWorld& ropes, double v) {
    ClosingBoxes out;
    out.a = &phys.box(btVector3(0.05f, 0.05f, 0.05f), 1.0, btVector3(-0.6f, 0, 0));
    out.b = &phys.box(btVector3(0.05f, 0.05f, 0.05f), 1.0, btVector3(0.6f, 0, 0));
    StringDesc d;
    const double pi = 3.14159265358979323846;
    for (int i = 0; i <= 30; ++i) d.points.push_back(Vec3(-0.6 * std::cos(pi * i / 30), 0.05 + 0.6 * std::sin(pi * i / 30), 0));
    d.material.variation = 0.0;
    d.tearable = false;
    out.rope = ropes.addString(d);
    ropes.attach(out.rope, 0, *out.a, btVector3(0, 0.05f, 0));
    ropes.attach(out.rope, -1, *out.b, btVector3(0, 0.05f, 0));
    out.a->setLinearVelocity(btVector3(static_cast<btScalar>(v), 0, 0));
    out.b->setLinearVelocity(btVector3(static_cast<btScalar>(-v), 0, 0));
    for (btRigidBody* body : {out.a, out.b}) body->setActivationState(DISABLE_DEACTIVATION);
    return out;
}

}  // namespace tearables::island
