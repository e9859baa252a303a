// The viewer as a person uses it, under Xvfb: tearables-view opens tests/viewer/two_ropes.json,
// a script (drag_and_cut.txt) pulls the left rope until it tears and cuts the right one, and
// the screenshots and the state printed at exit are checked. Skipped (reported as such) when
// xvfb-run is not installed. Bad scripts and arguments are refused before any window opens.
#include "render/renderer.hpp"
#include "render/scene_painter.hpp"
#include "render/tools.hpp"
#include "tearables/scene.hpp"
#include "tearables/colormap.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <sys/wait.h>

namespace {

namespace fs = std::filesystem;
using tearables::Rgb;
using tearables::Vec3;
using tearables::render::Image;

struct Outcome {
    int status = -1;
    std::string out, err;
};

std::string slurp(const fs::path& p) {
    std::ifstream in(p);
    std::stringstream s;
    s << in.rdbuf();
    return s.str();
}

/// Runs `command` in `dir` (a shell command line), capturing stdout and stderr.
Outcome runIn(const fs::path& dir, const std::string& command) {
    fs::create_directories(dir);
    const std::string cmd = "cd " + dir.string() + " && " + command + " >stdout.txt 2>stderr.txt";
    const int raw = std::system(cmd.c_str());
    Outcome r;
    r.status = WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
    r.out = slurp(dir / "stdout.txt");
    r.err = slurp(dir / "stderr.txt");
    return r;
}

const std::string kViewer = TEARABLES_VIEWER_PROGRAM;
const std::string kScenes = std::string(TEARABLES_SOURCE_DIR) + "/tests/viewer/";

/// Hue of an RGB colour, degrees in [0, 360).
double hue(double r, double g, double b) {
    const double hi = std::max({r, g, b}), lo = std::min({r, g, b}), c = hi - lo;
    if (c <= 0.0) return 0.0;
    double h = hi == r ? std::fmod((g - b) / c, 6.0) : hi == g ? (b - r) / c + 2.0 : (r - g) / c + 4.0;
    h *= 60.0;
    return h < 0.0 ? h + 360.0 : h;
}

/// A pixel drawn with the tension colour map: saturated (the sky, the grid and the panels'
/// greys are not) with a hue the map takes, from its deep blue (about 245 degrees) through
/// magenta and orange to its yellow (about 62 degrees). Shading scales a colour and adds
/// grey, which keeps its hue.
bool tensionColoured(const Image& im, int x, int y) {
    if (x < 0 || y < 0 || x >= im.width || y >= im.height) return false;
    const auto p = im.at(x, y);
    const int hi = std::max({p[0], p[1], p[2]}), lo = std::min({p[0], p[1], p[2]});
    if (hi - lo < 40) return false;
    const double h = hue(p[0], p[1], p[2]);
    return h >= 235.0 || h <= 68.0;
}

/// The share of points of the vertical segment x = x0, y in [y0, y1] (z = 0) whose pixel
/// (or one within 2 px across) is tension coloured, seen by the test scene's camera.
double ropeCoverage(const Image& im, double x0, double y0, double y1) {
    tearables::render::Renderer projector(im.width, im.height, 1);
    tearables::render::View view;
    view.eye = Vec3(0.0, 1.0, 3.0);
    view.target = Vec3(0.0, 1.0, 0.0);
    view.fov = 40.0;
    projector.begin(view);
    int seen = 0, total = 0;
    for (double y = y0; y <= y1 + 1e-9; y += 0.01) {
        const auto p = projector.project(Vec3(x0, y, 0.0));
        if (!p) continue;
        ++total;
        const int px = static_cast<int>(std::lround((*p)[0])), py = static_cast<int>(std::lround((*p)[1]));
        bool hit = false;
        for (int dx = -2; dx <= 2 && !hit; ++dx) hit = tensionColoured(im, px + dx, py);
        seen += hit;
    }
    return total > 0 ? static_cast<double>(seen) / total : 0.0;
}

/// The colour bar at the window's right edge (demos/viewer/viewer.cpp, colorBarRect): from
/// the bottom (load 0) to the top (load 1) it shows the tension colour map.
void expectColourBar(const Image& im) {
    const int x = im.width - 36;
    const double top = 40.0, bottom = std::max(im.height - 250, 140);
    for (double u : {0.1, 0.3, 0.5, 0.7, 0.9}) {
        const int y = static_cast<int>(std::lround(bottom - u * (bottom - top)));
        const auto p = im.at(x, y);
        const Rgb c = tearables::tensionColor(u);
        // 64 bands: a band's colour differs from the exact u's by at most 1/128 of the map's
        // span (< 3 levels), plus rounding.
        EXPECT_NEAR(p[0], 255.0 * c.r, 6.0) << "colour bar at load " << u;
        EXPECT_NEAR(p[1], 255.0 * c.g, 6.0) << "colour bar at load " << u;
        EXPECT_NEAR(p[2], 255.0 * c.b, 6.0) << "colour bar at load " << u;
    }
}

}  // namespace

TEST(Viewer, DragTearsARopeAndAClickCutsAnother) {
    if (tearables::render::findOnPath("xvfb-run").empty()) GTEST_SKIP() << "xvfb-run is not installed (apt-get install xvfb xauth)";
    const fs::path dir = fs::path(TEARABLES_TEST_OUT) / "viewer" / "drag_and_cut";
    fs::remove_all(dir);
    const Outcome r = runIn(dir, "xvfb-run -a -s '-screen 0 1024x768x24' " + kViewer + " " + kScenes +
                                 "two_ropes.json --size 1280x900 --script " + kScenes + "drag_and_cut.txt --print-state");
    ASSERT_EQ(r.status, 0) << r.err;

    // The state at exit: the pulled rope tore under tension, the other was cut (a tear by
    // request) where it was clicked, at its middle (segments 9 and 10 meet at y = 1.0).
    const auto state = nlohmann::json::parse(r.out);
    ASSERT_TRUE(state.contains("strings")) << r.out;
    bool pull_tore = false, cut_cut = false;
    int cut_segment = -1;
    for (const auto& e : state["events"]) {
        if (e["type"] != "tear") continue;
        if (e["object"] == "pull" && e["cause"] == "tension") pull_tore = true;
        if (e["object"] == "cut") {
            EXPECT_EQ(e["cause"], "request");
            cut_cut = true;
            cut_segment = e["segment"];
        }
    }
    EXPECT_TRUE(pull_tore) << r.out;
    EXPECT_TRUE(cut_cut) << r.out;
    EXPECT_GE(cut_segment, 9);
    EXPECT_LE(cut_segment, 10);
    EXPECT_FALSE(state["strings"]["pull"]["broken"].empty());
    ASSERT_EQ(state["strings"]["cut"]["broken"].size(), 1u);
    EXPECT_EQ(state["strings"]["cut"]["broken"][0], cut_segment);

    const Image before = tearables::render::readPng((dir / "before.png").string());
    const Image after = tearables::render::readPng((dir / "after.png").string());
    ASSERT_EQ(before.width, 1280);
    ASSERT_EQ(before.height, 900);
    // Before: both ropes hang whole, tension coloured, along their length (the ends left out).
    EXPECT_GT(ropeCoverage(before, -0.3, 0.65, 1.35), 0.9);
    EXPECT_GT(ropeCoverage(before, 0.3, 0.65, 1.35), 0.9);
    // After: the pulled rope tore where the hand held it, so its torn-off end fell from the
    // hand when it was let go (0.6 m up before, and 1.5 s of free fall take it ~10 m down;
    // a rope that had not torn would hold it within its 0.8 m and 13% of plastic stretch);
    // the cut rope keeps its upper half and has lost its lower half.
    EXPECT_LT(state["strings"]["pull"]["ends"][1][1].get<double>(), -1.0);
    EXPECT_GT(ropeCoverage(after, 0.3, 1.05, 1.35), 0.9);
    EXPECT_LT(ropeCoverage(after, 0.3, 0.65, 0.95), 0.1);
    expectColourBar(before);
    expectColourBar(after);
}

// A pinned particle dragged and let go is pinned again where it was let go: the right
// rope's top, carried from x = 0.3 to 0.6 m, stays there (a free end would fall 0.3 m in the
// last second); nothing tears on the way (the pull is far below the rupture tension).
TEST(Viewer, DraggedAnchorIsPinnedWhereItIsLetGo) {
    if (tearables::render::findOnPath("xvfb-run").empty()) GTEST_SKIP() << "xvfb-run is not installed (apt-get install xvfb xauth)";
    const fs::path dir = fs::path(TEARABLES_TEST_OUT) / "viewer" / "move_anchor";
    fs::remove_all(dir);
    const Outcome r = runIn(dir, "xvfb-run -a -s '-screen 0 1024x768x24' " + kViewer + " " + kScenes +
                                     "two_ropes.json --size 800x600 --hide-panels --script " + kScenes + "move_anchor.txt --print-state");
    ASSERT_EQ(r.status, 0) << r.err;
    const auto state = nlohmann::json::parse(r.out);
    const auto& top = state["strings"]["cut"]["ends"][0];
    // The hand follows the cursor through a constraint: within 2 cm of it after 40 frames.
    EXPECT_NEAR(top[0].get<double>(), 0.6, 0.02) << r.out;
    EXPECT_NEAR(top[1].get<double>(), 1.4, 0.02) << r.out;
    EXPECT_TRUE(state["strings"]["cut"]["broken"].empty());
    EXPECT_TRUE(state["strings"]["pull"]["broken"].empty());
    // The other rope was not touched: its top is where the scene pinned it (to Bullet's
    // single precision, in which the pin point is given: 0.3 rounds by 1.2e-8).
    EXPECT_NEAR(state["strings"]["pull"]["ends"][0][0].get<double>(), -0.3, 1e-7);
}

TEST(Viewer, ScreenshotAfterStepsWritesTheWindow) {
    if (tearables::render::findOnPath("xvfb-run").empty()) GTEST_SKIP() << "xvfb-run is not installed (apt-get install xvfb xauth)";
    const fs::path dir = fs::path(TEARABLES_TEST_OUT) / "viewer" / "screenshot";
    fs::remove_all(dir);
    const Outcome r = runIn(dir, "xvfb-run -a -s '-screen 0 1024x768x24' " + kViewer + " " + kScenes +
                                 "two_ropes.json --size 1280x900 --screenshot shot.png --steps 10");
    ASSERT_EQ(r.status, 0) << r.err;
    const Image im = tearables::render::readPng((dir / "shot.png").string());
    EXPECT_EQ(im.width, 1280);
    EXPECT_EQ(im.height, 900);
    EXPECT_GT(ropeCoverage(im, -0.3, 0.65, 1.35), 0.9);
    expectColourBar(im);
}

// The window draws ropes with the same code as the headless frames: a straight rope of
// radius r = 0.04 m seen across from d = 2 m covers 2 f r / sqrt(d^2 - r^2) rows, f =
// H / (2 tan(fov/2)) (the 16-sided tube is within 2 % of the circle: to 2 px), and its
// shading varies across it.
TEST(Viewer, ThickRopeIsATubeAtItsTrueRadius) {
    if (tearables::render::findOnPath("xvfb-run").empty()) GTEST_SKIP() << "xvfb-run is not installed (apt-get install xvfb xauth)";
    const fs::path dir = fs::path(TEARABLES_TEST_OUT) / "viewer" / "thick_rope";
    fs::remove_all(dir);
    fs::create_directories(dir);
    std::ofstream(dir / "rope.json") << R"({"format": "tearables-scene/1", "gravity": [0, 0, 0], "steps": 0,
        "camera": {"eye": [0, 1, 2], "target": [0, 1, 0], "fov": 40},
        "strings": [{"name": "rope", "from": [-0.6, 1, 0], "to": [0.6, 1, 0], "segments": 12, "radius": 0.04}]})";
    const Outcome r = runIn(dir, "xvfb-run -a -s '-screen 0 1024x768x24' " + kViewer +
                                 " rope.json --size 640x480 --hide-panels --paused --screenshot shot.png");
    ASSERT_EQ(r.status, 0) << r.err;
    const Image im = tearables::render::readPng((dir / "shot.png").string());
    ASSERT_EQ(im.height, 480);
    const int x = 320 + 16;  // right of the middle joint: (0.05, 1, 0) is 16 px from the centre
    std::vector<int> rows, sums;
    for (int y = 0; y < im.height; ++y) {
        const auto p = im.at(x, y);
        const int sum = p[0] + p[1] + p[2];
        if (sum < 450) rows.push_back(y), sums.push_back(sum);  // the sky is lighter than 600
    }
    ASSERT_FALSE(rows.empty());
    const double f = 480.0 / (2.0 * std::tan(20.0 * M_PI / 180.0));
    const double expected = 2.0 * f * 0.04 / std::sqrt(4.0 - 0.04 * 0.04);
    std::printf("window: thick rope covers %zu rows, %.2f expected\n", rows.size(), expected);
    EXPECT_NEAR(static_cast<double>(rows.size()), expected, 2.0);
    EXPECT_NEAR(0.5 * (rows.front() + rows.back() + 1), 240.0, 1.5);
    EXPECT_GT(*std::max_element(sums.begin() + 2, sums.end() - 2) - *std::min_element(sums.begin() + 2, sums.end() - 2), 40);
}

// --follow in the window: a ball falls 11 m in 1.5 s; after 150 steps the middle of its
// pixels (brown) is in the central third of the screenshot both ways.
TEST(Viewer, FollowKeepsAFallingBodyCentred) {
    if (tearables::render::findOnPath("xvfb-run").empty()) GTEST_SKIP() << "xvfb-run is not installed (apt-get install xvfb xauth)";
    const fs::path dir = fs::path(TEARABLES_TEST_OUT) / "viewer" / "follow";
    fs::remove_all(dir);
    fs::create_directories(dir);
    std::ofstream(dir / "falling.json") << R"({"format": "tearables-scene/1", "dt": 0.01, "steps": 150,
        "bodies": [{"name": "ball", "shape": {"sphere": 0.2}, "mass": 1, "position": [0.8, 10, 0]},
                   {"name": "post", "shape": {"box": [0.2, 0.2, 0.2]}, "mass": 0, "position": [0, 10, 0]}]})";
    const Outcome r = runIn(dir, "xvfb-run -a -s '-screen 0 1024x768x24' " + kViewer +
                                 " falling.json --size 800x600 --hide-panels --follow ball --screenshot shot.png --steps 150");
    ASSERT_EQ(r.status, 0) << r.err;
    const Image im = tearables::render::readPng((dir / "shot.png").string());
    double sx = 0.0, sy = 0.0;
    int n = 0;
    for (int y = 0; y < im.height; ++y)
        for (int x = 0; x < im.width; ++x) {
            const auto p = im.at(x, y);
            if (p[0] > 100 && p[0] > p[2] + 50) sx += x, sy += y, ++n;
        }
    ASSERT_GT(n, 50) << "the ball is not in the window";
    EXPECT_GT(sx / n, im.width / 3.0);
    EXPECT_LT(sx / n, 2.0 * im.width / 3.0);
    EXPECT_GT(sy / n, im.height / 3.0);
    EXPECT_LT(sy / n, 2.0 * im.height / 3.0);
    // An unknown name is refused before any window, naming the option.
    const Outcome bad = runIn(dir, "env -u DISPLAY " + kViewer + " falling.json --follow crate");
    EXPECT_EQ(bad.status, 2);
    EXPECT_NE(bad.err.find("--follow"), std::string::npos) << bad.err;
}

// Refusals come before any window: no display is needed for them.
TEST(Viewer, BadScriptIsRefusedNamingTheLine) {
    const fs::path dir = fs::path(TEARABLES_TEST_OUT) / "viewer" / "bad_script";
    fs::create_directories(dir);
    std::ofstream(dir / "bad.txt") << "frames 3\nmove 10 x\n";
    const Outcome r = runIn(dir, "env -u DISPLAY " + kViewer + " " + kScenes + "two_ropes.json --script bad.txt");
    EXPECT_EQ(r.status, 2) << r.err;
    EXPECT_NE(r.err.find("script:2"), std::string::npos) << r.err;
    std::ofstream(dir / "bad2.txt") << "key z\n";
    const Outcome r2 = runIn(dir, "env -u DISPLAY " + kViewer + " " + kScenes + "two_ropes.json --script bad2.txt");
    EXPECT_EQ(r2.status, 2) << r2.err;
    EXPECT_NE(r2.err.find("unknown key"), std::string::npos) << r2.err;
}

TEST(Viewer, BadArgumentsAreRefused) {
    const fs::path dir = fs::path(TEARABLES_TEST_OUT) / "viewer" / "bad_args";
    const Outcome r = runIn(dir, "env -u DISPLAY " + kViewer + " no-such-scene");
    EXPECT_EQ(r.status, 2);
    EXPECT_NE(r.err.find("no-such-scene"), std::string::npos) << r.err;
    const Outcome r2 = runIn(dir, "env -u DISPLAY " + kViewer + " " + kScenes + "two_ropes.json --size 10x10");
    EXPECT_EQ(r2.status, 2);
    EXPECT_NE(r2.err.find("--size"), std::string::npos) << r2.err;
    // `tearables view` hands its arguments to tearables-view.
    const Outcome r3 = runIn(dir, "env -u DISPLAY " + std::string(TEARABLES_CLI) + " view no-such-scene");
    EXPECT_EQ(r3.status, 2);
    EXPECT_NE(r3.err.find("no-such-scene"), std::string::npos) << r3.err;
}

/// The share of points along a polyline (every 5 mm) in view whose pixel (or one within
/// 2 px) is tension coloured, seen from `view`; the first `skip` m of it are left out. At
/// least 50 points must be in view.
double polylineCoverage(const Image& im, const tearables::render::View& view, const std::vector<Vec3>& points, double skip) {
    tearables::render::Renderer projector(im.width, im.height, 1);
    projector.begin(view);
    int seen = 0, total = 0;
    double along = 0.0;
    for (std::size_t k = 0; k + 1 < points.size(); ++k) {
        const double len = (points[k + 1] - points[k]).norm();
        for (double s = 0.0; s < len; s += 0.005) {
            along += 0.005;
            if (along < skip) continue;
            const auto p = projector.project(points[k] + (points[k + 1] - points[k]) * (s / len));
            if (!p || (*p)[0] < 0 || (*p)[1] < 0 || (*p)[0] >= im.width || (*p)[1] >= im.height) continue;  // out of view
            ++total;
            const int px = static_cast<int>(std::lround((*p)[0])), py = static_cast<int>(std::lround((*p)[1]));
            bool hit = false;
            for (int dy = -2; dy <= 2 && !hit; ++dy)
                for (int dx = -2; dx <= 2 && !hit; ++dx) hit = tensionColoured(im, px + dx, py + dy);
            seen += hit;
        }
    }
    EXPECT_GE(total, 50) << "the polyline is out of view";
    return total > 0 ? static_cast<double>(seen) / total : 0.0;
}

// Playback of a recorded run (`tearables run hanging-rope --out DIR`, then `view --trace`):
// the screenshot at step 300 shows the rope where the trace has it at step 300 (hanging),
// not where it started (a slanted line); the arrow keys step one frame forwards and back.
TEST(Viewer, PlaysBackARecordedRun) {
    if (tearables::render::findOnPath("xvfb-run").empty()) GTEST_SKIP() << "xvfb-run is not installed (apt-get install xvfb xauth)";
    const fs::path dir = fs::path(TEARABLES_TEST_OUT) / "viewer" / "playback";
    fs::remove_all(dir);
    const Outcome rec = runIn(dir, std::string(TEARABLES_CLI) + " run hanging-rope --quiet --out rec");
    ASSERT_EQ(rec.status, 0) << rec.err;
    const Outcome r = runIn(dir, "xvfb-run -a -s '-screen 0 1024x768x24' " + kViewer +
                                 " hanging-rope --trace rec --size 800x600 --hide-panels --screenshot shot.png --steps 300");
    ASSERT_EQ(r.status, 0) << r.err;

    // The trace's first and last frames (every 10 steps: step 0 and step 300).
    std::ifstream trace(dir / "rec" / "trace.jsonl");
    std::string line, first, last;
    while (std::getline(trace, line))
        if (!line.empty()) (first.empty() ? first : last) = line;
    const auto points = [](const std::string& text) {
        std::vector<Vec3> out;
        const nlohmann::json frame = nlohmann::json::parse(text);
        for (const auto& p : frame["strings"]["rope"]["x"]) out.emplace_back(p[0].get<double>(), p[1].get<double>(), p[2].get<double>());
        return out;
    };
    ASSERT_EQ(nlohmann::json::parse(last)["step"], 300);
    namespace ts = tearables::scene;
    const tearables::render::View view = tearables::render::fitCamera(ts::parseScene(*ts::builtinSceneText("hanging-rope")), 800.0 / 600.0);
    const Image im = tearables::render::readPng((dir / "shot.png").string());
    EXPECT_GT(polylineCoverage(im, view, points(last), 0.1), 0.9);
    EXPECT_LT(polylineCoverage(im, view, points(first), 0.3), 0.3);
    expectColourBar(im);

    // Paused at the start: three frames on, one back: frame 2 (step 20).
    fs::create_directories(dir);
    std::ofstream(dir / "keys.txt") << "key right\nkey right\nkey right\nkey left\nframes 2\nquit\n";
    const Outcome k = runIn(dir, "xvfb-run -a -s '-screen 0 1024x768x24' " + kViewer +
                                 " hanging-rope --trace rec --size 640x480 --paused --script keys.txt --print-state");
    ASSERT_EQ(k.status, 0) << k.err;
    const auto state = nlohmann::json::parse(k.out);
    EXPECT_EQ(state["frame"], 2);
    EXPECT_EQ(state["step"], 20);
}

TEST(Viewer, TraceThatDoesNotMatchTheSceneIsRefused) {
    const fs::path dir = fs::path(TEARABLES_TEST_OUT) / "viewer" / "bad_trace";
    fs::remove_all(dir);
    fs::create_directories(dir / "rec");
    const Outcome none = runIn(dir, "env -u DISPLAY " + kViewer + " hanging-rope --trace nowhere");
    EXPECT_EQ(none.status, 2);
    EXPECT_NE(none.err.find("--trace"), std::string::npos) << none.err;
    std::ofstream(dir / "rec" / "trace.jsonl") << R"({"step": 0, "t": 0, "strings": {"other": {"x": [], "tension": [], "broken": []}}})" << "\n";
    const Outcome wrong = runIn(dir, "env -u DISPLAY " + kViewer + " hanging-rope --trace rec");
    EXPECT_EQ(wrong.status, 2);
    EXPECT_NE(wrong.err.find("\"other\" is not in the scene"), std::string::npos) << wrong.err;
}
