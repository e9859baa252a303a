// tearables-view: the interactive viewer's program (`tearables view` runs it). Exit status
// as the command line's: 0 done; 2 the scene, the script or the arguments are invalid;
// 1 anything else went wrong (no window could be opened).
#include "render/scene_painter.hpp"
#include "viewer/viewer.hpp"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>

namespace {

constexpr int kInvalid = 2;
constexpr int kFailed = 1;

namespace ts = tearables::scene;

/// A scene file or a built-in scene's name, with its description.
ts::Scene loadNamed(const std::string& what, std::string& description) {
    std::error_code ec;
    if (std::filesystem::is_regular_file(what, ec)) {
        ts::Scene scene = ts::loadSceneFile(what);
        std::ifstream in(what);
        std::stringstream text;
        text << in.rdbuf();
        const nlohmann::json j = nlohmann::json::parse(text.str(), nullptr, false, true);
        if (j.is_object() && j.contains("description") && j["description"].is_string()) description = j["description"];
        return scene;
    }
    if (auto text = ts::builtinSceneText(what)) {
        ts::Scene scene = ts::parseScene(*text);
        scene.source = what;
        for (const auto& [name, d] : ts::builtinScenes())
            if (name == what) description = d;
        return scene;
    }
    throw tearables::InvalidInput("SCENE", "no scene file or built-in scene named \"" + what + "\" (see `tearables list`)");
}

std::pair<int, int> parseSize(const std::string& text) {
    static const std::regex pattern("([0-9]{1,5})x([0-9]{1,5})");
    std::smatch m;
    if (!std::regex_match(text, m, pattern))
        throw tearables::InvalidInput("--size", "expected WIDTHxHEIGHT in pixels, e.g. 1280x720 (got \"" + text + "\")");
    const int w = std::stoi(m[1]), h = std::stoi(m[2]);
    if (w < 320 || h < 240 || w > 8192 || h > 8192)
        throw tearables::InvalidInput("--size", "each side must be in [320, 8192] x [240, 8192] pixels (got " + text + ")");
    return {w, h};
}

}  // namespace

int main(int argc, char** argv) {
    CLI::App app{"tearables view: play a scene in a window, drag, cut and tear"};
    app.name("tearables view");
    std::string scene_arg, size_text;
    tearables::viewer::ViewerOptions options;
    app.add_option("SCENE", scene_arg, "a scene JSON file, or a built-in scene's name")->required();
    app.add_option("--size", size_text, "the window's size WIDTHxHEIGHT (default 1280x720)");
    app.add_option("--script", options.script, "run the timed input events of FILE (docs/SCENE_FORMAT.md, \"Viewer scripts\")");
    app.add_option("--screenshot", options.screenshot, "after --steps N steps, write the window to FILE (PNG) and exit");
    app.add_option("--steps", options.steps, "with --screenshot: steps to simulate first, 0..10000000")
        ->check(CLI::Range(0LL, 10'000'000LL));
    app.add_flag("--print-state", options.print_state, "at exit, print the world state (torn segments, events) as JSON on stdout");
    app.add_flag("--paused", options.paused, "start paused");
    app.add_flag("--hide-panels", options.hide_panels, "start without the panels (the colour bar stays; P shows them)");
    app.add_option("--follow", options.follow, "keep the named body, string, cloth or paper sheet in the middle of the window (orbit and zoom still work)");
    app.add_option("--trace", options.trace_dir, "play back the run `tearables run SCENE --out DIR` recorded in DIR");
    try {
        app.parse(argc, argv);
    } catch (const CLI::ParseError& e) {
        const int code = app.exit(e);
        return code == 0 ? 0 : kInvalid;
    }
    try {
        if (!size_text.empty()) std::tie(options.width, options.height) = parseSize(size_text);
        if (options.steps > 0 && options.screenshot.empty())
            throw tearables::InvalidInput("--steps", "sets the steps before --screenshot: give it with --screenshot");
        options.scene = loadNamed(scene_arg, options.description);
        options.scene_arg = scene_arg;
        if (!options.follow.empty()) tearables::render::checkFollowable(options.scene, options.follow);
        return tearables::viewer::runViewer(options);
    } catch (const tearables::InvalidInput& e) {
        std::fprintf(stderr, "tearables view: %s: %s\n", scene_arg.c_str(), e.what());
        return kInvalid;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "tearables view: %s\n", e.what());
        return kFailed;
    }
}
