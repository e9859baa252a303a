// The `tearables` command line: runs headless scenes (../shared/SCENE_FORMAT.md).
// Exit status: 0 simulated; 2 the scene or the arguments are invalid (nothing simulated);
// 1 anything else went wrong.
#include "tearables/scene.hpp"

#include <CLI/CLI.hpp>

#include <cstdio>
#include <filesystem>
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

}  // namespace

int main(int argc, char** argv) {
    CLI::App app{"tearables: ropes, strings, paper and cloth that twist and tear, for Bullet"};
    app.require_subcommand(1);

    std::string scene_arg, out_dir;
    long long steps = -1;
    int every = 0;
    bool png = false, quiet = false;
    CLI::App* run = app.add_subcommand("run", "run a scene file or a built-in scene");
    run->add_option("SCENE", scene_arg, "a scene JSON file, or a built-in scene's name")->required();
    run->add_option("--out", out_dir, "output directory (default: tearables-out/<scene>)");
    run->add_option("--steps", steps, "override the scene's step count")->check(CLI::NonNegativeNumber);
    run->add_option("--every", every, "write a trace frame every K steps")->check(CLI::PositiveNumber);
    run->add_flag("--png", png, "write frame images (not available in this build yet)");
    run->add_flag("--quiet", quiet, "no progress bar, no report");
    CLI::App* list = app.add_subcommand("list", "list the built-in scenes");

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

    ts::Scene scene;
    if (const int status = guarded(scene_arg, [&] {
            if (png) throw tearables::InvalidInput("--png", "frame images are not available in this build yet");
            scene = loadNamed(scene_arg);
        }))
        return status;

    ts::RunOptions options;
    if (out_dir.empty()) out_dir = "tearables-out/" + std::filesystem::path(scene_arg).stem().string();
    options.out_dir = out_dir;
    if (steps >= 0) options.steps = steps;
    if (every > 0) options.every = every;
    options.progress = !quiet && isatty(fileno(stderr));
    return guarded(scene_arg, [&] {
        const ts::RunResult r = ts::runScene(scene, options);
        if (quiet) return;
        std::printf("simulated %lld steps (%.3g s) in %.3g s of stepping; digest %s\n", r.steps, r.simulated_seconds,
                    r.wall_seconds, r.digest.c_str());
        for (const auto& [type, n] : r.event_counts) std::printf("  %s: %lld\n", type.c_str(), n);
        std::printf("output: %s/{trace.jsonl,events.jsonl,summary.json}\n", out_dir.c_str());
    });
}
