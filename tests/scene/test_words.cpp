// One meaning per word across strings, papers and cloths (docs/SCENE_FORMAT.md, "Words"):
// a paper and a cloth written with the same words weigh the same and lie in the same place,
// in a scene and in C++; a word used the old way is refused with what to write now.
#include "tearables/bullet_core.hpp"
#include "tearables/scene.hpp"
#include "tearables/world.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numeric>
#include <string>
#include <vector>

namespace {

using namespace tearables;
using tearables::scene::parseScene;

double sum(const std::vector<double>& v) { return std::accumulate(v.begin(), v.end(), 0.0); }

/// Rounding of a sum of n terms of a double-precision product: a few ulps each, so a
/// relative 1e-13 bounds it for the few hundred vertices here (n * 2^-52 ~ 1e-13 for n = 400).
constexpr double kRounding = 1e-13;

/// What InvalidInput a scene is refused with ("" when it loads).
InvalidInput refusal(const std::string& text) {
    try {
        parseScene(text);
    } catch (const InvalidInput& e) {
        return e;
    }
    return InvalidInput("", "");
}

/// A sheet's words, the same for a paper and a cloth.
std::string sheet(const std::string& name, const std::string& placement) {
    return R"({"name": ")" + name + R"(", )" + placement +
           R"(, "size": [0.3, 0.2], "resolution": [7, 5], "orientation": [0.2, 0.3, 0.1, 0.9], "areal_density": 0.08})";
}

/// A paper and a cloth with the same center (or corner), size, resolution, orientation and
/// areal_density: each weighs areal_density * size[0] * size[1], and vertex k * nx + i of one
/// lies where vertex k * nx + i of the other does.
void expectSameSheet(const std::string& placement) {
    SCOPED_TRACE(placement);
    const scene::Scene s = parseScene(R"({"papers": [)" + sheet("p", placement) + R"(], "cloths": [)" + sheet("c", placement) + "]}");
    World world;
    const PaperId paper = world.addPaper(s.papers.at(0).desc);
    const ClothId cloth = world.addCloth(s.cloths.at(0).desc);
    const PaperView pv = world.viewPaper(paper);
    const ClothView cv = world.viewCloth(cloth);
    const double mass = 0.08 * 0.3 * 0.2;  // areal_density * area, kg
    EXPECT_NEAR(sum(*pv.masses), mass, kRounding * mass);
    EXPECT_NEAR(sum(*cv.masses), mass, kRounding * mass);
    ASSERT_EQ(pv.vertexCount(), 35u);
    ASSERT_EQ(cv.vertexCount(), 35u);
    // Positions within rounding of the 0.3 m sheet (the paper rotates by a quaternion, the
    // cloth by its matrix): 1e-15 m relative to the metre-sized coordinates, with margin.
    for (std::size_t v = 0; v < 35; ++v) EXPECT_LT(((*pv.positions)[v] - (*cv.positions)[v]).norm(), 1e-14) << "vertex " << v;
}

TEST(Words, PaperAndClothWithTheSameWordsWeighTheSameAndLieTheSame) {
    expectSameSheet(R"("center": [0.5, 1.5, -0.25])");
    expectSameSheet(R"("corner": [0.5, 1.5, -0.25])");
}

// The corner is vertex [0, 0], the local -x -z corner: a sheet given by its corner lies
// where one given by its centre half the size away (in its frame) does, paper and cloth.
TEST(Words, CornerIsHalfTheSizeFromTheCenter) {
    const Quat q = Quat(0.9, 0.2, 0.3, 0.1).normalized();
    const Vec3 corner(0.5, 1.5, -0.25);
    const Vec3 center = corner + q * Vec3(0.15, 0.0, 0.1);
    World world;
    PaperDesc a, b;
    a.size[0] = b.size[0] = 0.3;
    a.size[1] = b.size[1] = 0.2;
    a.resolution[0] = b.resolution[0] = 7;
    a.resolution[1] = b.resolution[1] = 5;
    a.orientation = b.orientation = q;
    a.corner = corner;
    b.center = center;
    ClothDesc c, d;
    c.size = d.size = {0.3, 0.2};
    c.resolution = d.resolution = {7, 5};
    c.orientation = d.orientation = q;
    c.corner = corner;
    d.center = center;
    const PaperId ida = world.addPaper(a), idb = world.addPaper(b);
    const ClothId idc = world.addCloth(c), idd = world.addCloth(d);
    // Views after every object is added (adding one may move the others' storage).
    const PaperView pa = world.viewPaper(ida), pb = world.viewPaper(idb);
    const ClothView ca = world.viewCloth(idc), cb = world.viewCloth(idd);
    EXPECT_LT(((*pa.positions)[0] - corner).norm(), 1e-15);
    EXPECT_LT(((*ca.positions)[0] - corner).norm(), 1e-15);
    for (std::size_t v = 0; v < 35; ++v) {
        EXPECT_LT(((*pa.positions)[v] - (*pb.positions)[v]).norm(), 1e-14) << "paper vertex " << v;
        EXPECT_LT(((*ca.positions)[v] - (*cb.positions)[v]).norm(), 1e-14) << "cloth vertex " << v;
    }
    // Vertex 1 is one spacing along local x from vertex 0; vertex 7 (= 1 * nx + 0) one along z.
    EXPECT_LT(((*pa.positions)[1] - (corner + q * Vec3(0.05, 0, 0))).norm(), 1e-14);
    EXPECT_LT(((*ca.positions)[7] - (corner + q * Vec3(0, 0, 0.05))).norm(), 1e-14);
}

// Neither center nor corner: both kinds centre on (0, 1, 0).
TEST(Words, DefaultPlacementIsTheSameCentre) {
    World world;
    PaperDesc p;
    ClothDesc c;
    p.size[0] = p.size[1] = 0.2;
    p.resolution[0] = p.resolution[1] = 5;
    c.size = {0.2, 0.2};
    c.resolution = {5, 5};
    const PaperId pid = world.addPaper(p);
    const ClothId cid = world.addCloth(c);
    const PaperView pv = world.viewPaper(pid);
    const ClothView cv = world.viewCloth(cid);
    EXPECT_LT(((*pv.positions)[12] - Vec3(0, 1, 0)).norm(), 1e-15);  // the middle vertex (2, 2)
    EXPECT_LT(((*cv.positions)[12] - Vec3(0, 1, 0)).norm(), 1e-15);
}

// The bug as filed: a cloth written like a paper of the old format (density in kg/m^2,
// origin its centre) was taken as fibre of 0.08 kg/m^3 cornered there, and hung weightless.
// Now each old word is refused, naming the field and saying what to write.
TEST(Words, AClothWrittenLikeAnOldPaperIsRefused) {
    const InvalidInput e = refusal(R"({"cloths": [{"name": "c", "origin": [0, 1, 0], "density": 0.08}]})");
    EXPECT_EQ(e.field(), "cloths[0].origin");
    EXPECT_NE(e.problem().find("write \"corner\": [0,1,0]"), std::string::npos) << e.problem();
    const InvalidInput p = refusal(R"({"papers": [{"name": "p", "center": [0, 1, 0], "density": 0.08}]})");
    EXPECT_EQ(p.field(), "papers[0].density");
    EXPECT_NE(p.problem().find("write \"areal_density\": 0.08"), std::string::npos) << p.problem();
}

// Attachments: the same keys and meanings on strings, papers and cloths. "world": true pins
// where the particle or vertex is; "body" without "local" glues it where it is; "edge" names
// a side of a sheet or cloth; vertices are an index or [i, k].
TEST(Words, AttachmentsMeanTheSameOnEveryObject) {
    const scene::Scene s = parseScene(R"({
      "bodies": [{"name": "b", "shape": {"box": [0.1, 0.1, 0.1]}, "mass": 0, "position": [3, 0, 0]}],
      "strings": [{"name": "r", "from": [0, 2, 0], "to": [0, 1, 0], "segments": 4,
                   "attachments": [{"particle": 0, "world": true}, {"particle": -1, "body": "b"}]}],
      "papers": [{"name": "p", "corner": [1, 1, 0], "size": [0.2, 0.2], "resolution": [3, 3],
                  "attachments": [{"edge": "z-", "world": true}, {"vertex": [0, -1], "body": "b"}]}],
      "cloths": [{"name": "c", "corner": [2, 1, 0], "size": [0.2, 0.2], "resolution": [3, 3],
                  "attachments": [{"edge": "z-", "world": true}, {"vertex": 6, "body": "b"}]}]
    })");
    const scene::String& r = s.strings.at(0);
    ASSERT_EQ(r.attachments.size(), 2u);
    EXPECT_EQ(r.attachments[0].world, std::optional<Vec3>(Vec3(0, 2, 0)));
    EXPECT_FALSE(r.attachments[1].local.has_value());
    const scene::Paper& p = s.papers.at(0);
    ASSERT_EQ(p.desc.attachments.size(), 3u);  // the z- side: vertices 0, 1, 2
    for (int v = 0; v < 3; ++v) EXPECT_EQ(p.desc.attachments[static_cast<std::size_t>(v)].vertex, v);
    ASSERT_EQ(p.glue.size(), 1u);
    EXPECT_EQ(p.glue[0].vertex, 6u);  // [0, -1] = 2 * 3 + 0
    EXPECT_FALSE(p.glue[0].local.has_value());
    const scene::Cloth& c = s.cloths.at(0);
    ASSERT_EQ(c.desc.attachments.size(), 3u);  // the same words, the same C++ fields as the paper's
    for (int v = 0; v < 3; ++v) {
        EXPECT_EQ(c.desc.attachments[static_cast<std::size_t>(v)].vertex, v);
        EXPECT_FALSE(c.desc.attachments[static_cast<std::size_t>(v)].world.has_value());
    }
    ASSERT_EQ(c.glue.size(), 1u);
    EXPECT_EQ(c.glue[0].vertex, 6u);
    EXPECT_FALSE(c.glue[0].local.has_value());
}

// Glued without "local": the particle (vertex) stays where it is, on a string as on a cloth
// and a paper. Were it glued at the body's centre it would be pulled 0.5 m or more there.
TEST(Words, GluedWithoutLocalStaysWhereItIs) {
    const scene::Scene s = parseScene(R"({
      "dt": 0.01, "steps": 10, "gravity": [0, 0, 0],
      "bodies": [{"name": "b", "shape": {"box": [0.1, 0.1, 0.1]}, "mass": 0, "position": [0, 0, 0]}],
      "strings": [{"name": "r", "from": [0.5, 1, 0], "to": [0.5, 0, 0], "segments": 4,
                   "attachments": [{"particle": -1, "body": "b"}]}],
      "papers": [{"name": "p", "corner": [-1, 0, 0], "size": [0.2, 0.2], "resolution": [3, 3], "breakable": false,
                  "attachments": [{"vertex": 0, "body": "b"}]}],
      "cloths": [{"name": "c", "corner": [0, 0, 1], "size": [0.2, 0.2], "resolution": [3, 3],
                  "attachments": [{"vertex": 0, "body": "b"}]}]
    })");
    scene::SceneRun run(s);
    for (int k = 0; k < 10; ++k) run.advance();
    const World& w = run.ropes().core();
    // Nothing pulls: without gravity the held points keep their place to the solvers'
    // tolerance, far below the 0.5 m an anchor at the body's centre would have moved them.
    EXPECT_LT((w.view(run.stringId(0)).positions->back() - Vec3(0.5, 0, 0)).norm(), 1e-3);
    EXPECT_LT(((*w.viewPaper(run.paperId(0)).positions)[0] - Vec3(-1, 0, 0)).norm(), 1e-3);
    EXPECT_LT(((*w.viewCloth(run.clothId(0)).positions)[0] - Vec3(0, 0, 1)).norm(), 1e-3);
}

}  // namespace
