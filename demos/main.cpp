// The `tearables` command line: runs headless scenes (docs/SCENE_FORMAT.md).
// Exit status: 0 simulated; 2 the scene or the arguments are invalid (nothing simulated);
// 1 anything else went wrong.
#include "render/overlay.hpp"
#include "render/plot.hpp"
#include "render/scene_painter.hpp"
#include "render/tools.hpp"
#include "tearables/scene.hpp"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <regex>
#include <iostream>
#include <unistd.h>

namespace {

constexpr int kInvalid = 2;
constexpr int kFailed = 1;

/// A scene file path, or the name of a built-in scene.
tearables::scene::Scene loadNamed(const std::string& what) {
    namespace ts = tearables::scene;
    std::error_code ec;
    if (std::filesystem::is_regular_file(what, ec)) return ts::loadSceneFile(what);
    if (auto text = ts::builtinSceneText(what)) {
        ts::Scene scene = ts::parseScene(*text);
        scene.source = what;
        return scene;
    }
    throw tearables::InvalidInput("SCENE", "no scene file or built-in scene named \"" + what +
                                               "\" (see `tearables list`)");
}

/// "640x360" -> (640, 360); throws InvalidInput(option) for anything else.
std::pair<int, int> parseSize(const std::string& text, const std::string& option) {
    static const std::regex pattern("([0-9]{1,5})x([0-9]{1,5})");
    std::smatch m;
    if (!std::regex_match(text, m, pattern))
        throw tearables::InvalidInput(option, "expected WIDTHxHEIGHT in pixels, e.g. 640x360 (got \"" + text + "\")");
    const int w = std::stoi(m[1]), h = std::stoi(m[2]);
    if (w < 16 || h < 16 || w > 8192 || h > 8192)
        throw tearables::InvalidInput(option, "each side must be in [16, 8192] pixels (got " + text + ")");
    return {w, h};
}

/// A size in bytes: a number with an optional suffix K, M, G or T (powers of 1000), e.g.
/// 8G; within [1 MB, 1 PB].
double parseBytes(const std::string& text, const std::string& option) {
    static const std::regex pattern("([0-9]+(\\.[0-9]+)?)([KMGT]?)B?");
    std::smatch m;
    if (!std::regex_match(text, m, pattern))
        throw tearables::InvalidInput(option, "expected a size in bytes, e.g. 8G or 500M (got \"" + text + "\")");
    const std::string unit = m[3];
    const double scale = unit == "K" ? 1e3 : unit == "M" ? 1e6 : unit == "G" ? 1e9 : unit == "T" ? 1e12 : 1.0;
    const double bytes = std::stod(m[1]) * scale;
    if (!(bytes >= 1e6 && bytes <= 1e15)) throw tearables::InvalidInput(option, "must be in [1M, 1000T] (got " + text + ")");
    return bytes;
}

/// Deletes frame_*.png left in `dir` by an earlier run (a video would pick them up).
void removeOldFrames(const std::filesystem::path& dir) {
    std::error_code ec;
    if (!std::filesystem::is_directory(dir, ec)) return;
    for (const auto& entry : std::filesystem::directory_iterator(dir, ec)) {
        const std::string name = entry.path().filename().string();
        if (name.rfind("frame_", 0) == 0 && entry.path().extension() == ".png") std::filesystem::remove(entry.path(), ec);
    }
}

/// Runs `body`, mapping refusals to exit status 2 and other failures to 1.
template <class Body>
int guarded(const std::string& what, Body&& body) {
    try {
        body();
        return 0;
    } catch (const tearables::InvalidInput& e) {
        std::fprintf(stderr, "tearables: %s: %s\n", what.c_str(), e.what());
        return kInvalid;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "tearables: %s\n", e.what());
        return kFailed;
    }
}

/// `tearables view ...` runs the viewer's program, tearables-view, with the same arguments:
/// it links libGL for its window where this program links libOSMesa, and both export the gl*
/// entry points. Looked for beside this program, then on PATH; returns only when it cannot
/// be run.
int execViewer(int argc, char** argv) {
    std::error_code ec;
    std::filesystem::path self = std::filesystem::read_symlink("/proc/self/exe", ec);
    std::string program = ec ? std::string() : (self.parent_path() / "tearables-view").string();
    if (program.empty() || access(program.c_str(), X_OK) != 0) program = tearables::render::findOnPath("tearables-view");
    if (program.empty()) {
        std::fprintf(stderr,
                     "tearables: view: the viewer (tearables-view) was not built: it needs libglfw3-dev, libimgui-dev and "
                     "libgl-dev (bash .ci/install-deps), then configure again with cmake\n");
        return kFailed;
    }
    std::vector<char*> args{program.data()};
    for (int i = 2; i < argc; ++i) args.push_back(argv[i]);
    args.push_back(nullptr);
    execv(program.c_str(), args.data());
    std::fprintf(stderr, "tearables: view: cannot run %s\n", program.c_str());
    return kFailed;
}

}  // namespace

int main(int argc, char** argv) {
    if (argc >= 2 && std::string(argv[1]) == "view") return execViewer(argc, argv);
    CLI::App app{"tearables: ropes, strings, paper and cloth that twist and tear, for Bullet"};
    app.require_subcommand(1);

    std::string scene_arg, out_dir;
    long long steps = -1;
    int every = 0;
    bool png = false, quiet = false, mp4 = false, plot = false;
    std::string size_text, plot_size_text, follow, max_memory_text;
    double max_step_seconds = tearables::scene::ResourceLimits{}.step_seconds;
    CLI::App* run = app.add_subcommand("run", "run a scene file or a built-in scene");
    run->add_option("SCENE", scene_arg, "a scene JSON file, or a built-in scene's name")->required();
    run->add_option("--out", out_dir, "output directory (default: tearables-out/<scene>)");
    run->add_option("--steps", steps, "override the scene's step count, 0..1000000000 (as the scene's steps)")
        ->check(CLI::Range(0LL, 1'000'000'000LL));
    run->add_option("--max-memory", max_memory_text,
                    "refuse a scene whose estimated memory passes this, bytes with K/M/G/T (default 4G)");
    run->add_option("--max-step-seconds", max_step_seconds,
                    "refuse a scene whose estimated step takes longer on one core, s (default 10)")
        ->check(CLI::Range(1e-3, 1e6));
    run->add_option("--every", every, "write a trace frame every K steps")->check(CLI::PositiveNumber);
    run->add_flag("--png", png, "write frame_NNNNN.png images of every trace frame (offscreen OpenGL, OSMesa)");
    run->add_option("--size", size_text, "image size WIDTHxHEIGHT for --png and --mp4 (default 640x360)");
    run->add_option("--follow", follow, "keep the named body, string, cloth or paper sheet in the middle of the pictures (the camera moves with it)");
    run->add_flag("--mp4", mp4, "also assemble the frames into video.mp4 with ffmpeg (implies --png)");
    run->add_flag("--plot", plot, "plot.png with gnuplot: strings' tension, length, stress-strain (and torsional strain when they twist); cloths' yarn tension and torn yarns; paper sheets' creases, tears and broken springs");
    run->add_option("--plot-size", plot_size_text, "plot.png's size WIDTHxHEIGHT (default 1200x900)");
    run->add_flag("--quiet", quiet, "no progress bar, no report");
    CLI::App* list = app.add_subcommand("list", "list the built-in scenes");
    // Listed for --help; `tearables view ...` is handed to tearables-view before parsing.
    app.add_subcommand("view", "open a scene in the interactive viewer (`tearables view --help`)");

    try {
        app.parse(argc, argv);
    } catch (const CLI::ParseError& e) {
        const int code = app.exit(e);
        return code == 0 ? 0 : kInvalid;
    }

    namespace ts = tearables::scene;
    if (list->parsed()) {
        for (const auto& [name, description] : ts::builtinScenes()) std::printf("%-24s %s\n", name.c_str(), description.c_str());
        return 0;
    }

    namespace tr = tearables::render;
    ts::Scene scene;
    std::pair<int, int> size{640, 360}, plot_size{1200, 900};
    if (mp4) png = true;
    if (const int status = guarded(scene_arg, [&] {
            if (!size_text.empty()) {
                if (!png) throw tearables::InvalidInput("--size", "sets the size of pictures: give it with --png or --mp4");
                size = parseSize(size_text, "--size");
            }
            if (!plot_size_text.empty()) {
                if (!plot) throw tearables::InvalidInput("--plot-size", "sets the size of plot.png: give it with --plot");
                plot_size = parseSize(plot_size_text, "--plot-size");
            }
            if (!follow.empty() && !png)
                throw tearables::InvalidInput("--follow", "moves the camera of pictures: give it with --png or --mp4");
            scene = loadNamed(scene_arg);
            if (!follow.empty()) tr::checkFollowable(scene, follow);
            if (plot) tr::checkPlottable(scene);
        }))
        return status;
    // Missing tools are found before anything is simulated.
    if (mp4 && tr::findOnPath("ffmpeg").empty()) {
        std::fprintf(stderr, "tearables: %s\n", tr::notInstalledMessage("ffmpeg", "ffmpeg", "for --mp4").c_str());
        return kFailed;
    }
    if (plot && tr::findOnPath("gnuplot").empty()) {
        std::fprintf(stderr, "tearables: %s\n", tr::notInstalledMessage("gnuplot", "gnuplot-nox", "for --plot").c_str());
        return kFailed;
    }

    ts::RunOptions options;
    if (out_dir.empty()) out_dir = "tearables-out/" + std::filesystem::path(scene_arg).stem().string();
    options.out_dir = out_dir;
    if (steps >= 0) options.steps = steps;
    if (every > 0) options.every = every;
    options.limits.step_seconds = max_step_seconds;
    if (const int status = guarded(scene_arg, [&] {
            if (!max_memory_text.empty()) options.limits.memory_bytes = parseBytes(max_memory_text, "--max-memory");
            ts::checkResources(scene, options.limits);
        }))
        return status;
    options.progress = !quiet && isatty(fileno(stderr));
    return guarded(scene_arg, [&] {
        std::unique_ptr<tr::Renderer> renderer;
        tr::View view;
        tr::Bounds seen;
        long long frames = 0;
        if (png) {
            removeOldFrames(out_dir);
            renderer = std::make_unique<tr::Renderer>(size.first, size.second);
            const double aspect = static_cast<double>(size.first) / size.second;
            view = tr::fitCamera(scene, aspect);
            // What moves out of the picture brings the camera back: it is refitted to the
            // union of everything seen so far (it only widens, so it does not swing back and
            // forth), unless the scene places the eye itself.
            seen = tr::sceneBounds(scene);
            options.on_frame = [&, aspect](const ts::FrameState& f) {
                const tr::Bounds now = tr::frameBounds(f);
                if (!follow.empty()) {
                    // Following: the camera keeps its offset from the followed thing.
                    if (const auto p = tr::followPoint(f, follow)) view = tr::followView(view, *p);
                } else if (!scene.camera.eye && !now.empty() && !tr::inFrame(view, aspect, now)) {
                    seen.add(now.lo);
                    seen.add(now.hi);
                    view = tr::fitCamera(scene, aspect, seen);
                }
                char name[32];
                std::snprintf(name, sizeof name, "frame_%05lld.png", frames++);
                tr::Image image = tr::paintFrame(*renderer, scene, f, view);
                tr::paintOverlay(image, scene, f.time, f.step);
                tr::writePng((std::filesystem::path(out_dir) / name).string(), image);
            };
        }
        const ts::RunResult r = ts::runScene(scene, options);
        const std::string video = (std::filesystem::path(out_dir) / "video.mp4").string();
        if (mp4) {
            // Real time where it can be: one frame per trace frame, clamped to 1-60 frames/s.
            const int every_used = options.every.value_or(scene.output_every);
            tr::makeVideo(out_dir, std::clamp(1.0 / (scene.dt * every_used), 1.0, 60.0), video);
        }
        if (plot) tr::writePlots(scene, out_dir, plot_size.first, plot_size.second);
        if (quiet) return;
        std::printf("simulated %lld steps (%.3g s) in %.3g s of stepping; digest %s\n", r.steps, r.simulated_seconds,
                    r.wall_seconds, r.digest.c_str());
        for (const auto& [type, n] : r.event_counts) std::printf("  %s: %lld\n", type.c_str(), n);
        if (r.islands.solves > 0)
            std::printf("islands: %lld solves, %.1f Newton iterations each (at most %d), %lld not converged\n",
                        r.islands.solves, static_cast<double>(r.islands.iterations) / static_cast<double>(r.islands.solves),
                        r.islands.most_iterations, r.islands.unconverged);
        std::printf("output: %s/{trace.jsonl,events.jsonl,summary.json}\n", out_dir.c_str());
        if (png) std::printf("pictures: %lld x %s/frame_NNNNN.png (%dx%d)\n", frames, out_dir.c_str(), size.first, size.second);
        if (mp4) std::printf("video: %s\n", video.c_str());
        if (plot) std::printf("plot: %s/plot.png\n", out_dir.c_str());
    });
}
