// Pictures, videos and plots from the command line, run headless as a user runs it: the
// PNGs exist, decode, have the size asked for and show something; bad options exit 2 naming
// the option; missing tools exit 1 saying how to install them.
#include "render/renderer.hpp"
#include "tearables/colormap.hpp"

#include <nlohmann/json.hpp>

#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <sys/wait.h>
#include <unistd.h>
#include <vector>

namespace {

namespace fs = std::filesystem;
using tearables::render::Image;
using tearables::render::readPng;

struct Result {
    int status = -1;
    std::string err;
};

/// Runs the CLI with `args` and no display (DISPLAY unset), with `env` before it (e.g.
/// "PATH=/nonexistent"), capturing stderr.
Result cli(const std::string& args, const std::string& env = "") {
    const fs::path dir = fs::path(TEARABLES_TEST_OUT) / "cli";
    fs::create_directories(dir);
    const fs::path err = dir / ("stderr-pictures-" + std::to_string(::getpid()) + ".txt");
    const std::string cmd = "env -u DISPLAY " + env + " " + std::string(TEARABLES_CLI) + " " + args + " >/dev/null 2>" + err.string();
    const int raw = std::system(cmd.c_str());
    Result r;
    r.status = WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
    std::ifstream in(err);
    std::stringstream s;
    s << in.rdbuf();
    r.err = s.str();
    return r;
}

/// Standard deviation of the pixels' grey level.
double greyDeviation(const Image& im) {
    double sum = 0.0, sum2 = 0.0;
    const std::size_t n = static_cast<std::size_t>(im.width) * im.height;
    for (std::size_t i = 0; i < n; ++i) {
        const double g = (im.rgb[3 * i] + im.rgb[3 * i + 1] + im.rgb[3 * i + 2]) / 3.0;
        sum += g;
        sum2 += g * g;
    }
    return std::sqrt(std::max(0.0, sum2 / n - (sum / n) * (sum / n)));
}

/// The rows of a plot data file (lines not starting with '#'), each split into numbers.
std::vector<std::vector<double>> dataRows(const fs::path& path) {
    std::ifstream in(path);
    std::vector<std::vector<double>> rows;
    std::string line;
    while (std::getline(in, line)) {
        if (line.empty() || line[0] == '#') continue;
        std::istringstream fields(line);
        std::vector<double> row;
        std::string field;
        while (fields >> field) row.push_back(field == "NaN" ? std::nan("") : std::stod(field));
        rows.push_back(row);
    }
    return rows;
}

/// The number of lines of a text file.
std::size_t lineCount(const fs::path& path) {
    std::ifstream in(path);
    std::size_t n = 0;
    for (std::string line; std::getline(in, line);) n += !line.empty();
    return n;
}

/// The events of `type` on `object` in events.jsonl.
long long eventCount(const fs::path& events, const std::string& type, const std::string& object) {
    std::ifstream in(events);
    long long n = 0;
    for (std::string line; std::getline(in, line);) {
        if (line.empty()) continue;
        const nlohmann::json e = nlohmann::json::parse(line);
        n += e.value("type", "") == type && e.value("object", "") == object;
    }
    return n;
}

std::string fileText(const fs::path& path) {
    std::ifstream in(path);
    std::stringstream s;
    s << in.rdbuf();
    return s.str();
}

bool haveGnuplot() { return std::system("command -v gnuplot >/dev/null 2>&1") == 0; }

}  // namespace

// `run swing --png --steps 80 --size 160x90`: one picture per trace frame (every 5 steps:
// 17), each 160x90, not blank, and the crate's fall changes the picture.
TEST(Pictures, SwingWritesDecodablePngs) {
    const fs::path out = fs::path(TEARABLES_TEST_OUT) / "pictures-swing";
    fs::remove_all(out);
    const Result r = cli("run swing --png --steps 80 --size 160x90 --quiet --out " + out.string());
    ASSERT_EQ(r.status, 0) << r.err;
    int count = 0;
    for (const auto& e : fs::directory_iterator(out))
        if (e.path().filename().string().rfind("frame_", 0) == 0) ++count;
    EXPECT_EQ(count, 17);
    Image first, last;
    for (int i = 0; i < 17; ++i) {
        char name[32];
        std::snprintf(name, sizeof name, "frame_%05d.png", i);
        const Image im = readPng((out / name).string());
        ASSERT_EQ(im.width, 160) << name;
        ASSERT_EQ(im.height, 90) << name;
        EXPECT_GT(greyDeviation(im), 10.0) << name << " looks blank";
        if (i == 0) first = im;
        last = im;
    }
    int changed = 0;
    for (std::size_t i = 0; i < first.rgb.size(); i += 3)
        if (std::abs(first.rgb[i] - last.rgb[i]) + std::abs(first.rgb[i + 1] - last.rgb[i + 1]) +
                std::abs(first.rgb[i + 2] - last.rgb[i + 2]) > 30)
            ++changed;
    EXPECT_GT(changed, 50) << "the first and the last frame look alike";
}

TEST(Pictures, BadOptionsExitTwoNamingTheOption) {
    for (const char* size : {"160", "160x", "x90", "abcxdef", "8x8", "100000x90", "-160x90"}) {
        const Result r = cli(std::string("run swing --steps 1 --png --out ") + TEARABLES_TEST_OUT + "/pictures-bad --size " + size);
        EXPECT_EQ(r.status, 2) << size;
        EXPECT_NE(r.err.find("--size"), std::string::npos) << size << ": " << r.err;
    }
    const Result plot_size = cli(std::string("run flick --steps 1 --plot --plot-size 0x0 --out ") + TEARABLES_TEST_OUT + "/pictures-bad");
    EXPECT_EQ(plot_size.status, 2);
    EXPECT_NE(plot_size.err.find("--plot-size"), std::string::npos) << plot_size.err;
    const Result no_png = cli(std::string("run swing --steps 1 --size 160x90 --out ") + TEARABLES_TEST_OUT + "/pictures-bad");
    EXPECT_EQ(no_png.status, 2);
    EXPECT_NE(no_png.err.find("--size"), std::string::npos) << no_png.err;
}

// Without ffmpeg or gnuplot on PATH, --mp4 and --plot stop before simulating, exit 1, and say
// how to install them.
TEST(Pictures, MissingToolsSayHowToInstallThem) {
    const fs::path out = fs::path(TEARABLES_TEST_OUT) / "pictures-notools";
    fs::remove_all(out);
    const Result mp4 = cli("run swing --steps 5 --mp4 --out " + out.string(), "PATH=/nonexistent");
    EXPECT_EQ(mp4.status, 1);
    EXPECT_NE(mp4.err.find("apt-get install ffmpeg"), std::string::npos) << mp4.err;
    const Result plot = cli("run flick --steps 5 --plot --out " + out.string(), "PATH=/nonexistent");
    EXPECT_EQ(plot.status, 1);
    EXPECT_NE(plot.err.find("apt-get install gnuplot-nox"), std::string::npos) << plot.err;
    EXPECT_FALSE(fs::exists(out / "trace.jsonl")) << "simulated although the tool is missing";
}

// --plot on an experiment with curves writes plot.png through gnuplot (skipped only where
// gnuplot is not installed; CI installs it).
TEST(Pictures, PlotOfRuptureVariation) {
    if (std::system("command -v gnuplot >/dev/null 2>&1") != 0) GTEST_SKIP() << "gnuplot is not installed";
    const fs::path out = fs::path(TEARABLES_TEST_OUT) / "pictures-plot";
    fs::remove_all(out);
    const Result r = cli("run rupture-variation --plot --plot-size 800x600 --steps 300 --quiet --out " + out.string());
    ASSERT_EQ(r.status, 0) << r.err;
    const Image plot = readPng((out / "plot.png").string());
    EXPECT_EQ(plot.width, 800);
    EXPECT_EQ(plot.height, 600);
    EXPECT_GT(greyDeviation(plot), 10.0);
    for (int i = 0; i < 4; ++i) EXPECT_TRUE(fs::exists(out / ("plot_" + std::to_string(i) + ".dat"))) << i;
}

// Headless frames carry a time stamp at the top-left and, for a scene with strings, the
// tension colour bar at the right edge (render/overlay.hpp: x in [w - 48, w - 24), from
// y = 40 (load 1) down to min(max(h - 250, 140), h - 30) (load 0)).
TEST(Pictures, FramesHaveTimeStampAndColourBar) {
    const fs::path out = fs::path(TEARABLES_TEST_OUT) / "pictures-overlay";
    fs::remove_all(out);
    const Result r = cli("run swing --png --steps 20 --every 20 --size 640x360 --quiet --out " + out.string());
    ASSERT_EQ(r.status, 0) << r.err;
    const Image first = readPng((out / "frame_00000.png").string());
    const Image second = readPng((out / "frame_00001.png").string());
    const int x = first.width - 36;
    const double top = 40.0, bottom = 140.0;
    for (double u : {0.1, 0.3, 0.5, 0.7, 0.9}) {
        const int y = static_cast<int>(std::lround(bottom - u * (bottom - top)));
        const auto p = first.at(x, y);
        const tearables::Rgb c = tearables::tensionColor(u);
        // 64 bands: a band's colour differs from the exact u's by at most 1/128 of the
        // map's span (< 3 levels), plus rounding.
        EXPECT_NEAR(p[0], 255.0 * c.r, 6.0) << "colour bar at load " << u;
        EXPECT_NEAR(p[1], 255.0 * c.g, 6.0) << "colour bar at load " << u;
        EXPECT_NEAR(p[2], 255.0 * c.b, 6.0) << "colour bar at load " << u;
    }
    // The stamp: dark text in the box at (8, 8), 19 px high; it reads t = 0 in the first
    // frame and t = 0.2 s in the second, so the two differ there.
    int ink = 0, differ = 0;
    for (int y = 8; y < 27; ++y)
        for (int xx = 8; xx < 160; ++xx) {
            const auto a = first.at(xx, y), b = second.at(xx, y);
            ink += a[0] + a[1] + a[2] < 3 * 100;
            differ += std::abs(a[0] - b[0]) + std::abs(a[1] - b[1]) + std::abs(a[2] - b[2]) > 60;
        }
    EXPECT_GT(ink, 40) << "no time stamp text";
    EXPECT_GT(differ, 10) << "the time stamp did not change with the time";
}

// A ball falls out of the first frame's view (1.5 s: 11 m down, the scene is 1.6 m across):
// the camera is refitted as it leaves, so the last frame still shows it (its colour, the
// first dynamic body's brown, is in the picture), as does the first.
TEST(Pictures, CameraKeepsAFallingBodyInFrame) {
    const fs::path out = fs::path(TEARABLES_TEST_OUT) / "pictures-falling";
    fs::remove_all(out);
    fs::create_directories(out);
    const fs::path scene = out / "falling.json";
    std::ofstream(scene) << R"({"format": "tearables-scene/1", "dt": 0.01, "steps": 150, "output": {"every": 50},
        "bodies": [{"name": "ball", "shape": {"sphere": 0.2}, "mass": 1, "position": [0.8, 10, 0]},
                   {"name": "post", "shape": {"box": [0.2, 0.2, 0.2]}, "mass": 0, "position": [0, 10, 0]}]})";
    const Result r = cli("run " + scene.string() + " --png --size 640x360 --quiet --out " + out.string());
    ASSERT_EQ(r.status, 0) << r.err;
    const auto brown = [](const Image& im) {
        int n = 0;
        for (int y = 0; y < im.height; ++y)
            for (int x = 0; x < im.width; ++x) {
                const auto p = im.at(x, y);
                n += p[0] > 100 && p[0] > p[2] + 50;
            }
        return n;
    };
    EXPECT_GT(brown(readPng((out / "frame_00000.png").string())), 20) << "the ball is not in the first frame";
    EXPECT_GT(brown(readPng((out / "frame_00003.png").string())), 20) << "the ball fell out of the picture";
}

// --plot on a cloth (no strings): plot.png with the cloth's panels; its data has a row per
// trace frame, and the torn yarns of the last frame are the tear events on the cloth (the
// trace's broken list and the event log are written by separate code).
TEST(Pictures, PlotOfClothTear) {
    if (!haveGnuplot()) GTEST_SKIP() << "gnuplot is not installed";
    const fs::path out = fs::path(TEARABLES_TEST_OUT) / "pictures-plot-cloth";
    fs::remove_all(out);
    const Result r = cli("run cloth-tear --plot --plot-size 640x480 --quiet --out " + out.string());
    ASSERT_EQ(r.status, 0) << r.err;
    const Image plot = readPng((out / "plot.png").string());
    EXPECT_EQ(plot.width, 640);
    EXPECT_GT(greyDeviation(plot), 10.0);
    const auto rows = dataRows(out / "plot_cloth_0.dat");
    ASSERT_EQ(rows.size(), lineCount(out / "trace.jsonl"));
    ASSERT_EQ(rows.back().size(), 3u);
    const long long tears = eventCount(out / "events.jsonl", "tear", "cloth");
    EXPECT_GT(tears, 0) << "the scene tears its cloth";
    EXPECT_EQ(static_cast<long long>(rows.back()[2]), tears);
    for (std::size_t i = 1; i < rows.size(); ++i) EXPECT_GE(rows[i][2], rows[i - 1][2]) << "torn yarns do not heal";
    const std::string script = fileText(out / "plot.gp");
    EXPECT_NE(script.find("Cloth: torn yarns"), std::string::npos);
    EXPECT_EQ(script.find("Torsional"), std::string::npos) << "a torsion panel without strings";
    EXPECT_EQ(script.find("Stress-strain"), std::string::npos) << "a string panel without strings";
}

// --plot on a paper sheet: its creases column ends at the crease events on the sheet.
TEST(Pictures, PlotOfPaper) {
    if (!haveGnuplot()) GTEST_SKIP() << "gnuplot is not installed";
    const fs::path out = fs::path(TEARABLES_TEST_OUT) / "pictures-plot-paper";
    fs::remove_all(out);
    const Result r = cli("run paper-ball --plot --plot-size 640x480 --quiet --out " + out.string());
    ASSERT_EQ(r.status, 0) << r.err;
    EXPECT_GT(greyDeviation(readPng((out / "plot.png").string())), 10.0);
    std::ifstream data(out / "plot_paper_0.dat");
    std::string header;
    std::getline(data, header);
    const std::string name = header.substr(2);
    const auto rows = dataRows(out / "plot_paper_0.dat");
    ASSERT_EQ(rows.size(), lineCount(out / "trace.jsonl"));
    EXPECT_EQ(static_cast<long long>(rows.back()[1]), eventCount(out / "events.jsonl", "crease", name));
    EXPECT_NE(fileText(out / "plot.gp").find("Paper: creases"), std::string::npos);
}

// The torsion panel is there only when a string twists: not for a hanging rope, and for
// torsion-uniform (a twisted string).
TEST(Pictures, TorsionPanelOnlyWhereStringsTwist) {
    if (!haveGnuplot()) GTEST_SKIP() << "gnuplot is not installed";
    const fs::path plain = fs::path(TEARABLES_TEST_OUT) / "pictures-plot-plain";
    const fs::path twisted = fs::path(TEARABLES_TEST_OUT) / "pictures-plot-twisted";
    fs::remove_all(plain);
    fs::remove_all(twisted);
    Result r = cli("run hanging-rope --plot --steps 50 --quiet --out " + plain.string());
    ASSERT_EQ(r.status, 0) << r.err;
    EXPECT_EQ(fileText(plain / "plot.gp").find("Torsional"), std::string::npos);
    EXPECT_NE(fileText(plain / "plot.gp").find("Tension"), std::string::npos);
    r = cli("run torsion-uniform --plot --steps 50 --quiet --out " + twisted.string());
    ASSERT_EQ(r.status, 0) << r.err;
    EXPECT_NE(fileText(twisted / "plot.gp").find("Torsional"), std::string::npos);
}

// A scene with nothing --plot draws is refused before simulating: exit 2 naming --plot.
TEST(Pictures, PlotOfNothingRefusedBeforeSimulating) {
    const fs::path out = fs::path(TEARABLES_TEST_OUT) / "pictures-plot-nothing";
    fs::remove_all(out);
    fs::create_directories(out);
    const fs::path scene = out / "boxes.json";
    std::ofstream(scene) << R"({"format": "tearables-scene/1", "dt": 0.01, "steps": 10,
        "bodies": [{"name": "ground", "shape": {"plane": [0, 1, 0, 0]}, "mass": 0},
                   {"name": "box", "shape": {"box": [0.1, 0.1, 0.1]}, "mass": 1, "position": [0, 1, 0]}]})";
    const Result r = cli("run " + scene.string() + " --plot --quiet --out " + out.string());
    EXPECT_EQ(r.status, 2) << r.err;
    EXPECT_NE(r.err.find("--plot"), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(out / "trace.jsonl")) << "simulated although there is nothing to plot";
}

// --mp4 with ffmpeg installed (not in CI: skipped there): a non-empty video.mp4 beside the frames.
TEST(Pictures, VideoWhereFfmpegIsInstalled) {
    if (std::system("command -v ffmpeg >/dev/null 2>&1") != 0) GTEST_SKIP() << "ffmpeg is not installed";
    const fs::path out = fs::path(TEARABLES_TEST_OUT) / "pictures-video";
    fs::remove_all(out);
    const Result r = cli("run swing --mp4 --steps 40 --size 160x90 --quiet --out " + out.string());
    ASSERT_EQ(r.status, 0) << r.err;
    ASSERT_TRUE(fs::exists(out / "video.mp4"));
    EXPECT_GT(fs::file_size(out / "video.mp4"), 1000u);
    EXPECT_TRUE(fs::exists(out / "frame_00008.png"));
}

// --follow keeps a falling body centred: a ball falls 11 m in 1.5 s past a fixed post; in
// every frame the middle of its pixels (the first dynamic body's brown) is in the central
// third of the picture both ways. Without --follow it would leave the first frame's view.
TEST(Pictures, FollowKeepsAFallingBodyCentred) {
    const fs::path out = fs::path(TEARABLES_TEST_OUT) / "pictures-follow";
    fs::remove_all(out);
    fs::create_directories(out);
    const fs::path scene = out / "falling.json";
    std::ofstream(scene) << R"({"format": "tearables-scene/1", "dt": 0.01, "steps": 150, "output": {"every": 25},
        "bodies": [{"name": "ball", "shape": {"sphere": 0.2}, "mass": 1, "position": [0.8, 10, 0]},
                   {"name": "post", "shape": {"box": [0.2, 0.2, 0.2]}, "mass": 0, "position": [0, 10, 0]}]})";
    const Result r = cli("run " + scene.string() + " --png --size 320x180 --follow ball --quiet --out " + out.string());
    ASSERT_EQ(r.status, 0) << r.err;
    int frames = 0;
    for (int k = 0; fs::exists(out / ("frame_0000" + std::to_string(k) + ".png")); ++k) {
        const Image im = readPng((out / ("frame_0000" + std::to_string(k) + ".png")).string());
        double sx = 0.0, sy = 0.0;
        int n = 0;
        for (int y = 0; y < im.height; ++y)
            for (int x = 0; x < im.width; ++x) {
                const auto p = im.at(x, y);
                if (p[0] > 100 && p[0] > p[2] + 50) sx += x, sy += y, ++n;
            }
        ASSERT_GT(n, 20) << "the ball is not in frame " << k;
        EXPECT_GT(sx / n, im.width / 3.0) << "frame " << k;
        EXPECT_LT(sx / n, 2.0 * im.width / 3.0) << "frame " << k;
        EXPECT_GT(sy / n, im.height / 3.0) << "frame " << k;
        EXPECT_LT(sy / n, 2.0 * im.height / 3.0) << "frame " << k;
        ++frames;
    }
    EXPECT_EQ(frames, 7);  // steps 0, 25, ..., 150
    // A name the scene does not have, or --follow without pictures, is refused naming it.
    const Result unknown = cli("run " + scene.string() + " --png --follow crate --quiet --out " + out.string());
    EXPECT_EQ(unknown.status, 2);
    EXPECT_NE(unknown.err.find("--follow"), std::string::npos) << unknown.err;
    EXPECT_NE(unknown.err.find("ball, post"), std::string::npos) << unknown.err;
    const Result no_png = cli("run " + scene.string() + " --follow ball --quiet --out " + out.string());
    EXPECT_EQ(no_png.status, 2);
    EXPECT_NE(no_png.err.find("--follow"), std::string::npos) << no_png.err;
}
