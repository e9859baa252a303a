// The viewer's scripts (`tearables view --script FILE`): timed input events, one a line,
// run in order; the format is in docs/SCENE_FORMAT.md ("Viewer scripts").
#pragma once

#include "tearables/types.hpp"

#include <string>
#include <vector>

namespace tearables::viewer {

/// One line of a script.
struct ScriptCommand {
    enum class Kind {
        Frames,     ///< let `count` frames pass (the simulation runs as it would)
        Step,       ///< take `count` simulation steps now (paused or not)
        Move,       ///< the cursor to pixel (x, y) from the window's top-left corner
        MoveWorld,  ///< the cursor to where the world point `point` is seen
        Press,      ///< press mouse button `button` (0 left, 1 right) where the cursor is
        Release,    ///< release it
        Key,        ///< press and release the key `key` (as the keyboard controls)
        Screenshot, ///< write the window (panels included) to `path` as PNG
        Quit,       ///< close the viewer
    };
    Kind kind = Kind::Frames;
    long long count = 0;
    double x = 0.0, y = 0.0;
    Vec3 point = Vec3::Zero();
    int button = 0;
    std::string key;
    std::string path;
    int line = 0;  ///< in the file, for messages
};

/// Parses a script's text. Throws InvalidInput("script:LINE") naming what is wrong.
std::vector<ScriptCommand> parseScript(const std::string& text);
/// Reads and parses a script file (std::runtime_error when unreadable).
std::vector<ScriptCommand> loadScript(const std::string& path);

}  // namespace tearables::viewer
