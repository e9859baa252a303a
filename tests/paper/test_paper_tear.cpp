// Tearing (beyond Paper): a sheet pulled at two corners tears between them, where the
// edges are stretched past rupture_stretch, never where they are not; the mesh stays
// valid and its mass is conserved.
#include "world/world_access.hpp"
#include "paper/sheet.hpp"
#include "paper_helpers.hpp"
#include "tearables/world.hpp"

#include <gtest/gtest.h>

#include <cstdio>
#include <map>
#include <numeric>

namespace tearables {
namespace {

/// Connected pieces of the mesh (triangles sharing a vertex).
int pieces(const PaperView& v) {
    std::vector<std::uint32_t> parent(v.vertexCount());
    std::iota(parent.begin(), parent.end(), 0u);
    auto find = [&](std::uint32_t a) {
        while (parent[a] != a) a = parent[a] = parent[parent[a]];
        return a;
    };
    for (const auto& t : *v.triangles) {
        parent[find(t[1])] = find(t[0]);
        parent[find(t[2])] = find(t[0]);
    }
    int count = 0;
    for (std::uint32_t i = 0; i < parent.size(); ++i) count += find(i) == i;
    return count;
}

void pulledAtTwoCorners(PaperTension tension) {
    PaperDesc d;
    d.tension = tension;
    d.size[0] = 0.2;
    d.size[1] = 0.1;
    d.resolution[0] = 21;
    d.resolution[1] = 11;
    d.tearable = true;
    d.breakable = false;
    d.rupture_stretch = 0.02;
    const auto left = static_cast<std::uint32_t>(d.gridVertex(0, 0));
    const auto right = static_cast<std::uint32_t>(d.gridVertex(d.resolution[0] - 1, 0));
    d.attachments.push_back(PaperAttachment{static_cast<int>(left), {}, Vec3::Zero(), {}});
    d.attachments.push_back(PaperAttachment{static_cast<int>(right), {}, Vec3::Zero(), {}});
    World world{WorldSettings{Vec3::Zero()}};
    const PaperId id = world.addPaper(d);
    const std::vector<Vec3> rest = *world.viewPaper(id).positions;
    const double mass = testing::totalMass(world.viewPaper(id));
    const Vec3 l0 = rest[left], r0 = rest[right];
    const double h = 1.0 / 60.0;
    int tears = 0, direct_steps = 0;
    bool first_checked = false;
    for (int step = 1; step <= 240; ++step) {
        // The corners move apart along the edge between them at 2 cm/s each.
        const double pull = 0.02 * step * h;
        world.movePaperPin(id, left, l0 - Vec3(pull, 0, 0));
        world.movePaperPin(id, right, r0 + Vec3(pull, 0, 0));
        world.step(h);
        for (const Event& e : world.events()) {
            if (e.type != EventType::Tear) continue;
            ++tears;
            // Only where the edge was stretched past rupture.
            EXPECT_GE(e.stress, d.rupture_stretch);
            ASSERT_GE(e.particle, 0);
            if (!first_checked && static_cast<std::size_t>(e.particle) < rest.size()) {
                // The first crack starts on the pulled edge, between the corners.
                const Vec3& p = rest[static_cast<std::size_t>(e.particle)];
                EXPECT_NEAR(p.z(), l0.z(), 1e-9);
                EXPECT_GT(p.x(), l0.x());
                EXPECT_LT(p.x(), r0.x());
                first_checked = true;
            }
        }
        const PaperView v = world.viewPaper(id);
        ASSERT_EQ(detail::checkMesh(v, mass), "") << "step " << step;
        ASSERT_TRUE(testing::allFinite(v));
        if (tension == PaperTension::Momentum) {
            // The normal equations are solved exactly, before and after each tear (whose
            // new springs and ends the solve's pattern is rebuilt for, once they stay the
            // same for a step; in the steps that tear, the conjugate gradients answer): the
            // residual, by the matrix-free product, is at round-off.
            const detail::PaperSheet& sheet = (*detail::WorldAccess::parts(world).papers)[id.index];
            if (sheet.tension_scratch.iterations == 0) {
                ++direct_steps;
                EXPECT_LT(sheet.tension_scratch.residual_norm, 1e-9) << "step " << step;
            }
        }
    }
    if (tension == PaperTension::Momentum) {
        std::printf("momentum tension: %d of 240 steps solved directly\n", direct_steps);
        EXPECT_GE(direct_steps, 240 - tears - 1);  // the first step and each that tore: not
    }
    const PaperView v = world.viewPaper(id);
    std::printf("tears: %d, pieces: %d, vertices %zu -> %zu\n", tears, pieces(v), rest.size(), v.vertexCount());
    EXPECT_GT(tears, 0);
    EXPECT_TRUE(first_checked);
    EXPECT_EQ(v.counters.tears, static_cast<std::uint64_t>(tears));
    EXPECT_NEAR(testing::totalMass(v), mass, 1e-12 * mass);
    // The same pull on an untearable sheet: no tear, and the stretch it reaches is past
    // rupture (so the tears above were where the stress was high).
    PaperDesc whole = d;
    whole.tearable = false;
    World control{WorldSettings{Vec3::Zero()}};
    const PaperId cid = control.addPaper(whole);
    for (int step = 1; step <= 60; ++step) {
        const double pull = 0.02 * step * h;
        control.movePaperPin(cid, left, l0 - Vec3(pull, 0, 0));
        control.movePaperPin(cid, right, r0 + Vec3(pull, 0, 0));
        control.step(h);
        for (const Event& e : control.events()) EXPECT_NE(e.type, EventType::Tear);
    }
    EXPECT_GT(testing::maxEdgeStrain(control.viewPaper(cid)), d.rupture_stretch);
}

TEST(PaperTear, PulledAtTwoCornersTearsBetweenThemWhereStretched) { pulledAtTwoCorners(PaperTension::Stretch); }
TEST(PaperTear, PulledAtTwoCornersTearsWithMomentumBalanceTension) { pulledAtTwoCorners(PaperTension::Momentum); }

/// Below the rupture stretch nothing tears: a sheet hanging from its two top corners
/// under its weight (strain far below 2%).
TEST(PaperTear, NoTearBelowRupture) {
    PaperDesc d;
    d.orientation = Quat(Eigen::AngleAxisd(0.5 * M_PI, Vec3::UnitX()));  // local z points down: row 0 on top
    d.size[0] = 0.2;
    d.size[1] = 0.1;
    d.resolution[0] = 11;
    d.resolution[1] = 6;
    d.tearable = true;
    d.breakable = false;
    d.attachments.push_back(PaperAttachment{0, {}, Vec3::Zero(), {}});
    d.attachments.push_back(PaperAttachment{static_cast<int>(d.resolution[0] - 1), {}, Vec3::Zero(), {}});
    World world;
    const PaperId id = world.addPaper(d);
    double peak = 0.0;
    for (int step = 0; step < 300; ++step) {
        world.step(1.0 / 60.0);
        for (const Event& e : world.events()) EXPECT_NE(e.type, EventType::Tear);
        peak = std::max(peak, testing::maxEdgeStrain(world.viewPaper(id)));
    }
    EXPECT_EQ(world.viewPaper(id).counters.tears, 0u);
    EXPECT_LT(peak, d.rupture_stretch);
    std::printf("hanging from two corners: peak strain %.3g\n", peak);
}

/// Edges used by one triangle only (the sheet's boundary, cuts included).
int boundaryEdges(const PaperView& v) {
    std::map<std::pair<std::uint32_t, std::uint32_t>, int> uses;
    for (const auto& t : *v.triangles)
        for (int c = 0; c < 3; ++c) ++uses[{std::min(t[c], t[(c + 1) % 3]), std::max(t[c], t[(c + 1) % 3])}];
    int count = 0;
    for (const auto& [edge, n] : uses) count += n == 1;
    return count;
}

/// A crack starts where an edge is overstretched, also inside the sheet: two inner
/// vertices of a free sheet (no gravity) pulled apart (10 N each, on a 20 cm sheet of 5 kN/m
/// springs, whose edge tears at 2.5 N) stretch the edge between them past
/// rupture first, and the sheet opens a slit there, across that edge. The first tear is
/// exactly one split of an inner vertex along two of its fan edges: one vertex more, the
/// same triangles, four boundary edges more (each cut edge now borders one triangle on
/// each side of the slit), still one piece; and the split vertex is one of the two pulled.
TEST(PaperTear, AnOverstretchedInnerEdgeStartsASlitThere) {
    PaperDesc d;
    d.size[0] = 0.2;
    d.size[1] = 0.2;
    d.resolution[0] = 9;
    d.resolution[1] = 9;
    d.tearable = true;
    d.breakable = false;
    WorldSettings settings;
    settings.gravity = Vec3::Zero();
    World world(settings);
    const PaperId id = world.addPaper(d);
    const auto left = static_cast<std::uint32_t>(d.gridVertex(4, 4)), right = static_cast<std::uint32_t>(d.gridVertex(5, 4));
    const PaperView before = world.viewPaper(id);
    const std::size_t vertices = before.vertexCount(), triangles = before.triangles->size();
    const int boundary = boundaryEdges(before);
    ASSERT_EQ(boundary, 4 * 8);
    int step = 0;
    for (; step < 120 && world.viewPaper(id).counters.tears == 0; ++step) {
        world.applyPaperForce(id, left, Vec3(-10.0, 0, 0));
        world.applyPaperForce(id, right, Vec3(10.0, 0, 0));
        world.step(1.0 / 240.0);
    }
    const PaperView after = world.viewPaper(id);
    ASSERT_EQ(after.counters.tears, 1u) << "no tear in " << step << " steps";
    int split = -1;
    for (const Event& e : world.events())
        if (e.type == EventType::Tear) split = e.particle;
    EXPECT_TRUE(split == static_cast<int>(left) || split == static_cast<int>(right)) << split;
    EXPECT_EQ(after.vertexCount(), vertices + 1);
    EXPECT_EQ(after.triangles->size(), triangles);
    EXPECT_EQ(boundaryEdges(after), boundary + 4);
    EXPECT_EQ(pieces(after), 1);
    EXPECT_EQ(detail::checkMesh(after, d.areal_density * 0.2 * 0.2), "");
    std::printf("inner slit after %d steps at vertex %d\n", step, split);
}

}  // namespace
}  // namespace tearables

namespace tearables {
namespace {

/// Yarn's momentum-balance tensions on a sheet hanging at rest from its top edge: the
/// springs crossing any horizontal cut carry the weight of the sheet below it (the balance
/// of the part below the cut, an invariant of any exact solution: the edges' solved
/// tensions plus the bending springs' known forces), and the load decreases downward.
TEST(PaperTension, MomentumBalanceCarriesTheWeightBelowEachCut) {
    PaperDesc d;
    d.size[0] = 0.1;
    d.size[1] = 0.1;
    d.resolution[0] = 8;
    d.resolution[1] = 8;
    d.orientation = Quat(Eigen::AngleAxisd(0.5 * M_PI, Vec3::UnitX()));  // local z points down: row 0 on top
    d.breakable = false;
    d.tension = PaperTension::Momentum;
    d.jacobi_iterations = 16;
    for (int i = 0; i < d.resolution[0]; ++i) d.attachments.push_back(PaperAttachment{static_cast<int>(i), {}, Vec3::Zero(), {}});
    World world;
    const PaperId id = world.addPaper(d);
    for (int step = 0; step < 600; ++step) world.step(1.0 / 60.0);
    const PaperView v = world.viewPaper(id);
    ASSERT_LT(testing::maxSpeed(v), 1e-3);  // at rest
    const double g = 9.81;
    double previous = 1e300;
    for (int cut = 1; cut + 1 < d.resolution[1]; ++cut) {
        // Edges between row `cut` and row `cut + 1`, and the mass below.
        double carried = 0.0, below = 0.0;
        for (std::size_t k = 0; k < v.springs->size(); ++k) {
            const PaperSpring& sp = (*v.springs)[k];
            if (sp.broken) continue;
            const int ra = static_cast<int>(sp.a) / d.resolution[0], rb = static_cast<int>(sp.b) / d.resolution[0];
            if (std::min(ra, rb) > cut || std::max(ra, rb) <= cut) continue;  // does not cross the cut
            const std::uint32_t upper = ra <= cut ? sp.a : sp.b, lower = ra <= cut ? sp.b : sp.a;
            const Vec3 e = (*v.positions)[upper] - (*v.positions)[lower];
            // Structural edges: the balance's tensions; the bending springs across the cut
            // carry their share too (their spring force, known to the balance).
            const double t = sp.kind == PaperSpringKind::Structural ? (*v.tension)[k] : sp.stiffness * (e.norm() - sp.rest);
            carried += t * e.normalized().y();
        }
        for (std::size_t i = 0; i < v.vertexCount(); ++i)
            if (static_cast<int>(i) / d.resolution[0] > cut) below += (*v.masses)[i] * g;
        std::printf("cut %d: tension carries %.6f N, weight below %.6f N\n", cut, carried, below);
        EXPECT_NEAR(carried, below, 0.005 * below + 1e-9) << "cut " << cut;
        EXPECT_LT(carried, previous);
        previous = carried;
    }
}

}  // namespace
}  // namespace tearables
