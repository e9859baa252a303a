// The interactive viewer (`tearables view`, the program tearables-view): a GLFW window
// that plays a scene with the renderer's drawing code (demos/render/) and Dear ImGui
// panels, and lets a person drag, cut, drop crates and blow wind.
#pragma once

#include "tearables/scene.hpp"

#include <string>

namespace tearables::viewer {

struct ViewerOptions {
    std::string scene_arg;       ///< for messages and the title
    scene::Scene scene;          ///< loaded and checked
    std::string description;     ///< the scene's "description" ("" when none)
    int width = 1280, height = 720;  ///< the window's size, pixels
    std::string script;          ///< --script FILE: timed input events ("" = none)
    std::string screenshot;      ///< --screenshot FILE: after `steps` steps, write the window and exit
    long long steps = 0;         ///< --steps N with --screenshot (with --trace: the frame at step N)
    bool print_state = false;    ///< --print-state: the world state as JSON on stdout at exit
    bool paused = false;         ///< --paused: start paused
    bool hide_panels = false;    ///< --hide-panels: start without the panels (P shows them)
    std::string trace_dir;       ///< --trace DIR: play back the run recorded there (trace.jsonl)
    std::string follow;          ///< --follow NAME: the camera keeps this body, string, cloth or sheet centred ("" = none)
};

/// Opens the window and runs until it is closed (or the script quits, or the screenshot is
/// written). Returns the exit status (0; 1 when no window can be opened). Throws
/// InvalidInput for a bad script.
int runViewer(const ViewerOptions& options);

}  // namespace tearables::viewer
