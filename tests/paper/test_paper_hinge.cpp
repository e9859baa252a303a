// Paper Sec. III.B-C: breakable hinge springs. Breaking follows Eq. 7's distribution,
// the inserted vertex is lifted by Eq. 8, phi and psi do what Fig. 8-9 show, and the mesh
// stays valid through any sequence of breaks, inserts and tears.
#include "world/world_access.hpp"
#include "paper/sheet.hpp"
#include "paper_helpers.hpp"
#include "tearables/world.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

namespace tearables {
namespace {

PaperDesc quad(std::uint64_t seed, double phi) {
    PaperDesc d;
    d.size[0] = 0.01;
    d.size[1] = 0.01;
    d.resolution[0] = 2;
    d.resolution[1] = 2;
    d.phi = phi;
    d.seed = seed;
    d.hinge_threshold = 0.0;
    return d;
}

/// Over many seeded trials, the fraction of springs broken by the time they are
/// compressed to l/l0 = ratio matches Eq. 7, (1 - ratio)^phi, within three standard
/// errors, also when the compression comes in several steps (each step draws only
/// against the increase).
TEST(PaperHinge, BreakingFractionMatchesEquation7) {
    struct Case {
        double ratio, phi;
        int increments;
    };
    for (const Case c : {Case{0.9, 1.0, 1}, Case{0.9, 1.0, 6}, Case{0.7, 2.0, 4}, Case{0.5, 0.5, 3}, Case{0.8, 5.0, 2}}) {
        const int trials = 3000;
        int broken = 0, samples = 0;
        for (int trial = 0; trial < trials; ++trial) {
            detail::PaperSheet s = detail::buildSheet(quad(1000 + trial, c.phi));
            const std::vector<Vec3> rest = s.x;
            const double x0 = rest[0].x();
            detail::PaperStep ctx;
            ctx.h = 0.01;
            std::vector<Event> events;
            for (int inc = 1; inc <= c.increments; ++inc) {
                // Squeeze along x: the x-edges {0,1} and {2,3} go to ratio (partially).
                const double r = 1.0 - (1.0 - c.ratio) * inc / c.increments;
                for (std::uint32_t v = 0; v < 4; ++v) s.x[v].x() = x0 + (rest[v].x() - x0) * r;
                detail::creaseAndFold(s, PaperId{0}, ctx, events);
            }
            for (std::size_t k = 0; k < s.springs.size(); ++k) {
                const PaperSpring& sp = s.springs[k];
                if (sp.kind != PaperSpringKind::Structural || k >= 5) continue;  // the original edges
                const bool x_edge = (sp.a == 0 && sp.b == 1) || (sp.a == 2 && sp.b == 3);
                if (!x_edge) continue;
                ++samples;
                broken += sp.broken ? 1 : 0;
            }
            ASSERT_EQ(detail::checkMesh(s), "") << "trial " << trial;
        }
        const double p = std::pow(1.0 - c.ratio, c.phi);
        const double fraction = static_cast<double>(broken) / samples;
        const double se = std::sqrt(p * (1.0 - p) / samples);
        std::printf("ratio %.2f phi %.1f in %d steps: broken %.4f, Eq. 7 %.4f, %.2f standard errors\n", c.ratio, c.phi,
                    c.increments, fraction, p, std::abs(fraction - p) / se);
        EXPECT_LT(std::abs(fraction - p), 3.0 * se) << "ratio " << c.ratio << " phi " << c.phi;
    }
}

/// Eq. 8: the inserted vertex sits psi/2 sqrt(l0^2 - l^2) off the spring's middle, along
/// the normal; with psi = 1 the two new halves are exactly at rest (l0 / 2 each).
TEST(PaperHinge, InsertedVertexLiftedByEquation8) {
    for (const double psi : {0.0, 0.5, 1.0, 2.0}) {
        PaperDesc d = quad(3, 1.0);
        d.psi = psi;
        detail::PaperSheet s = detail::buildSheet(d);
        const double ratio = 0.6;
        for (std::uint32_t v : {1u, 3u}) s.x[v].x() = s.x[0].x() + ratio * (s.x[v].x() - s.x[0].x());
        std::size_t edge = 0;
        for (std::size_t k = 0; k < s.springs.size(); ++k)
            if (s.springs[k].a == 0 && s.springs[k].b == 1) edge = k;
        const double l0 = s.springs[edge].rest, l = (s.x[1] - s.x[0]).norm();
        const std::uint32_t m = detail::breakSpring(s, static_cast<std::uint32_t>(edge));
        ASSERT_NE(m, UINT32_MAX);
        const Vec3 mid = 0.5 * (s.x[0] + s.x[1]);
        const double expected = 0.5 * psi * std::sqrt(l0 * l0 - l * l);
        EXPECT_NEAR((s.x[m] - mid).norm(), expected, 1e-12 * l0);
        EXPECT_NEAR(std::abs((s.x[m] - mid).y()), expected, 1e-12 * l0);  // along the normal (the sheet is in x-z)
        if (psi == 1.0) {
            EXPECT_NEAR((s.x[m] - s.x[0]).norm(), 0.5 * l0, 1e-12);
            EXPECT_NEAR((s.x[m] - s.x[1]).norm(), 0.5 * l0, 1e-12);
        }
        // The damage is remembered: an unbreakable auxiliary spring at the compressed length.
        bool auxiliary = false;
        for (const PaperSpring& sp : s.springs)
            auxiliary = auxiliary || (sp.kind == PaperSpringKind::Auxiliary && sp.a == 0 && sp.b == 1 && std::abs(sp.rest - l) < 1e-12);
        EXPECT_TRUE(auxiliary);
        EXPECT_EQ(detail::checkMesh(s), "");
    }
}

/// Any sequence of breaks, vertex splits (tears) and jitter keeps the mesh valid: no
/// degenerate triangle, consistent orientation, manifold edges, no dangling spring, the
/// mass conserved.
TEST(PaperHinge, MeshStaysValidThroughRandomBreaksInsertsAndTears) {
    for (std::uint64_t seed = 1; seed <= 20; ++seed) {
        PaperDesc d;
        d.size[0] = 0.06;
        d.size[1] = 0.05;
        d.resolution[0] = 7;
        d.resolution[1] = 6;
        d.seed = seed;
        detail::PaperSheet s = detail::buildSheet(d);
        std::mt19937_64 rng(seed);
        int breaks = 0, splits = 0;
        for (int op = 0; op < 80; ++op) {
            std::uniform_int_distribution<int> pick(0, 2);
            const int kind = pick(rng);
            if (kind == 0) {
                std::uniform_int_distribution<std::size_t> sp(0, s.springs.size() - 1);
                const std::size_t k = sp(rng);
                if (s.springs[k].kind == PaperSpringKind::Structural && !s.springs[k].broken) {
                    // Compress it a little first, as a load would.
                    const PaperSpring spring = s.springs[k];
                    const Vec3 mid = 0.5 * (s.x[spring.a] + s.x[spring.b]);
                    s.x[spring.b] = mid + 0.45 * (s.x[spring.b] - s.x[spring.a]);
                    s.x[spring.a] = mid - (s.x[spring.b] - mid);
                    breaks += detail::breakSpring(s, static_cast<std::uint32_t>(k)) != UINT32_MAX;
                }
            } else if (kind == 1) {
                std::uniform_int_distribution<std::uint32_t> vx(0, static_cast<std::uint32_t>(s.vertices() - 1));
                const std::uint32_t v = vx(rng);
                std::vector<std::uint32_t> fan;
                detail::trianglesOf(s, v, fan);
                std::uniform_int_distribution<std::size_t> f(0, fan.size() - 1);
                const auto& t = s.triangles[fan[f(rng)]];
                const std::uint32_t w = t[0] == v ? t[1] : t[0];
                splits += detail::splitVertex(s, v, w) != UINT32_MAX;
            } else {
                std::normal_distribution<double> jitter(0.0, 5e-4);
                for (Vec3& x : s.x) x += Vec3(jitter(rng), jitter(rng), jitter(rng));
            }
            const std::string problem = detail::checkMesh(s, 1e-16);
            ASSERT_EQ(problem, "") << "seed " << seed << " op " << op << " kind " << kind;
            for (const PaperSpring& sp : s.springs)
                if (!sp.broken && sp.kind != PaperSpringKind::Structural) ASSERT_TRUE(detail::springHolds(s, sp)) << "seed " << seed;
        }
        EXPECT_GT(breaks, 0);
        EXPECT_GT(splits, 0);
    }
}

/// A sheet whose two opposite edges are pushed together, without gravity.
struct Squeeze {
    World world{WorldSettings{Vec3::Zero()}};
    PaperId id;
    Squeeze(double phi, double psi, bool breakable, std::uint64_t seed) {
        PaperDesc d;
        d.size[0] = 0.2;
        d.size[1] = 0.1;
        d.resolution[0] = 21;
        d.resolution[1] = 11;
        d.phi = phi;
        d.psi = psi;
        d.breakable = breakable;
        d.seed = seed;
        for (int k = 0; k < d.resolution[1]; ++k)
            for (int i : {0, d.resolution[0] - 1}) {
                PaperAttachment a;
                a.vertex = d.gridVertex(i, k);
                d.attachments.push_back(a);
            }
        id = world.addPaper(d);
        const PaperDesc& desc = world.paperDesc(id);
        // Push the two held edges 30% closer over 1 s, then hold.
        const double h = 1.0 / 60.0;
        for (int step = 1; step <= 90; ++step) {
            const double squeeze = 0.3 * 0.5 * desc.size[0] * std::min(1.0, step / 60.0);
            for (int k = 0; k < desc.resolution[1]; ++k) {
                const auto left = static_cast<std::uint32_t>(desc.gridVertex(0, k));
                const auto right = static_cast<std::uint32_t>(desc.gridVertex(desc.resolution[0] - 1, k));
                const double z = -0.5 * desc.size[1] + desc.size[1] * k / (desc.resolution[1] - 1);
                world.movePaperPin(id, left, Vec3(-0.5 * desc.size[0] + squeeze, 1.0, z));
                world.movePaperPin(id, right, Vec3(0.5 * desc.size[0] - squeeze, 1.0, z));
            }
            world.step(h);
        }
    }
};

/// Fig. 9: small phi is fragile (many creases), large phi rubbery (few).
TEST(PaperHinge, PhiControlsFragility) {
    int fragile = 0, rubbery = 0;
    for (std::uint64_t seed = 1; seed <= 3; ++seed) {
        Squeeze a(1.0, 0.5, true, seed), b(5.0, 0.5, true, seed);
        fragile += static_cast<int>(a.world.viewPaper(a.id).counters.creases);
        rubbery += static_cast<int>(b.world.viewPaper(b.id).counters.creases);
        for (const Squeeze* q : {&a, &b}) {
            const PaperView v = q->world.viewPaper(q->id);
            EXPECT_EQ(detail::checkMesh(v, 0.08 * 0.2 * 0.1), "");
        }
    }
    std::printf("creases: phi = 1: %d, phi = 5: %d (3 seeds)\n", fragile, rubbery);
    EXPECT_GT(fragile, 2 * rubbery);
    EXPECT_GT(fragile, 0);
}

/// Fig. 8: psi sets how far a crease's new vertex is lifted. Small psi (a bank note)
/// leaves the new halves compressed, so they break again and again into many small
/// creases: the sheet bends smoothly. Large psi (card board) lifts the crease so the halves
/// are at rest: few creases, each a fold that holds (the sharpest local kink is not a
/// measure of it: many small creases make sharper kinks between them).
TEST(PaperHinge, PsiControlsHowCreasesForm) {
    long flexible_creases = 0, stiff_creases = 0;
    for (std::uint64_t seed = 1; seed <= 3; ++seed) {
        Squeeze a(1.0, 1.0, true, seed), b(1.0, 0.1, true, seed);
        stiff_creases += static_cast<long>(a.world.viewPaper(a.id).counters.creases);
        flexible_creases += static_cast<long>(b.world.viewPaper(b.id).counters.creases);
    }
    std::printf("creases: psi = 1: %ld, psi = 0.1: %ld (3 seeds)\n", stiff_creases, flexible_creases);
    EXPECT_GT(flexible_creases, stiff_creases + stiff_creases / 2);
}

/// Same seed, same creases; another seed, others.
TEST(PaperHinge, DeterministicPerSeed) {
    Squeeze a(1.0, 0.5, true, 7), b(1.0, 0.5, true, 7), c(1.0, 0.5, true, 8);
    const PaperView va = a.world.viewPaper(a.id), vb = b.world.viewPaper(b.id), vc = c.world.viewPaper(c.id);
    ASSERT_EQ(va.vertexCount(), vb.vertexCount());
    for (std::size_t i = 0; i < va.vertexCount(); ++i) EXPECT_EQ((*va.positions)[i], (*vb.positions)[i]);
    bool differs = va.vertexCount() != vc.vertexCount();
    for (std::size_t i = 0; i < std::min(va.vertexCount(), vc.vertexCount()) && !differs; ++i)
        differs = (*va.positions)[i] != (*vc.positions)[i];
    EXPECT_TRUE(differs);
}

/// A breakable sheet creasing as it swings (BM_PaperStepBreakable's, 64 x 64) gains
/// vertices and springs at nearly every step, and its Jacobi rows are rebuilt for them.
/// They grow by half again where they must (assignGrowing), so they are made anew in a few
/// steps only: an exact assign made a new 2 MB allocation at every step that grew them,
/// mapped and zeroed afresh by the kernel (twice the step's time).
TEST(PaperHinge, CreasingSheetGrowsItsRowsWithoutANewAllocationEveryStep) {
    const int n = 64;
    World world;
    PaperDesc d;
    d.size[0] = 0.3;
    d.size[1] = 0.3;
    d.resolution[0] = n;
    d.resolution[1] = n;
    d.breakable = true;
    d.attachments.push_back(PaperAttachment{0, {}, Vec3::Zero(), {}});
    d.attachments.push_back(PaperAttachment{static_cast<int>(n - 1), {}, Vec3::Zero(), {}});
    const PaperId id = world.addPaper(d);
    const detail::PaperSheet& sheet = (*detail::WorldAccess::parts(world).papers)[id.index];
    int grew = 0, allocated = 0;
    for (int i = 0; i < 100; ++i) {
        const std::size_t size = sheet.row_quads.size();
        const detail::JacobiQuad* data = sheet.row_quads.data();
        world.step(1.0 / 60.0);
        grew += sheet.row_quads.size() > size;
        allocated += sheet.row_quads.data() != data;
    }
    EXPECT_GE(grew, 50);  // the sheet creases, and its rows grow, at most steps
    EXPECT_LE(allocated, 5);
    EXPECT_GT(world.viewPaper(id).vertexCount(), static_cast<std::size_t>(n * n));
}

}  // namespace
}  // namespace tearables

namespace tearables {
namespace {

/// Fig. 5: an edge folded so far that the vertices across it come closer than
/// hinge_threshold times their rest distance gets a hinge spring at the folded distance
/// (the bending spring it replaces is retired), and the fold stays after the sheet is
/// let go.
TEST(PaperHinge, FoldedEdgeGetsAHingeThatKeepsTheFold) {
    PaperDesc d;
    d.size[0] = 0.02;
    d.size[1] = 0.02;
    d.resolution[0] = 2;
    d.resolution[1] = 2;
    d.hinge_threshold = 0.5;
    d.phi = 1000.0;  // no compression breaks here: only the fold
    World world{WorldSettings{Vec3::Zero()}};
    // Vertices 0 (-x,-z), 1 (+x,-z), 2 (-x,+z), 3 (+x,+z); the diagonal 0-3 is the inner
    // edge, the bending spring joins 1 and 2. Fold vertex 1 about the diagonal by 160 deg.
    const PaperId id = world.addPaper(d);
    {
        // Fold it as a load would: the flat sheet's springs stay the rest state. (A
        // sheet given folded would take the fold as its rest shape.)
        const std::vector<Vec3>& x = *world.viewPaper(id).positions;
        const Vec3 axis = (x[3] - x[0]).normalized();
        const Vec3 moved = x[0] + Eigen::AngleAxisd(160.0 * M_PI / 180.0, axis) * (x[1] - x[0]);
        world.attachPaperToPoint(id, 1, moved);  // puts it there
        world.detachPaper(id, 1);
    }
    world.step(1e-4);
    const PaperView v = world.viewPaper(id);
    ASSERT_EQ(v.counters.hinges, 1u);
    const PaperSpring* hinge = nullptr;
    for (const PaperSpring& sp : *v.springs) {
        if (sp.kind == PaperSpringKind::Hinge) hinge = &sp;
        if (sp.kind == PaperSpringKind::Bending) EXPECT_TRUE(sp.broken);
    }
    ASSERT_NE(hinge, nullptr);
    EXPECT_EQ(std::min(hinge->a, hinge->b), 1u);
    EXPECT_EQ(std::max(hinge->a, hinge->b), 2u);
    EXPECT_LT(hinge->rest, 0.5 * std::sqrt(2.0) * 0.02);
    bool event = false;
    for (const Event& e : world.events()) event = event || e.type == EventType::Hinge;
    EXPECT_TRUE(event);
    // Let go: one second later the fold is still there (the vertices across the edge stay
    // at the hinge's distance).
    for (int i = 0; i < 60; ++i) world.step(1.0 / 60.0);
    const PaperView after = world.viewPaper(id);
    EXPECT_NEAR(((*after.positions)[1] - (*after.positions)[2]).norm(), hinge->rest, 0.05 * hinge->rest);
    EXPECT_EQ(detail::checkMesh(after, 0.08 * 0.02 * 0.02), "");
}

}  // namespace
}  // namespace tearables
