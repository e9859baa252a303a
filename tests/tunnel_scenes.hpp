// Shots at ropes, sheets and cloths held at their ends or edges: a body
// fired straight down at the middle of the target, without gravity, at a fixed step. Shared
// by the probe that prints the table (tests/benchmarks/tunnel_probe.cpp) and the tests that
// hold its cases (tests/plugin/test_tunnelling.cpp).
#pragma once

#include "plugin/bullet_fixture.hpp"
#include "tearables/bullet_core.hpp"

#include <btBulletDynamicsCommon.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

namespace tearables::tunnel {

enum class Target { Rope, TearableRope, Paper, Cloth };
enum class Shape { Sphere, Box };

inline const char* name(Target t) {
    switch (t) {
        case Target::Rope: return "rope";
        case Target::TearableRope: return "tearable rope";
        case Target::Paper: return "paper";
        case Target::Cloth: return "cloth";
    }
    return "?";
}

/// One shot: `shape` (a sphere of 1 cm radius, 2 cm across, or a box of 5 cm half
/// extents, 10 cm across) of `mass` at `speed` straight down (-y) at the middle of the
/// target, which lies in the plane y = 0 held at its ends (a rope, 1 m, pinned at both
/// ends) or all its edges (a 0.4 m sheet or cloth). The body starts with its near face
/// 0.25 m above the target, so the first contact falls inside a step at any speed.
struct Shot {
    Target target = Target::Rope;
    Shape shape = Shape::Sphere;
    double mass = 1.0;    ///< kg
    double speed = 100.0; ///< m/s
    double dt = 0.01;     ///< s, one internal Bullet step a frame
    int steps = 40;       ///< steps simulated (0.4 s: a body that passed is 20 m away at 50 m/s)
    double spin = 0.0;    ///< rad/s about z (across the rope), a pitched ball's
};

struct Outcome {
    bool through = false;      ///< at some step the body was wholly past the intact target's surface, within its outline
    bool tore = false;         ///< a segment or yarn tore (or a sheet spring), at any step
    double peak_tension = 0;   ///< N, the largest segment tension of a rope (0 for sheets)
    double rupture_load = 0;   ///< N, rupture stress times the section, a rope's
    double end_speed = 0;      ///< m/s, the body's at the end (signed along -y: > 0 still going down)
    double end_y = 0;          ///< m, the body's centre at the end
    double half = 0;           ///< m, the body's half size along y
    bool end_inside = false;   ///< at the end the body's centre is within the target's outline
    double end_gap = 0;        ///< m, at the end: the body's centre minus the target's height under it (> 0: near side)
    double start_energy = 0;   ///< J, the body's kinetic energy (translation and rotation) at the start
    double peak_energy = 0;    ///< J, its largest at any step end (no gravity: the target can only take energy)
    std::string error;         ///< BulletWorld::lastError() at the end
};

inline double halfSize(Shape s) { return s == Shape::Sphere ? 0.01 : 0.05; }

/// Runs `shot` and classifies where the body ended. With `trace`, one line a step: the
/// body's centre height and speed along -y, the target's height under it, the lowest
/// point of the target and its fastest point's speed.
inline Outcome fire(const Shot& shot, std::FILE* trace = nullptr) {
    testing::Physics phys(0.0);
    const double half = halfSize(shot.shape);
    const btVector3 start(0, static_cast<btScalar>(0.25 + half), 0);
    btRigidBody& body = shot.shape == Shape::Sphere ? phys.sphere(half, shot.mass, start)
                                                    : phys.box(btVector3(0.05f, 0.05f, 0.05f), shot.mass, start);
    body.setLinearVelocity(btVector3(0, static_cast<btScalar>(-shot.speed), 0));
    body.setAngularVelocity(btVector3(0, 0, static_cast<btScalar>(shot.spin)));
    body.setActivationState(DISABLE_DEACTIVATION);
    BulletWorld world(*phys.world);
    Outcome out;
    out.half = half;
    out.start_energy = out.peak_energy = testing::kineticEnergy(body);
    StringId rope;
    PaperId paper;
    ClothId cloth;
    const bool is_rope = shot.target == Target::Rope || shot.target == Target::TearableRope;
    if (is_rope) {
        StringDesc d = StringDesc::straight(Vec3(-0.5, 0, 0), Vec3(0.5, 0, 0), 50);
        d.material.variation = 0.0;
        d.radius = 0.003;
        d.tearable = shot.target == Target::TearableRope;
        rope = world.addString(d);
        world.attach(rope, 0, btVector3(-0.5f, 0, 0));
        world.attach(rope, -1, btVector3(0.5f, 0, 0));
        out.rupture_load = d.material.tensile.rupture * 3.14159265358979 * d.radius * d.radius;
    } else if (shot.target == Target::Paper) {
        PaperDesc d;
        d.center = Vec3(0, 0, 0);
        d.size[0] = d.size[1] = 0.4;
        d.resolution[0] = d.resolution[1] = 21;
        d.breakable = false;
        d.tearable = false;
        for (int k = 0; k < d.resolution[1]; ++k)
            for (int i = 0; i < d.resolution[0]; ++i)
                if (i == 0 || k == 0 || i == d.resolution[0] - 1 || k == d.resolution[1] - 1)
                    d.attachments.push_back(PaperAttachment{static_cast<int>(d.gridVertex(i, k)), {}, Vec3::Zero(), {}});
        paper = world.addPaper(d);
    } else {
        ClothDesc d;
        d.corner = Vec3(-0.2, 0, -0.2);
        d.size = {0.4, 0.4};
        d.resolution = {21, 21};
        d.material.variation = 0.0;
        d.tearable = false;
        for (int j = 0; j < 21; ++j)
            for (int i = 0; i < 21; ++i)
                if (i == 0 || j == 0 || i == 20 || j == 20) {
                    SheetAttachment pin;
                    pin.vertex = d.vertex(i, j);
                    d.attachments.push_back(pin);
                }
        cloth = world.addCloth(d);
    }
    // The target's surface under the body's centre: a rope's axis at the body's x
    // (interpolated between particles), a sheet's or cloth's lowest layer there.
    struct Under {
        bool inside = false;  ///< the body's centre is within the target's outline
        double y = 0.0;       ///< the target's height there, m
    };
    const double rope_radius = 0.003;
    std::vector<std::array<std::uint32_t, 3>> triangles;  // a cloth's: two a cell of its 21 x 21 grid
    auto under = [&](const btVector3& c) {
        Under u;
        const std::vector<Vec3>* x = nullptr;
        if (is_rope) {
            x = world.core().view(rope).positions;
            for (std::size_t j = 0; j + 1 < x->size(); ++j) {
                const Vec3 &a = (*x)[j], &b = (*x)[j + 1];
                if (c.x() < std::min(a.x(), b.x()) || c.x() > std::max(a.x(), b.x()) || a.x() == b.x()) continue;
                const double f = (c.x() - a.x()) / (b.x() - a.x());
                const Vec3 p = a + f * (b - a);
                u.inside = std::abs(c.z() - p.z()) < half + rope_radius;
                u.y = p.y();
                return u;
            }
            return u;
        }
        // A sheet or cloth: its lowest layer at the body's x-z, over the triangles whose
        // projection on the x-z plane holds the body's centre (a sheet drawn into a cone
        // or wrapped round the body has several layers there; the body is past the sheet
        // only when it is past all of them). Outside every triangle the body is outside
        // the outline.
        x = shot.target == Target::Paper ? world.core().viewPaper(paper).positions : world.core().viewCloth(cloth).positions;
        if (shot.target == Target::Cloth) {
            triangles.clear();
            for (int j = 0; j + 1 < 21; ++j)
                for (int i = 0; i + 1 < 21; ++i) {
                    const std::uint32_t a = static_cast<std::uint32_t>(j * 21 + i);
                    triangles.push_back({a, a + 1, a + 22});
                    triangles.push_back({a, a + 22, a + 21});
                }
        }
        const auto& tris = shot.target == Target::Paper ? *world.core().viewPaper(paper).triangles : triangles;
        u.y = 1e300;
        for (const auto& t : tris) {
            const Vec3 &p0 = (*x)[t[0]], &p1 = (*x)[t[1]], &p2 = (*x)[t[2]];
            // Barycentric coordinates of (c.x, c.z) in the triangle's x-z projection.
            const double d = (p1.x() - p0.x()) * (p2.z() - p0.z()) - (p2.x() - p0.x()) * (p1.z() - p0.z());
            if (std::abs(d) < 1e-18) continue;
            const double b1 = ((c.x() - p0.x()) * (p2.z() - p0.z()) - (p2.x() - p0.x()) * (c.z() - p0.z())) / d;
            const double b2 = ((p1.x() - p0.x()) * (c.z() - p0.z()) - (c.x() - p0.x()) * (p1.z() - p0.z())) / d;
            if (b1 < 0.0 || b2 < 0.0 || b1 + b2 > 1.0) continue;
            u.inside = true;
            u.y = std::min(u.y, p0.y() + b1 * (p1.y() - p0.y()) + b2 * (p2.y() - p0.y()));
        }
        if (!u.inside) u.y = 0.0;
        return u;
    };
    for (int i = 0; i < shot.steps; ++i) {
        phys.step(1, shot.dt);
        if (is_rope && world.core().contains(rope))
            for (double t : world.peakTension(rope)) out.peak_tension = std::max(out.peak_tension, t);
        bool torn = false;
        for (const Event& e : world.events()) torn = torn || e.type == EventType::Tear;
        const btVector3 c = body.getCenterOfMassPosition();
        const Under u = under(c);
        // Through: wholly past the intact target's surface, within its outline.
        if (!torn && u.inside && c.y() + half < u.y) out.through = true;
        out.peak_energy = std::max(out.peak_energy, testing::kineticEnergy(body));
        if (trace) {
            const std::vector<Vec3>* x = is_rope ? world.core().view(rope).positions
                                         : shot.target == Target::Paper ? world.core().viewPaper(paper).positions
                                                                        : world.core().viewCloth(cloth).positions;
            const std::vector<Vec3>* v = is_rope ? world.core().view(rope).velocities
                                         : shot.target == Target::Paper ? world.core().viewPaper(paper).velocities
                                                                        : world.core().viewCloth(cloth).velocities;
            double lowest = 1e300, fastest = 0.0;
            for (const Vec3& p : *x) lowest = std::min(lowest, p.y());
            for (const Vec3& w : *v) fastest = std::max(fastest, w.norm());
            std::fprintf(trace, "step %2d  body y %9.4f  v %9.3f  spin %8.1f  under %9.4f%s  lowest %9.4f  fastest %8.3f%s\n",
                         i + 1, c.y(), -body.getLinearVelocity().y(), body.getAngularVelocity().z(), u.y,
                         u.inside ? "" : " (outside)", lowest, fastest, torn ? "  tore" : "");
        }
    }
    for (const Event& e : world.events())
        if (e.type == EventType::Tear) out.tore = true;
    out.error = world.lastError();
    const btVector3 c = body.getCenterOfMassPosition();
    out.end_y = c.y();
    out.end_speed = -body.getLinearVelocity().y();
    const Under end = under(c);
    out.end_inside = end.inside;
    out.end_gap = c.y() - end.y;
    return out;
}

/// A rope particle at `speed`: a 0.2 m rope of 10 segments (radius 2 mm, untearable), lying
/// along x (`vertical` false) or along y, given `speed` straight down in its first step by a
/// force of m v / dt on every particle (no gravity), above a static slab 1 m wide and
/// 2 `half_thickness` thick whose top face is at y = half_thickness. Returns the lowest
/// any particle's axis went (m) over `steps` steps, and where the lowest particle ends.
struct ParticleShot {
    double lowest = 1e300;  ///< m, lowest particle y at any step end
    double end_lowest = 0;  ///< m, lowest particle y at the end
    std::string error;
};
inline ParticleShot fireRope(double speed, bool vertical, double half_thickness = 0.01, double dt = 0.01, int steps = 20) {
    testing::Physics phys(0.0);
    phys.box(btVector3(0.5f, static_cast<btScalar>(half_thickness), 0.5f), 0.0, btVector3(0, 0, 0));
    BulletWorld world(*phys.world);
    // Its first step brings it from rest to `speed` and moves it speed dt down: it starts
    // that far plus 0.2 m above the slab, so it meets the slab in its second step.
    const double y0 = half_thickness + speed * dt + 0.2;
    StringDesc d = vertical ? StringDesc::straight(Vec3(0, y0, 0), Vec3(0, y0 + 0.2, 0), 10)
                            : StringDesc::straight(Vec3(-0.1, y0, 0), Vec3(0.1, y0, 0), 10);
    d.material.variation = 0.0;
    d.tearable = false;
    const StringId id = world.addString(d);
    const std::vector<double> masses = *world.core().view(id).masses;
    for (std::size_t p = 0; p < masses.size(); ++p)
        world.applyForce(id, static_cast<int>(p), btVector3(0, static_cast<btScalar>(-masses[p] * speed / dt), 0));
    ParticleShot out;
    for (int i = 0; i < steps; ++i) {
        phys.step(1, dt);
        double lowest = 1e300;
        for (const Vec3& x : *world.core().view(id).positions) lowest = std::min(lowest, x.y());
        out.lowest = std::min(out.lowest, lowest);
        out.end_lowest = lowest;
    }
    out.error = world.lastError();
    return out;
}

}  // namespace tearables::tunnel
