// The offscreen renderer (OSMesa): pictures have the size asked for, what is drawn lands
// where the camera says, PNG files round-trip, and a scene's rope shows against its background.
#include "render/overlay.hpp"
#include "render/renderer.hpp"
#include "render/scene_painter.hpp"
#include "tearables/scene.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <vector>

namespace {

namespace fs = std::filesystem;
using namespace tearables;
using namespace tearables::render;

int difference(const std::array<std::uint8_t, 3>& a, const std::array<std::uint8_t, 3>& b) {
    return std::abs(a[0] - b[0]) + std::abs(a[1] - b[1]) + std::abs(a[2] - b[2]);
}

}  // namespace

// A bright tube across the middle: the pixel where its midpoint projects takes its colour;
// without it, that pixel is the sky.
TEST(Renderer, TubeLandsWhereTheCameraProjectsIt) {
    Renderer r(120, 80);
    const View view{{0.0, 0.0, 2.0}, {0.0, 0.0, 0.0}, 40.0};
    r.begin(view);
    const Image empty = r.finish();
    ASSERT_EQ(empty.width, 120);
    ASSERT_EQ(empty.height, 80);
    r.begin(view);
    const Rgb yellow = tensionColor(1.0);
    r.drawTube({{-0.5, 0.1, 0.0}, {0.5, 0.1, 0.0}}, {0.03}, {yellow}, {0});
    const Image tube = r.finish();
    const auto p = r.project({0.0, 0.1, 0.0});
    ASSERT_TRUE(p.has_value());
    const int x = static_cast<int>((*p)[0]), y = static_cast<int>((*p)[1]);
    EXPECT_NEAR((*p)[0], 60.0, 0.5);
    EXPECT_LT((*p)[1], 40.0);  // above the centre: y = 0.1 is up
    EXPECT_GT(difference(tube.at(x, y), empty.at(x, y)), 60);
    EXPECT_GT(tube.at(x, y)[0], tube.at(x, y)[2] + 40);  // yellowish: red well above blue
    // Far from the tube nothing changed.
    EXPECT_LT(difference(tube.at(x, 75), empty.at(x, 75)), 3);
    // Broken segments are not drawn.
    r.begin(view);
    r.drawTube({{-0.5, 0.1, 0.0}, {0.5, 0.1, 0.0}}, {0.03}, {yellow}, {1});
    EXPECT_LT(difference(r.finish().at(x, y), empty.at(x, y)), 3);
}

TEST(Renderer, PngRoundTrip) {
    Image image;
    image.width = 17;
    image.height = 5;
    for (int i = 0; i < 17 * 5 * 3; ++i) image.rgb.push_back(static_cast<std::uint8_t>(i * 7));
    const fs::path dir = fs::path(TEARABLES_TEST_OUT) / "render";
    fs::create_directories(dir);
    const std::string path = (dir / "roundtrip.png").string();
    writePng(path, image);
    const Image back = readPng(path);
    EXPECT_EQ(back.width, 17);
    EXPECT_EQ(back.height, 5);
    EXPECT_EQ(back.rgb, image.rgb);
    EXPECT_THROW(readPng((dir / "missing.png").string()), std::runtime_error);
    EXPECT_THROW(Renderer(8, 8), InvalidInput);
}

// The swing scene through the scene painter with its fitted default camera: every rope
// particle is in the picture, and at the middle of each rope the pixel differs from the same
// frame painted without the strings.
TEST(Renderer, SwingRopesShowAgainstTheBackground) {
    const auto text = scene::builtinSceneText("swing");
    ASSERT_TRUE(text.has_value());
    scene::Scene s = scene::parseScene(*text);
    Renderer r(160, 90);
    const View view = fitCamera(s, 160.0 / 90.0);
    scene::RunOptions options;
    options.steps = 10;
    options.every = 5;  // frames at steps 0, 5, 10
    int frames = 0;
    options.on_frame = [&](const scene::FrameState& f) {
        ++frames;
        if (f.step != 10) return;
        ASSERT_EQ(f.strings.size(), 2u);
        const Image with = paintFrame(r, s, f, view);
        scene::FrameState bare = f;
        bare.strings.clear();
        const Image without = paintFrame(r, s, bare, view);
        for (const scene::FrameString& str : f.strings) {
            const auto& x = *str.view.positions;
            for (const Vec3& p : x) {
                const auto q = r.project(p);
                ASSERT_TRUE(q.has_value());
                EXPECT_GE((*q)[0], 0.0);
                EXPECT_LT((*q)[0], 160.0);
                EXPECT_GE((*q)[1], 0.0);
                EXPECT_LT((*q)[1], 90.0);
            }
            const auto mid = r.project(x[x.size() / 2]);
            const int px = static_cast<int>((*mid)[0]), py = static_cast<int>((*mid)[1]);
            EXPECT_GT(difference(with.at(px, py), without.at(px, py)), 60) << str.name << " at " << px << "," << py;
        }
    };
    scene::runScene(s, options);
    EXPECT_EQ(frames, 3);
}

// World pins are drawn: in the swing scene each rope hangs from a world point; a few pixels
// above it (inside the pin's block, at least 8 px across, away from the rope below) the
// picture differs from the same frame of the scene without its attachments.
TEST(Renderer, WorldPinsAreDrawn) {
    const auto text = scene::builtinSceneText("swing");
    ASSERT_TRUE(text.has_value());
    scene::Scene s = scene::parseScene(*text);
    scene::Scene unpinned = s;
    for (scene::String& str : unpinned.strings) str.attachments.clear();
    Renderer r(320, 180);
    const View view = fitCamera(s, 320.0 / 180.0);
    scene::RunOptions options;
    options.steps = 0;
    int frames = 0;
    options.on_frame = [&](const scene::FrameState& f) {
        ++frames;
        const Image with = paintFrame(r, s, f, view);
        const Image without = paintFrame(r, unpinned, f, view);
        for (const Vec3 pin : {Vec3(-0.4, 2.5, 0.0), Vec3(0.4, 2.5, 0.0)}) {
            const auto q = r.project(pin);
            ASSERT_TRUE(q.has_value());
            const int px = static_cast<int>((*q)[0]), py = static_cast<int>((*q)[1]) - 3;
            ASSERT_GE(py, 0);
            EXPECT_GT(difference(with.at(px, py), without.at(px, py)), 60) << "no pin at " << px << "," << py;
        }
    };
    scene::runScene(s, options);
    EXPECT_EQ(frames, 1);
}

// A camera given in the scene is used as written; fov defaults to 40 degrees.
TEST(Renderer, SceneCameraOverridesTheFit) {
    scene::Scene s = scene::parseScene(R"({"camera": {"eye": [1, 2, 3], "target": [0, 1, 0], "fov": 55}})");
    const View v = fitCamera(s, 16.0 / 9.0);
    EXPECT_EQ(v.eye, Vec3(1, 2, 3));
    EXPECT_EQ(v.target, Vec3(0, 1, 0));
    EXPECT_EQ(v.fov, 55.0);
    // Only a target: the eye is fitted around it, looking at it.
    s = scene::parseScene(R"({"camera": {"target": [0, 1, 0]},
                              "strings": [{"name": "a", "from": [-1, 2, 0], "to": [1, 2, 0], "segments": 4}]})");
    const View fitted = fitCamera(s, 16.0 / 9.0);
    EXPECT_EQ(fitted.target, Vec3(0, 1, 0));
    EXPECT_GT(fitted.eye.z(), 1.0);
    EXPECT_EQ(fitted.fov, 40.0);
}

// The entry point for paper and cloth: a sheet facing the camera takes its vertex colours
// (lit, from either side), and a crease line is drawn over it.
TEST(Renderer, TriangleMeshWithVertexColoursAndCreases) {
    Renderer r(100, 100);
    const View view{{0.0, 0.0, 2.0}, {0.0, 0.0, 0.0}, 40.0};
    const std::vector<Vec3> x = {{-0.5, -0.5, 0}, {0.5, -0.5, 0}, {0.5, 0.5, 0}, {-0.5, 0.5, 0}};
    const std::vector<std::array<std::uint32_t, 3>> tris = {{0, 1, 2}, {0, 2, 3}};
    const std::vector<Rgb> red(4, Rgb{0.9f, 0.1f, 0.1f});
    const std::vector<std::array<std::uint32_t, 2>> crease = {{0, 2}};
    r.begin(view);
    const Image empty = r.finish();
    for (const bool flipped : {false, true}) {
        std::vector<std::array<std::uint32_t, 3>> t = tris;
        if (flipped)
            for (auto& f : t) std::swap(f[1], f[2]);  // the back faces the camera
        TriangleMesh mesh;
        mesh.positions = &x;
        mesh.triangles = &t;
        mesh.vertex_colors = &red;
        r.begin(view);
        r.drawTriangleMesh(mesh);
        const Image sheet = r.finish();
        const auto px = sheet.at(70, 30);  // inside the sheet, off the diagonal
        EXPECT_GT(px[0], px[1] + 60) << (flipped ? "back" : "front");
        EXPECT_GT(difference(px, empty.at(70, 30)), 60);
        mesh.lines = &crease;
        r.begin(view);
        r.drawTriangleMesh(mesh);
        const Image creased = r.finish();
        const auto centre = r.project(Vec3::Zero());
        ASSERT_TRUE(centre.has_value());
        const int cx = static_cast<int>((*centre)[0]), cy = static_cast<int>((*centre)[1]);
        EXPECT_GT(difference(creased.at(cx, cy), sheet.at(cx, cy)), 20) << "no crease line";  // the line covers part of the pixel
    }
}

// A cloth shows as a surface: at step 0 of cloth-tear the pixel where its centre vertex
// projects differs from the same frame without the cloth; after its yarns tore, the
// quads along the cut are gone (fewer cloth pixels than a mesh with nothing torn).
TEST(Renderer, ClothShowsAsASurfaceAndOpensWhereItTore) {
    const auto text = scene::builtinSceneText("cloth-tear");
    ASSERT_TRUE(text.has_value());
    scene::Scene s = scene::parseScene(*text);
    Renderer r(160, 90);
    const View view = fitCamera(s, 160.0 / 90.0);
    scene::RunOptions options;
    options.every = 1000000;  // frames at step 0 and the last
    int checked = 0;
    auto covered = [](const Image& a, const Image& b) {
        int n = 0;
        for (int y = 0; y < 90; ++y)
            for (int x = 0; x < 160; ++x) n += difference(a.at(x, y), b.at(x, y)) > 30;
        return n;
    };
    options.on_frame = [&](const scene::FrameState& f) {
        ASSERT_EQ(f.cloths.size(), 1u);
        const Image with = paintFrame(r, s, f, view);
        scene::FrameState bare = f;
        bare.cloths.clear();
        const Image without = paintFrame(r, s, bare, view);
        const ClothView& v = f.cloths[0].view;
        if (f.step == 0) {
            const auto c = r.project((*v.positions)[v.vertexCount() / 2]);
            ASSERT_TRUE(c.has_value());
            EXPECT_GT(difference(with.at(static_cast<int>((*c)[0]), static_cast<int>((*c)[1])),
                                 without.at(static_cast<int>((*c)[0]), static_cast<int>((*c)[1]))), 60);
            ++checked;
            return;
        }
        std::size_t torn = 0;
        for (std::uint8_t b : *v.broken) torn += b;
        ASSERT_GT(torn, 0u);
        // The same positions drawn as if nothing had torn cover more pixels.
        std::vector<std::uint8_t> whole(v.broken->size(), 0);
        scene::FrameState intact = f;
        intact.cloths[0].view.broken = &whole;
        EXPECT_LT(covered(with, without), covered(paintFrame(r, s, intact, view), without));
        ++checked;
    };
    scene::runScene(s, options);
    EXPECT_EQ(checked, 2);
}

// Paper sheets are drawn: in paper-ball after the ball has pressed (step 40), the picture
// differs from an empty scene's, the pixel where a vertex of each sheet projects (off the
// ball, which pokes through the centre) differs from the same frame without the sheets, and the breakable sheet carries crease
// lines (drawn darker over it) where the elastic one has none.
TEST(Renderer, PaperSheetsShowWithTheirCreases) {
    const auto text = scene::builtinSceneText("paper-ball");
    ASSERT_TRUE(text.has_value());
    scene::Scene s = scene::parseScene(*text);
    Renderer r(160, 90);
    const View view = fitCamera(s, 160.0 / 90.0);
    scene::RunOptions options;
    options.steps = 40;
    options.every = 40;
    int checked = 0;
    options.on_frame = [&](const scene::FrameState& f) {
        if (f.step != 40) return;
        ASSERT_EQ(f.papers.size(), 2u);
        const Image with = paintFrame(r, s, f, view);
        scene::FrameState bare = f;
        bare.papers.clear();
        const Image without = paintFrame(r, s, bare, view);
        const Image empty = paintFrame(r, scene::Scene{}, scene::FrameState{}, view);
        int differs_from_empty = 0, sheet_pixels = 0;
        for (int y = 0; y < 90; ++y)
            for (int x = 0; x < 160; ++x) {
                differs_from_empty += difference(with.at(x, y), empty.at(x, y)) > 30;
                sheet_pixels += difference(with.at(x, y), without.at(x, y)) > 30;
            }
        EXPECT_GT(differs_from_empty, 400);
        EXPECT_GT(sheet_pixels, 300);  // two 0.2 m sheets in a 160x90 picture
        for (const scene::FramePaper& p : f.papers) {
            const auto& x = *p.view.positions;
            const auto c = r.project(x[10 * 21 + 4]);  // vertex (4, 10) of 21 x 21
            ASSERT_TRUE(c.has_value());
            const int px = static_cast<int>((*c)[0]), py = static_cast<int>((*c)[1]);
            EXPECT_GT(difference(with.at(px, py), without.at(px, py)), 30) << p.name << " at " << px << "," << py << ": " << int(with.at(px, py)[0]) << " " << int(with.at(px, py)[1]) << " " << int(with.at(px, py)[2]) << " vs " << int(without.at(px, py)[0]) << " " << int(without.at(px, py)[1]) << " " << int(without.at(px, py)[2]);
        }
        const auto lines = [&](const std::string& name) {
            for (const scene::FramePaper& p : f.papers)
                if (p.name == name) return paperCreaseLines(p.view).size();
            return std::size_t{0};
        };
        std::printf("crease lines: %zu (breakable), %zu (elastic)\n", lines("paper"), lines("elastic"));
        EXPECT_GT(lines("paper"), 0u);
        EXPECT_EQ(lines("elastic"), 0u);
        ++checked;
    };
    scene::runScene(s, options);
    EXPECT_EQ(checked, 1);
}

// Strings are coloured by torsional load too: at the end of torsion-nonuniform the soft
// outer thirds (twisted to about 0.7 of the rupture strain) are drawn in a brighter
// colour of the load map than the three times more rigid middle third (about 0.2), though
// neither carries tension.
TEST(Renderer, TwistedStringsAreColouredByTorsionalLoad) {
    const auto text = scene::builtinSceneText("torsion-nonuniform");
    ASSERT_TRUE(text.has_value());
    scene::Scene s = scene::parseScene(*text);
    Renderer r(320, 180);
    const View view = fitCamera(s, 320.0 / 180.0);
    scene::RunOptions options;
    options.every = 1000000;  // frames at step 0 and the last
    int checked = 0;
    options.on_frame = [&](const scene::FrameState& f) {
        if (f.step == 0) return;
        ASSERT_EQ(f.strings.size(), 1u);
        const Image picture = paintFrame(r, s, f, view);
        const auto& x = *f.strings[0].view.positions;
        const auto brightness = [&](std::size_t segment) {
            const auto p = r.project(0.5 * (x[segment] + x[segment + 1]));
            EXPECT_TRUE(p.has_value());
            const auto c = picture.at(static_cast<int>((*p)[0]), static_cast<int>((*p)[1]));
            return 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2];
        };
        const double soft = 0.5 * (brightness(4) + brightness(25)), rigid = brightness(15);
        std::printf("torsional load colours: soft %.0f, rigid %.0f (luminance of 255)\n", soft, rigid);
        EXPECT_GT(soft, rigid + 20.0);
        ++checked;
    };
    scene::runScene(s, options);
    EXPECT_EQ(checked, 1);
}

namespace {

/// The rows of column x where `with` differs from `without` (by more than 30 in the sum of
/// the channels), top to bottom.
std::vector<int> coveredRows(const Image& with, const Image& without, int x) {
    std::vector<int> rows;
    for (int y = 0; y < with.height; ++y)
        if (difference(with.at(x, y), without.at(x, y)) > 30) rows.push_back(y);
    return rows;
}

/// A straight rope of the given radius along x at height 1 m, 2 m in front of the scene's
/// camera, without gravity: frame 0 of the scene, painted with and without the rope.
struct RopePicture {
    Image with, without;
    std::array<double, 2> middle{0.0, 0.0};  // where (0.05, 1, 0), mid-segment, projects
    double pixel = 0.0;                      // the size of a pixel there, m
};
RopePicture paintRope(double radius, int width, int height) {
    scene::Scene s = scene::parseScene(R"({"gravity": [0, 0, 0], "steps": 0,
        "camera": {"eye": [0, 1, 2], "target": [0, 1, 0], "fov": 40},
        "strings": [{"name": "rope", "from": [-0.6, 1, 0], "to": [0.6, 1, 0], "segments": 12,
                     "radius": )" + std::to_string(radius) + "}]}");
    Renderer r(width, height);
    const View view = fitCamera(s, static_cast<double>(width) / height);
    RopePicture picture;
    scene::RunOptions options;
    options.on_frame = [&](const scene::FrameState& f) {
        if (f.step != 0) return;
        picture.with = paintFrame(r, s, f, view);
        scene::FrameState bare = f;
        bare.strings.clear();
        picture.without = paintFrame(r, s, bare, view);
        picture.middle = *r.project({0.05, 1.0, 0.0});
        picture.pixel = r.pixelSizeAt({0.05, 1.0, 0.0});
    };
    scene::runScene(s, options);
    return picture;
}

}  // namespace

// A thick rope is drawn at its true radius, as a lit tube. Seen across from d = 2 m, a
// cylinder of radius r spans the angle 2 asin(r/d): on a picture H pixels high with a
// vertical field of view fov, 2 f r / sqrt(d^2 - r^2) pixels, f = H / (2 tan(fov/2)). The
// 16-sided tube is within cos(pi/16) (2 %) of the circle, and anti-aliasing blurs each edge
// by under a pixel: the covered rows match to 2 pixels. The key light comes from above, so
// the brightness across the tube changes (the diffuse term alone spans 0.91 of the key's
// 0.75 on the upper half).
TEST(Renderer, ThickRopeIsALitTubeAtItsTrueRadius) {
    const double radius = 0.04, d = 2.0;
    const int height = 360;
    const RopePicture p = paintRope(radius, 640, height);
    const double f = height / (2.0 * std::tan(20.0 * M_PI / 180.0));
    const double expected = 2.0 * f * radius / std::sqrt(d * d - radius * radius);
    const std::vector<int> rows = coveredRows(p.with, p.without, static_cast<int>(p.middle[0]));
    ASSERT_FALSE(rows.empty());
    std::printf("thick rope: %zu rows covered, %.2f expected\n", rows.size(), expected);
    EXPECT_NEAR(static_cast<double>(rows.size()), expected, 2.0);
    EXPECT_EQ(rows.back() - rows.front() + 1, static_cast<int>(rows.size()));  // one band, no gaps
    EXPECT_NEAR(0.5 * (rows.front() + rows.back() + 1), p.middle[1], 1.5);    // centred on the axis
    // Shading: the sum of the channels across the inner rows (edges left out) varies, and
    // the brightest row is above the darkest one (the key light is above).
    int brightest = -1, darkest = 1000, y_bright = 0, y_dark = 0;
    for (std::size_t k = 2; k + 2 < rows.size(); ++k) {
        const auto c = p.with.at(static_cast<int>(p.middle[0]), rows[k]);
        const int sum = c[0] + c[1] + c[2];
        if (sum > brightest) brightest = sum, y_bright = rows[k];
        if (sum < darkest) darkest = sum, y_dark = rows[k];
    }
    std::printf("thick rope: brightness %d to %d across it\n", darkest, brightest);
    EXPECT_GT(brightest - darkest, 40);
    EXPECT_LT(y_bright, y_dark);
}

// A rope thinner than 3 pixels on screen is drawn 3 pixels wide (1.5 pixels either side of
// its axis), so that it stays visible: 2 to 4 rows covered, whatever its true radius.
TEST(Renderer, ThinRopeIsDrawnThreePixelsWide) {
    const RopePicture p = paintRope(0.0005, 320, 180);
    ASSERT_GT(p.pixel, 0.0005 * 3.0);  // the true width is under a pixel
    const std::vector<int> rows = coveredRows(p.with, p.without, static_cast<int>(p.middle[0]));
    EXPECT_GE(rows.size(), 2u);
    EXPECT_LE(rows.size(), 4u);
}

namespace {

/// Pixels coloured from the damage end of the colour map (tensionColor(u) for u above about
/// 0.4 has more red than blue; the intact end, the sky, the grid and the pins do not) in the
/// box around where `points` project.
int damageColouredPixels(const Renderer& r, const Image& im, const std::vector<Vec3>& points) {
    double x0 = 1e9, y0 = 1e9, x1 = -1e9, y1 = -1e9;
    for (const Vec3& p : points)
        if (const auto q = r.project(p)) {
            x0 = std::min(x0, (*q)[0]), y0 = std::min(y0, (*q)[1]);
            x1 = std::max(x1, (*q)[0]), y1 = std::max(y1, (*q)[1]);
        }
    int n = 0;
    for (int y = std::max(0, static_cast<int>(y0)); y <= std::min(im.height - 1, static_cast<int>(y1)); ++y)
        for (int x = std::max(0, static_cast<int>(x0)); x <= std::min(im.width - 1, static_cast<int>(x1)); ++x) {
            const auto c = im.at(x, y);
            n += c[0] > c[2] + 20;
        }
    return n;
}

}  // namespace

// Paper is coloured by damage: at the end of paper-ball the breakable sheet keeps its
// creases and the elastic one has none. Every vertex on a crease line has damage (its faces
// along the line border it); the elastic sheet has none anywhere. On the picture the
// breakable sheet shows the damage end of the colour map and the elastic one does not; the
// overlay's only bar is the damage bar.
TEST(Renderer, PaperIsColouredByDamage) {
    const auto text = scene::builtinSceneText("paper-ball");
    ASSERT_TRUE(text.has_value());
    scene::Scene s = scene::parseScene(*text);
    Renderer r(640, 360);
    const View view = fitCamera(s, 640.0 / 360.0);
    scene::RunOptions options;
    options.every = 1000000;  // frames at step 0 and the last
    int checked = 0;
    options.on_frame = [&](const scene::FrameState& f) {
        if (f.step == 0) return;
        ASSERT_EQ(f.papers.size(), 2u);
        const Image picture = paintFrame(r, s, f, view);
        for (std::size_t k = 0; k < 2; ++k) {
            const PaperView& v = f.papers[k].view;
            const std::vector<double> damage = paperDamage(v, s.papers[k].desc);
            ASSERT_EQ(damage.size(), v.vertexCount());
            const auto lines = paperCreaseLines(v);
            const int coloured = damageColouredPixels(r, picture, *v.positions);
            std::printf("%s: %zu crease lines, %d damage-coloured pixels\n", f.papers[k].name.c_str(), lines.size(), coloured);
            if (f.papers[k].name == "paper") {
                ASSERT_GT(lines.size(), 0u);
                for (const auto& l : lines) {
                    EXPECT_GT(damage[l[0]], 0.0);
                    EXPECT_GT(damage[l[1]], 0.0);
                }
                EXPECT_GT(coloured, 100);
            } else {
                EXPECT_EQ(lines.size(), 0u);
                for (double d : damage) EXPECT_EQ(d, 0.0);
                EXPECT_LT(coloured, 5);
            }
        }
        const std::vector<ColorBar> bars = colorBars(s, 640, 360);
        ASSERT_EQ(bars.size(), 1u);
        EXPECT_EQ(bars[0].kind, BarKind::Damage);
        EXPECT_EQ(bars[0].labels.front().text, "damage");
        ++checked;
    };
    scene::runScene(s, options);
    EXPECT_EQ(checked, 1);
}

// A cloth is coloured by damage: at the end of cloth-tear, both ends of every torn yarn
// have half or more of their cells damaged (a yarn borders two cells, or one on the edge,
// and both contain both its ends; a vertex has at most four). The intact cloth of step 0
// has no damage and shows none of the colour map's damage end; the torn one does.
TEST(Renderer, ClothIsColouredByDamage) {
    const auto text = scene::builtinSceneText("cloth-tear");
    ASSERT_TRUE(text.has_value());
    scene::Scene s = scene::parseScene(*text);
    Renderer r(320, 180);
    const View view = fitCamera(s, 320.0 / 180.0);
    scene::RunOptions options;
    options.every = 1000000;  // frames at step 0 and the last
    int checked = 0;
    options.on_frame = [&](const scene::FrameState& f) {
        ASSERT_EQ(f.cloths.size(), 1u);
        const ClothView& v = f.cloths[0].view;
        const std::vector<double> damage = clothDamage(v, s.cloths[0].desc);
        const int coloured = damageColouredPixels(r, paintFrame(r, s, f, view), *v.positions);
        std::printf("cloth at step %lld: %d damage-coloured pixels\n", f.step, coloured);
        if (f.step == 0) {
            for (double d : damage) EXPECT_EQ(d, 0.0);
            EXPECT_LT(coloured, 5);
        } else {
            std::size_t torn = 0;
            for (std::size_t e = 0; e < v.edgeCount(); ++e) {
                if (!(*v.broken)[e]) continue;
                ++torn;
                EXPECT_GE(damage[(*v.edges)[e][0]], 0.5);
                EXPECT_GE(damage[(*v.edges)[e][1]], 0.5);
            }
            EXPECT_GT(torn, 0u);
            EXPECT_GT(coloured, 20);
        }
        ++checked;
    };
    scene::runScene(s, options);
    EXPECT_EQ(checked, 2);
    // Its colour bar is the damage bar (the scene has no strings).
    const std::vector<ColorBar> bars = colorBars(s, 320, 180);
    ASSERT_EQ(bars.size(), 1u);
    EXPECT_EQ(bars[0].kind, BarKind::Damage);
}

// The grid stays under a refitted camera: a ball falls 11 m below a post in a scene without
// a ground; the camera refitted to everything seen (as --png does) looks far below where
// the scene started, and the grid is drawn there: the lower quarter of the picture has grid
// lines (pixels off the empty sky's gradient), as does the first frame's.
TEST(Renderer, GridStaysUnderARefittedCamera) {
    scene::Scene s = scene::parseScene(R"({"dt": 0.01, "steps": 150,
        "bodies": [{"name": "ball", "shape": {"sphere": 0.2}, "mass": 1, "position": [0.8, 10, 0]},
                   {"name": "post", "shape": {"box": [0.2, 0.2, 0.2]}, "mass": 0, "position": [0, 10, 0]}]})");
    const int w = 320, h = 180;
    Renderer r(w, h);
    Bounds seen = sceneBounds(s);
    View view = fitCamera(s, static_cast<double>(w) / h);
    scene::RunOptions options;
    options.every = 150;
    int checked = 0;
    options.on_frame = [&](const scene::FrameState& f) {
        const Bounds now = frameBounds(f);
        if (!inFrame(view, static_cast<double>(w) / h, now)) {
            seen.add(now.lo);
            seen.add(now.hi);
            view = fitCamera(s, static_cast<double>(w) / h, seen);
        }
        const Image picture = paintFrame(r, s, f, view);
        r.begin(view);
        const Image sky = r.finish();
        int lines = 0;
        for (int y = 3 * h / 4; y < h; ++y)
            for (int x = 0; x < w; ++x) lines += difference(picture.at(x, y), sky.at(x, y)) > 20;
        std::printf("step %lld: camera target y = %.2f m, %d grid pixels in the lower quarter\n", f.step, view.target.y(), lines);
        EXPECT_GT(lines, 100) << "no grid under the camera at step " << f.step;
        ++checked;
    };
    scene::runScene(s, options);
    EXPECT_EQ(checked, 2);
    EXPECT_LT(view.target.y(), 6.0);  // the camera was refitted down
}

// The overlay scales with the frame: at 1280x720 the colour bar's rectangle is twice that
// of 640x360 (the same share of the picture), at 320x180 it is 0.7 times (the least scale,
// so that 9-pixel text stays legible), and the time stamp's box scales alike.
TEST(Renderer, OverlayScalesWithTheFrame) {
    const auto text = scene::builtinSceneText("swing");
    ASSERT_TRUE(text.has_value());
    const scene::Scene s = scene::parseScene(*text);
    EXPECT_FLOAT_EQ(overlayScale(640, 360), 1.0f);
    EXPECT_FLOAT_EQ(overlayScale(1280, 720), 2.0f);
    EXPECT_FLOAT_EQ(overlayScale(320, 180), kMinOverlayScale);
    const ColorBar small = colorBars(s, 640, 360, overlayScale(640, 360)).at(0);
    const ColorBar large = colorBars(s, 1280, 720, overlayScale(1280, 720)).at(0);
    EXPECT_FLOAT_EQ(large.x0, 2.0f * small.x0);
    EXPECT_FLOAT_EQ(large.x1, 2.0f * small.x1);
    EXPECT_FLOAT_EQ(large.y0, 2.0f * small.y0);
    EXPECT_FLOAT_EQ(large.y1, 2.0f * small.y1);
    const ColorBar tiny = colorBars(s, 320, 180, overlayScale(320, 180)).at(0);
    EXPECT_NEAR(tiny.x1 - tiny.x0, 0.7f * (small.x1 - small.x0), 1e-3);
    EXPECT_LE(tiny.y1, 180.0f - 0.7f * 30.0f);
    EXPECT_FLOAT_EQ(StampBox::at(2.0f).x0, 2.0f * StampBox::at(1.0f).x0);
    // Painted: the bar's bands at 1280x720 lie where the layout puts them.
    Image image;
    image.width = 1280;
    image.height = 720;
    image.rgb.assign(1280 * 720 * 3, 255);
    paintOverlay(image, s, 0.0, 0);
    for (int k : {5, 30, 60}) {
        const auto [top, bottom] = large.bandRows(k);
        const auto p = image.at(static_cast<int>(0.5f * (large.x0 + large.x1)), static_cast<int>(0.5f * (top + bottom)));
        const Rgb c = ColorBar::bandColor(k);
        EXPECT_NEAR(p[0], 255.0 * c.r, 2.0);
        EXPECT_NEAR(p[1], 255.0 * c.g, 2.0);
        EXPECT_NEAR(p[2], 255.0 * c.b, 2.0);
    }
    // The stamp's text is 26 px high at this scale: dark ink well below row 8 + 13.
    int ink_low = 0;
    for (int y = 30; y < 50; ++y)
        for (int x = 16; x < 200; ++x) {
            const auto p = image.at(x, y);
            ink_low += p[0] + p[1] + p[2] < 300;
        }
    EXPECT_GT(ink_low, 30);
}

// Ropes coloured by twist alone (the viewer's T): in hanging-rope, whose rope never
// twists, loaded to half its rupture tension, the twist picture is the load picture of the
// same frame with every tension zero, pixel for pixel, and differs from the load picture
// where the rope is; the strings' bar then explains twist, 0..1.
TEST(Renderer, RopesColouredByTwistAloneShowNoTensionWhereNothingTwists) {
    const auto text = scene::builtinSceneText("hanging-rope");
    ASSERT_TRUE(text.has_value());
    scene::Scene s = scene::parseScene(*text);
    Renderer r(320, 180);
    const View view = fitCamera(s, 320.0 / 180.0);
    scene::RunOptions options;
    options.steps = 50;
    options.every = 50;
    int checked = 0;
    options.on_frame = [&](const scene::FrameState& f) {
        if (f.step != 50) return;
        ASSERT_FALSE(f.strings.empty());
        for (const scene::FrameString& str : f.strings)
            for (double t : *str.view.twist) ASSERT_EQ(t, 0.0);
        std::vector<std::vector<double>> zero, half;
        zero.reserve(f.strings.size());
        half.reserve(f.strings.size());
        scene::FrameState slack = f, loaded = f;
        for (std::size_t k = 0; k < f.strings.size(); ++k) {
            const StringView& v = f.strings[k].view;
            zero.emplace_back(v.tension->size(), 0.0);
            half.emplace_back(v.tension->size(), 0.5 * f.strings[k].rupture_stress * M_PI * v.radius * v.radius);
            slack.strings[k].view.tension = &zero.back();
            loaded.strings[k].view.tension = &half.back();
        }
        const Image load = paintFrame(r, s, loaded, view);
        const Image twist = paintFrame(r, s, loaded, view, RopeColors::Twist);
        const Image unloaded = paintFrame(r, s, slack, view);
        int differs = 0;
        for (int y = 0; y < 180; ++y)
            for (int x = 0; x < 320; ++x) {
                ASSERT_EQ(difference(twist.at(x, y), unloaded.at(x, y)), 0) << x << "," << y;
                differs += difference(twist.at(x, y), load.at(x, y)) > 30;
            }
        EXPECT_GT(differs, 20);
        const std::vector<ColorBar> bars = colorBars(s, 320, 180, overlayScale(320, 180), RopeColors::Twist);
        ASSERT_EQ(bars.size(), 1u);
        EXPECT_EQ(bars[0].kind, BarKind::Twist);
        EXPECT_EQ(bars[0].labels.front().text, "twist / rupture twist");
        ++checked;
    };
    scene::runScene(s, options);
    EXPECT_EQ(checked, 1);
}
